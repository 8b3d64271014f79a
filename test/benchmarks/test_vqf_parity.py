"""Smoke test of ``bench --suite vqf`` on a slice of one BROAD recording (initial rest, the
first motion, the first pause): every figure is there and the tilt errors against the optical
truth are of the size the dataset's README gives VQF (well under a degree), for ours and VQF's.
The accuracy targets are the benchmark's business, never asserted here."""

from __future__ import annotations

import numpy as np
import pytest

from gyro_attitude.benchmarks import real
from gyro_attitude.benchmarks import vqf_parity as bench
from gyro_attitude.core.attitude.rest import detect_rest, rest_segments

NAME = "broad_05_slow_rotation_with_breaks"
DIR = real.real_dir()
pytestmark = pytest.mark.skipif(not (DIR / f"{NAME}.mcap").exists(),
                                reason=f"real recordings not found in {DIR}")


def test_slice_reports_every_estimator_against_the_truth():
    pytest.importorskip("vqf")
    t, g, a, tt, tq = real.load(NAME, DIR)
    segs = rest_segments(detect_rest(t, g, a).covered)
    end = segs[1][1] + 1  # through the first pause (~72 s)
    keep = tt <= t[end - 1]
    row = bench.evaluate_arrays(NAME, t[:end], g[:end], a[:end], tt[keep], tq[keep], "tilt")
    assert row["aiding"] == "tilt"
    assert 55.0 < row["motion_s"] < 70.0  # the motion ends where the pause starts (~64 s)
    for est in bench.ESTIMATORS:
        assert 0.02 < row[f"{est}_rms_tilt_deg"] < 0.6, est
        assert row[f"{est}_rms_tilt_deg"] <= row[f"{est}_peak_tilt_deg"] < 3.0, est
    assert row["causal_rms_over_vqf"] == pytest.approx(row["causal_rms_tilt_deg"]
                                                       / row["vqf_rms_tilt_deg"])
    s = bench.summary([row, dict(row, causal_rms_over_vqf=2.0)])
    assert s["causal_rms_worst"] == 2.0 and not s["causal_rms_worst_met"]
    assert not s["all_targets_met"]
    assert np.isfinite(s["offline_rms_median"])
