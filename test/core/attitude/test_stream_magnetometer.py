"""aiding magnetometer through the attitude stream: a simulated magnet does not turn the heading
(beyond the gyro-only drift over it), bad and missing fields are counted and never make the
attitude non-finite, push() equals run()."""

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gyro_attitude.core.attitude.sample_alignment import latest_at
from gyro_attitude.core.attitude.settings import StreamConfig
from gyro_attitude.core.attitude.stream import (
    INVALID_MAG,
    MAG_DISTURBED,
    MAG_MISSING,
    AttitudeStream,
)
from gyro_attitude.core.scene import SceneSimulator
from gyro_attitude.io.scene_file import load_scene

SCENE = "magnet_disturbance"  # config/scenes/magnet_disturbance.yaml: magnet at 25-35 s


def heading_deg(q, q_true):
    e = (Rotation.from_quat(q) * Rotation.from_quat(q_true).inv()).as_quat()
    return np.degrees(np.abs((2 * np.arctan2(e[:, 2], e[:, 3]) + np.pi) % (2 * np.pi) - np.pi))


@pytest.fixture(scope="module")
def sim():
    spec = load_scene(SCENE)
    b = SceneSimulator(spec, spec.rate_hz).next_block(int(spec.duration_s * spec.rate_hz))
    return spec, b


def config(spec, **kw):
    m = spec.magnetometer
    return StreamConfig(aiding="magnetometer", initial_attitude_source="level",
                        magnetic_declination_deg=math.degrees(m.declination),
                        mag_hard_iron_t=tuple(m.hard_iron.tolist()), **kw)


def run(spec, b, mag, **kw):
    stream = AttitudeStream(config=config(spec, **kw))
    res = stream.run(b.t_ns, b.omega_ib_b, "imu_link", None, b.specific_force_b, mag)
    return stream, res


def test_a_magnet_brought_near_keeps_the_heading_within_the_gyro_only_drift(sim):
    spec, b = sim
    stream, res = run(spec, b, b.magnetic_field_b)
    t = (b.t_ns[res.index] - spec.start_time_ns) * 1e-9
    err = heading_deg(res.q, b.truth_q_nb[res.index])
    on = (t >= 25.0) & (t < 35.0)
    k0 = np.flatnonzero(on)[0]
    # the gyro alone over the disturbance, from the estimate at its start: its heading drift
    bias = np.asarray(res.bias.bias)
    rates = b.omega_ib_b[res.index][on] - bias
    rot = Rotation.from_quat(res.q[k0])
    q_gyro = [rot.as_quat()]
    dts = np.diff(t[on])
    for w, dt in zip(rates[1:], dts, strict=True):
        rot = rot * Rotation.from_rotvec(w * dt)
        q_gyro.append(rot.as_quat())
    drift = np.abs(heading_deg(np.array(q_gyro), res.q[on]))
    assert err[on].max() <= err[k0] + drift.max() + 0.05
    assert res.counts[MAG_DISTURBED] >= 0.95 * on.sum()
    assert stream.aiding.mag_reference_changes == 0
    assert err[t > 40.0].max() < 1.0  # and the field holds the heading after it

    # the same magnet without the rejection: the heading swings toward the false north
    _, free = run(spec, b, b.magnetic_field_b, mag_norm_tol=10.0, mag_dip_tol_deg=180.0)
    assert heading_deg(free.q, b.truth_q_nb[free.index])[on].max() > err[on].max() + 5.0


@pytest.mark.parametrize("bad", ["stops", "nan", "huge", "zero", "flip"])
def test_bad_or_missing_field_is_counted_and_the_attitude_stays_finite(sim, bad):
    spec, b = sim
    t = (b.t_ns - spec.start_time_ns) * 1e-9
    sel = t > 20.0
    mag = b.magnetic_field_b.copy()
    mag[sel] = {"stops": np.nan, "nan": np.nan, "huge": 1e300, "zero": 0.0}.get(bad, 0.0) \
        if bad != "flip" else -mag[sel]
    if bad == "nan":
        mag[sel, 1] = 1e-5  # partly NaN: a broken reading, not a missing one
    stream, res = run(spec, b, mag)
    assert np.isfinite(res.q).all()
    counted = {"stops": MAG_MISSING, "nan": INVALID_MAG, "huge": INVALID_MAG,
               "zero": INVALID_MAG, "flip": MAG_DISTURBED}[bad]
    assert res.counts[counted] >= sel.sum() - 1
    # gyro-only from 20 s: the heading drifts by the residual bias, no jump
    err = heading_deg(res.q, b.truth_q_nb[res.index])
    tt = t[res.index]
    assert err[tt > 20.0].max() < err[np.flatnonzero(tt > 20.0)[0]] + 1.0


def test_a_field_message_of_nan_is_counted_invalid_not_missing_once_aligned(sim):
    # replay aligns the field to the Imu stamps (latest_at), where NaN means "no sample"; a
    # message whose values are NaN is a broken reading, as the live node counts it
    spec, b = sim
    sel = (b.t_ns - spec.start_time_ns) * 1e-9 > 20.0
    messages = b.magnetic_field_b.copy()
    messages[sel] = np.nan
    _, res = run(spec, b, latest_at(b.t_ns, b.t_ns, messages, 0))
    assert res.counts[INVALID_MAG] >= sel.sum() - 1
    assert res.counts[MAG_MISSING] == 0


def test_push_gives_what_run_gives_with_a_magnetometer(sim):
    spec, b = sim
    n = 3000
    mag = b.magnetic_field_b[:n].copy()
    mag[1000:1100] = np.nan  # a stretch with no field
    stream_run = AttitudeStream(config=config(spec))
    res = stream_run.run(b.t_ns[:n], b.omega_ib_b[:n], "imu_link", None,
                         b.specific_force_b[:n], mag)
    stream_push = AttitudeStream(config=config(spec))
    qs = []
    for k in range(n):
        _, q = stream_push.push(int(b.t_ns[k]), b.omega_ib_b[k], "imu_link", None,
                                b.specific_force_b[k], mag[k])
        if q is not None:
            qs.append(q)
    np.testing.assert_allclose(np.array(qs), res.q, atol=1e-12)
    assert stream_push.counts == res.counts
    assert res.counts[MAG_MISSING] == 100


def test_mag_rows_of_the_wrong_shape_are_refused(sim):
    spec, b = sim
    with pytest.raises(ValueError, match="mag must have shape"):
        AttitudeStream(config=config(spec)).run(b.t_ns[:10], b.omega_ib_b[:10], "imu_link",
                                                None, b.specific_force_b[:10],
                                                np.zeros((9, 3)))
