"""The offline estimator with the magnetometer (aiding magnetometer, core/attitude/offline.py
step 6) against a field written out in closed form: a constant Earth-like field in the ENU frame
seen by a body whose attitude is known exactly (rest_motion_rest of test_offline), so the body
reading is ``C_nb^T B``.  The heading comes from the field (any start heading), toward true north
with a declination; a magnet brought near is rejected (no jump toward the false north); bad
field samples are counted and never make the attitude non-finite."""

import math

import numpy as np
import pytest
from test_offline import rest_motion_rest

from gyro_attitude.core.attitude import offline
from gyro_attitude.core.attitude.offline import estimate_offline
from gyro_attitude.core.attitude.settings import StreamConfig
from gyro_attitude.core.attitude.stream import INVALID_MAG, MAG_DISTURBED, MAG_MISSING
from gyro_attitude.core.rotation import quat_conjugate, quat_multiply, quat_rotate

# Berlin-like field: 44 µT, dip 69° (down), horizontal toward magnetic north
B_MAG = 44e-6 * np.array([0.0, math.cos(math.radians(69.0)), -math.sin(math.radians(69.0))])


def field_enu(declination_deg=0.0):
    """The field in ENU whose horizontal part points ``declination_deg`` east of true north."""
    d = math.radians(declination_deg)
    h = B_MAG[1]
    return np.array([h * math.sin(d), h * math.cos(d), B_MAG[2]])


def body_field(q_true, b_enu, rng, noise_t=0.1e-6):
    return quat_rotate(quat_conjugate(q_true), b_enu) + rng.normal(scale=noise_t,
                                                                   size=(q_true.shape[0], 3))


def heading_error_deg(q_est, q_true):
    e = quat_multiply(q_est, quat_conjugate(q_true))
    return np.degrees(np.abs((2.0 * np.arctan2(e[:, 2], e[:, 3]) + np.pi) % (2 * np.pi) - np.pi))


def yaw(q, deg):
    r = math.radians(deg)
    return quat_multiply(np.array([0.0, 0.0, math.sin(r / 2), math.cos(r / 2)]), q)


@pytest.mark.parametrize("declination_deg", [0.0, 5.0])
def test_the_heading_comes_from_the_field_whatever_the_start_heading(declination_deg):
    t, w, a, q_true, var, k_end = rest_motion_rest(31)
    rng = np.random.default_rng(31)
    mag = body_field(q_true, field_enu(declination_deg), rng)
    q0 = yaw(q_true[0], 25.0)  # started 25° off in heading
    cfg = StreamConfig(aiding="magnetometer", magnetic_declination_deg=declination_deg)
    res = estimate_offline(t, w, a, q0=q0, config=cfg, mag=mag)
    h = heading_error_deg(res.q, q_true[res.index])
    assert h.max() < 0.3  # from the first sample on: the smoother sees the field on both sides
    assert res.counts[MAG_DISTURBED] == 0 and res.counts[INVALID_MAG] == 0
    ref = res.field_reference
    assert ref.mag_ref_norm == pytest.approx(44e-6, rel=1e-3)
    assert math.degrees(ref.mag_ref_dip) == pytest.approx(69.0, abs=0.2)
    # the heading variance is an observation's now: bounded, not growing with the motion
    assert res.variance[k_end, 2] < res.variance[k_end, 0] * 20
    # without the field (gyro aiding only) the start error stays: the field did the work
    grav = estimate_offline(t, w, a, q0=q0, config=StreamConfig(aiding="tilt"))
    assert heading_error_deg(grav.q, q_true[grav.index]).min() > 24.0


def magnet_case(seed=32, **kw):
    """A magnet near the sensor for 6 s in the middle of the motion: 30 µT in the body frame."""
    t, w, a, q_true, var, k_end = rest_motion_rest(seed, motion_s=24.0)
    rng = np.random.default_rng(seed)
    mag = body_field(q_true, field_enu(), rng)
    s = (t - t[0]) * 1e-9
    on = (s >= 15.0) & (s < 21.0)
    mag[on] += np.array([25e-6, -15e-6, 10e-6])
    cfg = StreamConfig(aiding="magnetometer", **kw)
    res = estimate_offline(t, w, a, q0=yaw(q_true[0], 10.0), config=cfg, mag=mag)
    return res, q_true, on


def test_a_magnet_brought_near_is_rejected_and_does_not_turn_the_heading():
    res, q_true, on = magnet_case()
    h = heading_error_deg(res.q, q_true[res.index])
    assert res.counts[MAG_DISTURBED] >= 0.95 * on.sum()
    # the gyro alone over 6 s (bias from the rests, SE ~5e-5 rad/s: < 0.05°) and the field on
    # both sides: the heading holds
    assert h[on].max() < 0.3
    assert h.max() < 0.3
    # the same magnet without the rejection: the heading swings toward the false north (by
    # ~2°: the 30 s smoother averages the 6 s of false field with the true one around it)
    free, _, _ = magnet_case(mag_norm_tol=10.0, mag_dip_tol_deg=180.0)
    swing = heading_error_deg(free.q, q_true[free.index])[on].max()
    assert swing > 1.0 and swing > 5 * h[on].max()


def test_bad_or_missing_field_samples_are_counted_and_the_attitude_stays_finite():
    t, w, a, q_true, var, k_end = rest_motion_rest(33)
    rng = np.random.default_rng(33)
    mag = body_field(q_true, field_enu(), rng)
    mag[100:300] = np.nan  # no field sample (as sample_alignment.latest_at gives)
    mag[400] = (np.nan, 0.0, 1e-5)
    mag[401] = (1e300, 0.0, 0.0)
    mag[402] = (0.0, 0.0, 0.0)
    mag[403] = (np.inf, 0.0, 0.0)
    res = estimate_offline(t, w, a, q0=q_true[0], config=StreamConfig(aiding="magnetometer"),
                           mag=mag)
    assert res.counts[MAG_MISSING] == 200 and res.counts[INVALID_MAG] == 4
    assert np.isfinite(res.q).all() and np.isfinite(res.variance).all()
    assert heading_error_deg(res.q, q_true[res.index]).max() < 0.3
    # a field that flips sign for the whole second half: off the reference's dip, rejected;
    # the first half's field keeps the heading
    flip = mag.copy()
    flip[t.size // 2:] *= -1.0
    r2 = estimate_offline(t, w, a, q0=q_true[0], config=StreamConfig(aiding="magnetometer"),
                          mag=flip)
    assert np.isfinite(r2.q).all()
    # no field at all: counted, heading gyro-only, said so
    r3 = estimate_offline(t, w, a, q0=q_true[0], config=StreamConfig(aiding="magnetometer"))
    assert r3.counts[MAG_MISSING] == t.size and any("without a field" in n for n in r3.notes)
    r4 = estimate_offline(t, w, a, q0=q_true[0], mag=mag,
                          config=StreamConfig(aiding="magnetometer", mag_hard_iron_estimate=True))
    assert any("does not estimate the hard iron" in n for n in r4.notes)
    with pytest.raises(ValueError, match="mag must have shape"):
        estimate_offline(t, w, a, config=StreamConfig(aiding="magnetometer"), mag=mag[:-1])


def test_zero_readings_do_not_vote_for_the_reference_and_unusable_fields_are_counted():
    t, w, a, q_true, var, k_end = rest_motion_rest(35)
    rng = np.random.default_rng(35)
    mag = body_field(q_true, field_enu(), rng)
    hard = (12e-6, -7e-6, 4e-6)
    cfg = StreamConfig(aiding="magnetometer", mag_hard_iron_t=hard)
    # a sensor that reads zeros for the first 60 % (less the hard iron they are 14 µT, a
    # plausible norm): invalid, and the reference is the true field's, not theirs
    zeros = mag + np.asarray(hard)
    zeros[: int(0.6 * t.size)] = 0.0
    res = estimate_offline(t, w, a, q0=yaw(q_true[0], 10.0), config=cfg, mag=zeros)
    assert res.counts[INVALID_MAG] == int(0.6 * t.size)
    assert res.field_reference.mag_ref_norm == pytest.approx(44e-6, rel=1e-2)
    assert heading_error_deg(res.q, q_true[res.index])[-1] < 0.5
    # no usable field at all: every sample counted, the heading gyro-only and said so
    for bad in (np.inf, 1e300, 0.0):
        r = estimate_offline(t, w, a, q0=q_true[0], config=cfg, mag=np.full_like(mag, bad))
        assert r.counts[INVALID_MAG] == t.size, bad
        assert any("too few usable field samples" in n for n in r.notes)
        assert np.isfinite(r.q).all()


@pytest.mark.parametrize("keep_forward", [True, False])
def test_chunked_heading_pass_gives_the_whole_recording_result(keep_forward, monkeypatch):
    t, w, a, q_true, var, k_end = rest_motion_rest(34, motion_s=24.0)
    rng = np.random.default_rng(34)
    mag = body_field(q_true, field_enu(), rng)
    cfg = StreamConfig(aiding="magnetometer")
    whole = estimate_offline(t, w, a, q0=q_true[0], config=cfg, mag=mag)
    if not keep_forward:
        monkeypatch.setattr(offline, "_KEEP_FORWARD", 0)
    chunked = estimate_offline(t, w, a, q0=q_true[0], config=cfg, mag=mag, chunk_samples=257)
    e = quat_multiply(whole.q, quat_conjugate(chunked.q))
    assert np.max(np.abs(e[:, :3])) < 1e-9
    assert whole.counts == chunked.counts
