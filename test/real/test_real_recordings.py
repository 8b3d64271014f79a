"""Rest bias, levelling and gravity aiding on the BROAD recordings (optical truth, CC BY 4.0).

Expected figures are the README table of /work/shared/real (error at the end of the motion,
integration from the first truth attitude): bias = mean over the initial rest 2.90°, 6.68°;
VQF 6D tilt 0.13°, 0.37°.  End of motion = start of the final rest found in the data.
"""

import os

import numpy as np
import pytest

from gyro_attitude.benchmarks import real
from gyro_attitude.core.attitude.alignment import align

DIR = real.real_dir()
HAVE = all((DIR / f"{n}.mcap").exists() for n in real.RECORDINGS)
if not HAVE and os.environ.get("CI") == "true":
    raise RuntimeError(f"CI=true but the real recordings are missing in {DIR}")
pytestmark = pytest.mark.skipif(not HAVE, reason=f"real recordings not found in {DIR}")

README = {"broad_05_slow_rotation_with_breaks": (2.90, 0.13), "broad_16_fast_translation": (6.68, 0.37)}


@pytest.fixture(scope="module", params=real.RECORDINGS)
def rows(request):
    return request.param, {r["mode"]: r for r in real.evaluate(request.param, DIR, modes=(
        "auto", "gravity"), peers=False)}


def test_auto_bias_end_error_within_1p2_of_initial_rest_mean(rows):
    name, r = rows
    assert r["auto"]["end_error_deg"] <= 1.2 * README[name][0]


def test_gravity_aiding_tilt_within_2x_vqf_and_1deg(rows):
    name, r = rows
    assert r["gravity"]["end_tilt_deg"] <= min(2 * README[name][1], 1.0)


def test_gravity_aiding_tilt_stays_small_during_fast_translation(rows):
    """The nav-frame low-pass of the specific force: RMS tilt over the motion 1.3° on trial 16
    (14.9° with the norm gate alone, which horizontal accelerations pass); VQF: 0.3–0.5°."""
    name, r = rows
    assert r["gravity"]["rms_tilt_deg"] <= 2.0


@pytest.mark.parametrize("name", real.RECORDINGS)
def test_levelling_tilt_against_first_truth(name):
    t, g, a, _, tq = real.load(name, DIR)
    res = align(t, g, a)
    tilt = float(np.degrees(real.tilt_error(res.q_nb, tq[0])))
    # Levelling error ≈ accel bias / g: the reported 1σ (5 mg assumed) is 0.29°; allow 3σ.
    assert tilt <= 3 * np.degrees(res.level_error_expected), tilt
