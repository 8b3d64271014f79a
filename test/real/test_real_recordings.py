"""Rest bias, levelling and tilt aiding on the BROAD recordings (optical truth, CC BY 4.0).

Expected figures are the README table of /work/shared/real (error at the end of the motion,
integration from the first truth attitude): bias = mean over the initial rest 2.90°, 6.68°;
VQF 6D tilt 0.13°, 0.37°.  End of motion = start of the final rest found in the data.
"""

import os

import numpy as np
import pytest

from gyro_attitude.benchmarks import real
from gyro_attitude.core.attitude import NavFrame
from gyro_attitude.core.attitude.stream import AttitudeStream, StreamConfig

DIR = real.real_dir()
HAVE = all((DIR / f"{n}.mcap").exists() for n in real.RECORDINGS)
if not HAVE and os.environ.get("CI") == "true":
    raise RuntimeError(f"CI=true but the real recordings are missing in {DIR}")
pytestmark = pytest.mark.skipif(not HAVE, reason=f"real recordings not found in {DIR}")

README = {"broad_05_slow_rotation_with_breaks": (2.90, 0.13), "broad_16_fast_translation": (6.68, 0.37)}


@pytest.fixture(scope="module", params=real.RECORDINGS)
def rows(request):
    return request.param, {r["mode"]: r for r in real.evaluate(request.param, DIR, modes=(
        "auto", "tilt"), peers=False)}


def test_auto_bias_end_error_within_1p2_of_initial_rest_mean(rows):
    name, r = rows
    assert r["auto"]["end_error_deg"] <= 1.2 * README[name][0]


def test_tilt_aiding_end_tilt_within_2x_vqf_and_1deg(rows):
    name, r = rows
    assert r["tilt"]["end_tilt_deg"] <= min(2 * README[name][1], 1.0)


def test_tilt_aiding_tilt_stays_small_during_fast_translation(rows):
    """The almost-inertial low-pass of the specific force: RMS tilt over the motion 0.48° on
    trial 16 (14.9° with a norm gate alone, which horizontal accelerations pass); VQF: 0.68°."""
    name, r = rows
    assert r["tilt"]["rms_tilt_deg"] <= 0.8


@pytest.mark.parametrize("name", real.RECORDINGS)
def test_levelling_tilt_against_first_truth(name):
    t, g, a, _, tq = real.load(name, DIR)
    res = AttitudeStream(config=StreamConfig(initial_attitude_source="level")).run(
        t, g, "imu", None, a).alignment
    tilt = float(np.degrees(real.tilt_error(res.q_nb, tq[0])))
    # Levelling error ≈ accel bias / g: the reported 1σ (5 mg assumed) is 0.29°; allow 3σ.
    assert tilt <= 3 * np.degrees(res.level_error_expected), tilt


@pytest.mark.parametrize("name", real.RECORDINGS)
def test_the_rests_are_still_found_with_the_per_axis_mean_bound(name):
    # The mean-rate bound (0.011 rad/s per axis) refuses a steady turn of 0.019 rad/s about any
    # axis; the BROAD biases (0.12–0.24 °/s per axis) pass it: the same rests, sample for sample,
    # as with a bound nine times looser (0.1 rad/s, the previous default in norm).
    from gyro_attitude.core.attitude.gyro_bias import J_UPDATED
    from gyro_attitude.io.imu_fast import read_imu_arrays

    imu = read_imu_arrays(DIR / f"{name}.mcap", "/imu/data_raw")
    t, g, a = imu.stamp_ns.tolist(), imu.angular_velocity, imu.linear_acceleration

    def updates(cfg):
        """The samples after which the stream's bias stage published a new estimate."""
        s = AttitudeStream("rotvec_cubic", config=cfg)
        bias_i, rows = s.state.bias_i[0], []
        for k in range(len(t)):
            s.push(t[k], g[k], "imu", None, a[k])
            if bias_i[J_UPDATED]:
                rows.append(k)
        return rows

    strict = updates(StreamConfig(aiding="none"))
    loose = updates(StreamConfig(aiding="none", rest_gyro_mean_max=0.1))
    assert len(strict) > 5000  # rests at the start, between motions and at the end
    assert strict == loose



@pytest.mark.parametrize("name", real.RECORDINGS)
def test_heading_from_the_field_after_levelling_at_vqf_9d_level(name):
    """Issue 19's target: with the heading from the mean field over the initial rest (then the
    AHRS), the RMS heading error over the motion is no worse than VQF 9D real-time's (same
    data; before the mean-field alignment 1.02°/0.68° against 0.79°/0.56°)."""
    vqf = pytest.importorskip("vqf")
    t, g, a, tt, tq = real.load(name, DIR)
    mag = real.load_mag(name, DIR)
    ke = real.end_of_motion(t, g, a)
    motion = tt <= t[ke]
    idx = np.searchsorted(t, tt)
    res = AttitudeStream(nav=NavFrame(latitude_rad=real.LATITUDE_RAD),
                         config=real.stream_config("level+magnetometer")).run(
        t, g, "imu_link", None, a, mag)
    q = np.empty((t.size, 4))
    q[:] = res.q[0]
    q[res.index] = res.q
    ours = real.heading_error(q[idx], tq)[motion & (idx >= res.index[0])]  # once aligned
    dt = float(np.median(np.diff(t))) * 1e-9
    qv = vqf.VQF(dt).updateBatch(*(np.ascontiguousarray(x) for x in (g, a, mag * 1e6)))["quat9D"]
    theirs = real.heading_error(np.column_stack([qv[:, 1:], qv[:, :1]])[idx], tq)[motion]
    rms = [float(np.sqrt(np.mean(x ** 2))) for x in (ours, theirs)]
    assert rms[0] <= rms[1], np.degrees(rms)
