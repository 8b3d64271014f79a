"""Scene simulator: a validated scene's truth and measurements in resumable blocks, and position integration.

:class:`SceneSimulator` composes exactly the effects named, once, and evaluates nothing
else; ``effects_run`` records the names of the effects actually evaluated. The gyro
measures ``ω_ib^b = C_bn (ω_ie^n + ω_en^n) + ω_nb^b`` (``docs/conventions.md``), then the instrument
(rate-gyro dynamics, then the error model of :mod:`gyro_attitude.core.sensor_errors`).
Accelerometers measure the specific force ``f^b = C_bn (dv^n/dt + (2ω_ie^n + ω_en^n) × v^n
− g^n)`` with WGS-84 normal gravity (gravitation plus centrifugal); a term whose effect is
switched off (Earth rotation, transport rate, gravity) is left out of that sum.

Memory is bounded whatever the caller asks for: a request for ``n`` samples is generated
in pieces of at most :data:`BLOCK_SAMPLES` (the working arrays of the motion, Earth and
instrument models scale with the piece, the result with ``n``), and ``n`` itself is at most
:data:`MAX_SAMPLES_PER_CALL`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gyro_attitude.core import earth
from gyro_attitude.core.angles import wrap_pi
from gyro_attitude.core.gyro.free_gyro import FreeGyroSimulator
from gyro_attitude.core.gyro.rate_gyro import RateGyroTriad
from gyro_attitude.core.instruments.common import InstrumentStepper
from gyro_attitude.core.limits import POLE_MARGIN_RAD
from gyro_attitude.core.motion import Motion, MotionSample, Stationary
from gyro_attitude.core.rotation import quat_conjugate, quat_rotate
from gyro_attitude.core.scene.magnetometer import measure_field
from gyro_attitude.core.scene.schema import MAX_RATE_HZ, SceneSpec
from gyro_attitude.core.sensor_errors import SensorErrorModel
from gyro_attitude.core.sensor_sampling import SensorSampler
from gyro_attitude.core.trajectory import TrajectoryMotion, TrajectorySample

__all__ = [
    "SceneSimulator",
    "SimBlock",
    "GimbalBlock",
    "integrate_position",
    "BLOCK_SAMPLES",
    "MAX_SAMPLES_PER_CALL",
    "POSITION_SEGMENT",
]

#: Largest piece generated at once; a longer request is assembled from such pieces.
BLOCK_SAMPLES = 65_536
#: Most samples one ``next_block`` call returns (about 3 GB of results): ask in pieces.
MAX_SAMPLES_PER_CALL = 1 << 24
#: Position integration runs on a fixed grid of segments of this many samples (segment s
#: holds samples s·N … (s+1)·N − 1, integrated from the last sample of segment s − 1), so
#: positions are bit for bit the same however the run is split into blocks.
POSITION_SEGMENT = 4096

# --------------------------------------------------------------------------- position
def _simpson_cumulative(h, f_a, f_m, f_b):
    """Cumulative Simpson sums over consecutive intervals of widths ``h``."""
    return np.cumsum(h / 6.0 * (f_a + 4.0 * f_m + f_b), axis=0)


def _hermite_mid(y_a, y_b, f_a, f_b, h):
    """Cubic Hermite value at an interval's midpoint from end values and slopes."""
    return 0.5 * (y_a + y_b) + h / 8.0 * (f_a - f_b)


def _lat_rate(lat, height, v_north):
    r_m, _ = earth.radii_of_curvature(lat)
    return v_north / (r_m + height)


def _lon_rate(lat, height, v_east):
    _, r_n = earth.radii_of_curvature(lat)
    return v_east / ((r_n + height) * np.cos(lat))


_wrap_lon = wrap_pi  # longitudes in [−π, π)


def integrate_position(motion: Motion, t0: float, llh0, t) -> np.ndarray:
    """Geodetic position ``(lat, lon, h)`` (rad, rad, m) at times ``t`` (s, sorted).

    Integrates ``(L̇, λ̇, ḣ) = (v_N/(R_M+h), v_E/((R_N+h) cos L), v_U)`` from ``llh0`` at
    ``t0`` with the motion's exact velocity: Simpson's rule over each interval between
    consecutive times (velocity at the midpoints evaluated in closed form), the latitude
    dependence of the radii resolved by three Picard sweeps with cubic-Hermite midpoint
    values. The integrand varies on the scale of the Earth's radius, so each sweep shrinks
    the error by ~e²·|v|·Δt/R and three leave it at rounding level for any block length.
    """
    t = np.asarray(t, dtype=np.float64)
    nodes = np.concatenate(([t0], t))
    h = np.diff(nodes)
    mids = nodes[:-1] + 0.5 * h
    v_n = motion.velocity(nodes)
    v_m = motion.velocity(mids)
    lat0, lon0, hgt0 = (float(x) for x in llh0)

    hgt = np.concatenate(([hgt0], hgt0 + _simpson_cumulative(h, v_n[:-1, 2], v_m[:, 2],
                                                             v_n[1:, 2])))
    hgt_m = _hermite_mid(hgt[:-1], hgt[1:], v_n[:-1, 2], v_n[1:, 2], h)

    lat = np.full(nodes.shape, lat0)
    for _ in range(3):
        f_n = _lat_rate(lat, hgt, v_n[:, 1])
        lat_m = _hermite_mid(lat[:-1], lat[1:], f_n[:-1], f_n[1:], h)
        f_m = _lat_rate(lat_m, hgt_m, v_m[:, 1])
        lat = np.concatenate(([lat0], lat0 + _simpson_cumulative(h, f_n[:-1], f_m, f_n[1:])))

    f_n = _lat_rate(lat, hgt, v_n[:, 1])
    lat_m = _hermite_mid(lat[:-1], lat[1:], f_n[:-1], f_n[1:], h)
    g_n = _lon_rate(lat, hgt, v_n[:, 0])
    g_m = _lon_rate(lat_m, hgt_m, v_m[:, 0])
    lon = lon0 + _simpson_cumulative(h, g_n[:-1], g_m, g_n[1:])
    return np.stack((lat[1:], _wrap_lon(lon), hgt[1:]), axis=-1)




def _pole_error(motion: Motion, t0: float, lat0: float, t: np.ndarray,
                start_lat: float) -> ValueError:
    """The error of a run that reaches a pole: when (first order in the latitude rate, with
    the radius at the start: good to the second order of the distance, enough to say when)."""
    nodes = np.concatenate(([t0], t))
    r_m, _ = earth.radii_of_curvature(lat0)
    v_north = motion.velocity(nodes)[:, 1]
    lat = lat0 + np.concatenate(([0.0], np.cumsum(np.diff(nodes) * 0.5
                                                  * (v_north[1:] + v_north[:-1]) / r_m)))
    over = np.nonzero(np.abs(lat) >= 0.5 * np.pi - POLE_MARGIN_RAD)[0]
    when = f"t ≈ {nodes[over[0]]:.6g} s" if over.size else f"before t = {nodes[-1]:.6g} s"
    pole = "North" if (lat[over[0]] if over.size else lat[-1]) > 0 else "South"
    return ValueError(
        f"position: the carrier reaches the {pole} pole at {when} (the scene starts at "
        f"latitude {np.degrees(start_lat):.6g}°): the ENU navigation frame has no East or "
        "North at a pole, so a scene cannot pass over one; start further from it, shorten the "
        "run or change the course")


def _checked_positions(motion: Motion, t0: float, llh0, t, start_lat: float) -> np.ndarray:
    """:func:`integrate_position`, with a run that reaches a pole refused saying when."""
    try:
        llh = integrate_position(motion, t0, llh0, t)
    except ValueError as exc:
        if "latitude" not in str(exc):
            raise
        raise _pole_error(motion, t0, float(llh0[0]), t, start_lat) from None
    if np.any(np.abs(llh[:, 0]) >= 0.5 * np.pi - POLE_MARGIN_RAD):
        raise _pole_error(motion, t0, float(llh0[0]), t, start_lat)
    return llh


def _position_steps(motion: Motion, t_a: np.ndarray, llh_a: np.ndarray,
                    t_b: np.ndarray) -> np.ndarray:
    """Positions at ``t_b (m,)``, each integrated over the one interval from its own start
    ``t_a (m,)``, ``llh_a (m, 3)``: the same Simpson step and Picard sweeps as
    :func:`integrate_position`, element-wise, so every result depends only on its own
    interval (not on which other times are asked for at once)."""
    h = t_b - t_a
    v_a, v_m, v_b = (motion.velocity(x) for x in (t_a, t_a + 0.5 * h, t_b))
    lat_a, lon_a, hgt_a = llh_a.T
    hgt_b = hgt_a + h / 6.0 * (v_a[:, 2] + 4.0 * v_m[:, 2] + v_b[:, 2])
    hgt_m = _hermite_mid(hgt_a, hgt_b, v_a[:, 2], v_b[:, 2], h)
    f_a = _lat_rate(lat_a, hgt_a, v_a[:, 1])
    lat_b = lat_a
    for _ in range(3):
        f_b = _lat_rate(lat_b, hgt_b, v_b[:, 1])
        lat_m = _hermite_mid(lat_a, lat_b, f_a, f_b, h)
        lat_b = lat_a + h / 6.0 * (f_a + 4.0 * _lat_rate(lat_m, hgt_m, v_m[:, 1]) + f_b)
    f_b = _lat_rate(lat_b, hgt_b, v_b[:, 1])
    lat_m = _hermite_mid(lat_a, lat_b, f_a, f_b, h)
    lon_b = lon_a + h / 6.0 * (_lon_rate(lat_a, hgt_a, v_a[:, 0])
                               + 4.0 * _lon_rate(lat_m, hgt_m, v_m[:, 0])
                               + _lon_rate(lat_b, hgt_b, v_b[:, 0]))
    return np.stack((lat_b, _wrap_lon(lon_b), hgt_b), axis=-1)


# --------------------------------------------------------------------------- simulator
@dataclass
class GimbalBlock:
    """Named joints of a gimballed instrument, as published on ``gyro/joint_states``:
    ``names (k,)``, ``positions (n,k)`` rad (gimbal angles and indications),
    ``velocities (n,k)`` rad/s."""

    names: tuple[str, ...]
    positions: np.ndarray
    velocities: np.ndarray

    @property
    def angles(self) -> np.ndarray:
        """The ``positions`` (free-gyro name)."""
        return self.positions

    @property
    def rates(self) -> np.ndarray:
        """The ``velocities`` (free-gyro name)."""
        return self.velocities


@dataclass
class SimBlock:
    """``n`` consecutive output samples of a scene (see module docstring for the physics).

    ``t_ns (n,)`` int64 stamps; ``omega_ib_b (n,3)`` measured gyro output (rad/s);
    ``specific_force_b (n,3)`` measured accelerometer output (m/s²) or ``None`` when the scene
    has no accelerometer; truth: ``truth_q_nb (n,4)``, ``truth_omega_nb_b (n,3)``,
    ``truth_omega_ib_b (n,3)``, ``position_llh (n,3)`` (rad, rad, m), ``velocity_enu (n,3)``;
    ``gimbal`` (named joints of the free gyro or the scene's instrument) or ``None``;
    ``magnetic_field_b (n,3)`` the magnetometer's output (tesla) or ``None`` without one.
    """

    t_ns: np.ndarray
    omega_ib_b: np.ndarray
    specific_force_b: np.ndarray | None
    truth_q_nb: np.ndarray
    truth_omega_nb_b: np.ndarray
    truth_omega_ib_b: np.ndarray
    position_llh: np.ndarray
    velocity_enu: np.ndarray
    gimbal: GimbalBlock | None = None
    magnetic_field_b: np.ndarray | None = None


def _concatenate(blocks: list[SimBlock]) -> SimBlock:
    """One SimBlock of consecutive pieces (same scene, so the same fields are present)."""
    first = blocks[0]

    def cat(name):
        return None if getattr(first, name) is None else np.concatenate(
            [getattr(b, name) for b in blocks])

    gimbal = None
    if first.gimbal is not None:
        gimbal = GimbalBlock(first.gimbal.names,
                             np.concatenate([b.gimbal.positions for b in blocks]),
                             np.concatenate([b.gimbal.velocities for b in blocks]))
    return SimBlock(**{f: cat(f) for f in ("t_ns", "omega_ib_b", "specific_force_b",
                                           "truth_q_nb", "truth_omega_nb_b", "truth_omega_ib_b",
                                           "position_llh", "velocity_enu",
                                           "magnetic_field_b")}, gimbal=gimbal)


def _repeat_row(a: np.ndarray | None, n: int) -> np.ndarray | None:
    """The one row of ``a`` (1, k) as ``n`` rows (a new array), None stays None."""
    return None if a is None else np.repeat(a, n, axis=0)


class SceneSimulator:
    """Generates a scene's samples at ``rate_hz`` in resumable, vectorized blocks.

    ``seed=None`` uses the scene's ``seed``; the same seed gives identical output, and the
    output does not depend on how it is split into blocks (each random process has its own
    generator). Sample k is stamped ``start_time_ns + k·10⁹/rate_hz`` ns (integer division
    when ``rate_hz`` is an integer, else rounded); truth is evaluated at exactly those stamps.
    ``effects_run`` is the set of effect names actually evaluated so far, e.g.
    ``motion.coning``, ``earth_rate``, ``transport_rate``, ``position``, ``gravity``,
    ``coriolis``, ``specific_force``, ``rate_gyro``, ``free_gyro``, ``instrument.gyrocompass``,
    ``gyro.white_noise``, ``accelerometer.bias``.
    """

    def __init__(self, spec: SceneSpec, rate_hz: float, seed: int | None = None):
        if (isinstance(rate_hz, bool) or not isinstance(rate_hz, int | float | np.number)
                or not (np.isfinite(rate_hz) and 0 < rate_hz <= MAX_RATE_HZ)):
            raise ValueError(f"rate_hz must be a number in (0, {MAX_RATE_HZ:g}] Hz, got {rate_hz!r}")
        self.spec = spec
        self.rate_hz = float(rate_hz)
        self.dt = 1.0 / self.rate_hz
        self.seed = spec.seed if seed is None else int(seed)
        self.effects_run: set[str] = set()
        self._k = 0
        ea = spec.earth
        self._llh0 = np.array([ea.latitude_rad, ea.longitude_rad, ea.height_m])
        # Position segments: {s: (t, llh)} the point segment s is integrated from, and
        # {s: positions} of the segments computed (the recent ones are kept).
        self._segment_anchor: dict[int, tuple[float, np.ndarray]] = {0: (0.0, self._llh0)}
        self._segment_llh: dict[int, np.ndarray] = {}
        # spawn(3)[:2] are spawn(2)'s children: adding the magnetometer stream left the gyro
        # and accelerometer noise of every existing seed as it was
        gyro_ss, accel_ss, mag_ss = np.random.SeedSequence(self.seed).spawn(3)
        self._mag_rng = np.random.default_rng(mag_ss) if spec.magnetometer is not None else None
        self._gyro_errors = (SensorErrorModel(spec.gyro_errors, self.dt, gyro_ss)
                             if spec.gyro_errors.active_effects() else None)
        self._accel_errors = (SensorErrorModel(spec.accel_errors, self.dt, accel_ss)
                              if spec.accelerometer and spec.accel_errors.active_effects()
                              else None)
        # sampling options: their own streams (children 2, 3), so the error streams stay
        samp_g, samp_a = np.random.SeedSequence(self.seed).spawn(4)[2:]
        self._gyro_sampler = (SensorSampler(spec.gyro_sampling, self.dt, samp_g)
                              if spec.gyro_sampling.active() else None)
        self._accel_sampler = (SensorSampler(spec.accel_sampling, self.dt, samp_a)
                               if spec.accelerometer and spec.accel_sampling.active() else None)
        self._rate_gyro = None
        self._free_gyro = None
        self._constant_case_rate = None
        self._constant_case_force = None
        self._last_angle = None  # integrating gyro: indicated angle at the last sample
        if spec.gyro_model in ("rate_gyro", "integrating_gyro"):
            self._rate_gyro = RateGyroTriad(spec.rate_gyro_params, self.dt)
        # g-sensitive drift of a mass unbalance needs the specific force, accelerometer or not
        self._gyro_unbalance = (self._rate_gyro is not None
                                and spec.rate_gyro_params.mass_unbalance != 0.0)
        self._gyro_g_sensitive = spec.gyro_sampling.g_sensitivity is not None
        if spec.free_gyro_params is not None:
            force = (self._case_specific_force if spec.free_gyro_params.mass_unbalance != 0.0
                     else None)
            self._free_gyro = FreeGyroSimulator(spec.free_gyro_params, self._case_rate, t0=0.0,
                                                specific_force_fn=force)
        self._instrument = None
        if spec.instrument is not None:
            ins = spec.instrument
            self._instrument = InstrumentStepper(
                ins.instrument, spec.motion, ea.latitude_rad, ea.height_m, t0=0.0,
                max_step=ins.max_step, **ins.initial)

    # ------------------------------------------------------------------ pieces
    def _stamps(self, n: int) -> np.ndarray:
        return self._stamps_at(np.arange(self._k, self._k + n, dtype=np.int64))

    def _stamps_at(self, k: np.ndarray) -> np.ndarray:
        """Stamps [ns] of samples with indices ``k``."""
        if self.rate_hz.is_integer():
            # exact k·10⁹/r in int64 without forming k·10⁹, which overflows after 9.2e9
            # samples (2.6 h at 1 MHz): whole seconds plus the remainder's nanoseconds
            r = int(self.rate_hz)
            offset = (k // r) * 1_000_000_000 + ((k % r) * 1_000_000_000) // r
        else:
            offset = np.rint(k * (1e9 / self.rate_hz)).astype(np.int64)
        return self.spec.start_time_ns + offset

    def _times_at(self, k: np.ndarray) -> np.ndarray:
        """Times [s since the first sample] of samples ``k``, as the blocks compute them."""
        return (self._stamps_at(k) - self.spec.start_time_ns).astype(np.float64) / 1e9

    def _segment_positions(self, s: int) -> np.ndarray:
        """Positions of the POSITION_SEGMENT samples of segment ``s`` (computing the
        segments before it first when their anchors are not known yet)."""
        if s in self._segment_llh:
            return self._segment_llh[s]
        first = s
        while first not in self._segment_anchor:
            first -= 1
        for j in range(first, s + 1):
            t = self._times_at(np.arange(j * POSITION_SEGMENT, (j + 1) * POSITION_SEGMENT,
                                         dtype=np.int64))
            llh = _checked_positions(self.spec.motion, *self._segment_anchor[j], t,
                                     float(self._llh0[0]))
            self._segment_anchor[j + 1] = (float(t[-1]), llh[-1].copy())
            self._segment_llh[j] = llh
        # Keep what a later request can still need: the free gyro's sub-steps cover the
        # piece just generated (at most BLOCK_SAMPLES) and reach into the one before.
        keep = s - 2 - BLOCK_SAMPLES // POSITION_SEGMENT
        for table in (self._segment_anchor, self._segment_llh):
            for old in [j for j in table if j < keep]:
                del table[old]
        return self._segment_llh[s]

    def _grid_positions(self, k0: int, n: int) -> np.ndarray:
        """Positions of samples ``k0 … k0+n−1``, from their fixed segments."""
        if not self.spec.motion.moves:
            return np.broadcast_to(self._llh0, (n, 3)).copy()
        self.effects_run.add("position")
        if isinstance(self.spec.motion, TrajectoryMotion):  # exact, from the fit
            return self.spec.motion.position_llh(self._times_at(np.arange(k0, k0 + n)))
        out = np.empty((n, 3))
        k = k0
        while k < k0 + n:
            s, i = divmod(k, POSITION_SEGMENT)
            m = min(POSITION_SEGMENT - i, k0 + n - k)
            out[k - k0:k - k0 + m] = self._segment_positions(s)[i:i + m]
            k += m
        return out

    def _positions(self, t: np.ndarray) -> np.ndarray:
        """Positions at any times ``t`` [s] (the free gyro's sub-steps): one step from the
        sample at or before each time, so they too are the same whatever the blocks."""
        if not self.spec.motion.moves:
            return np.broadcast_to(self._llh0, (t.shape[0], 3)).copy()
        self.effects_run.add("position")
        if isinstance(self.spec.motion, TrajectoryMotion):
            return self.spec.motion.position_llh(t)
        k = np.maximum(np.floor(t * self.rate_hz), 0).astype(np.int64)
        lowest = min(self._segment_anchor) * POSITION_SEGMENT
        k = np.maximum(k, lowest)  # never before the oldest segment kept
        k0 = int(k.min())
        llh_k = self._grid_positions(k0, int(k.max()) - k0 + 1)[k - k0]
        return _position_steps(self.spec.motion, self._times_at(k), llh_k, t)

    def _nav_rates(self, llh: np.ndarray, v: np.ndarray):
        """``(ω_ie^n, ω_en^n)``; ``None`` for an effect the scene does not call for."""
        ea = self.spec.earth
        w_ie = w_en = None
        if ea.rotation:
            self.effects_run.add("earth_rate")
            w_ie = earth.earth_rate_enu(llh[:, 0])
        if ea.transport_rate and self.spec.motion.moves:
            self.effects_run.add("transport_rate")
            w_en = earth.transport_rate_enu(llh[:, 0], llh[:, 2], v)
        return w_ie, w_en

    def _truth(self, t: np.ndarray, need_accel: bool, llh: np.ndarray | None = None):
        """Truth at times ``t``; ``llh`` the positions when known (the sample grid)."""
        if isinstance(self.spec.motion, TrajectoryMotion):
            return self._trajectory_truth(t, need_accel)
        if isinstance(self.spec.motion, Stationary) and t.shape[0] > 1:
            # At rest the attitude, the position and so the Earth rate in the body are the
            # same at every time: the first time's truth, repeated (the rows the per-time
            # arithmetic gives, to the bit: test_simulator checks it against the general path).
            one = self._truth(t[:1], need_accel, None if llh is None else llh[:1])
            n = t.shape[0]
            m = one[0]
            sample = MotionSample(*(_repeat_row(a, n) for a in (
                m.q_nb, m.omega_nb_b, m.velocity_enu, m.accel_enu)))
            return (sample, *(_repeat_row(a, n) for a in one[1:]))
        sample = self.spec.motion.evaluate(t, need_accel=need_accel)
        self.effects_run.add(f"motion.{self.spec.motion.name}")
        if llh is None:
            llh = self._positions(t)
        w_ie, w_en = self._nav_rates(llh, sample.velocity_enu)
        if w_ie is None and w_en is None:
            w_ib = sample.omega_nb_b.copy()
        else:
            w_in = w_ie if w_en is None else (w_en if w_ie is None else w_ie + w_en)
            w_ib = quat_rotate(quat_conjugate(sample.q_nb), w_in) + sample.omega_nb_b
        return sample, llh, w_ie, w_en, w_ib

    def _trajectory_truth(self, t: np.ndarray, need_accel: bool):
        """A trajectory's truth and ideal sensors from its fit, in the Earth-fixed tangent
        frame (:mod:`gyro_attitude.core.trajectory`): the transport rate does not enter (the
        frame does not travel), ``earth.rotation`` switches Earth rate and Coriolis."""
        motion = self.spec.motion
        self.effects_run.update(("motion.trajectory", "position"))
        rotation = self.spec.earth.rotation
        if rotation:
            self.effects_run.add("earth_rate")
        sample = motion.imu(t, earth_rotation=rotation, gravity=self.spec.gravity,
                            need_force=need_accel)
        return sample, sample.llh, None, None, sample.omega_ib_b

    def _case_rate(self, t) -> np.ndarray:
        """Inertial angular velocity of the instrument case in the case (body) frame,
        ``ω_ib^b(t)`` at any times ``t`` (s since the start): the free gyro's base motion."""
        t = np.atleast_1d(np.asarray(t, dtype=np.float64))
        if isinstance(self.spec.motion, Stationary):
            # At rest ω_ib^b = C_bn ω_ie^n is constant; the free gyro asks for it at every
            # integration sub-step, one time at a time, so compute it once.
            if self._constant_case_rate is None:
                self._constant_case_rate = self._truth(np.zeros(1), need_accel=False)[4][0]
            return np.broadcast_to(self._constant_case_rate, (t.shape[0], 3)).copy()
        return self._truth(t, need_accel=False)[4]

    def _case_specific_force(self, t) -> np.ndarray:
        """Specific force in the case (body) frame ``f^b(t)`` (m/s², error-free) at any times
        ``t`` (s since the start): what a mass unbalance of the free gyro feels."""
        t = np.atleast_1d(np.asarray(t, dtype=np.float64))
        self.effects_run.add("g_sensitive_drift")
        if isinstance(self.spec.motion, Stationary):  # constant at rest: compute once
            if self._constant_case_force is None:
                sample, llh, w_ie, w_en, _ = self._truth(np.zeros(1), need_accel=True)
                self._constant_case_force = self._specific_force(sample, llh, w_ie, w_en)[0]
            return np.broadcast_to(self._constant_case_force, (t.shape[0], 3)).copy()
        sample, llh, w_ie, w_en, _ = self._truth(t, need_accel=True)
        return self._specific_force(sample, llh, w_ie, w_en)

    def _specific_force(self, sample, llh, w_ie, w_en) -> np.ndarray:
        n = sample.q_nb.shape[0]
        if isinstance(self.spec.motion, Stationary) and n > 1:  # at rest: as in _truth
            first = MotionSample(*(None if a is None else a[:1] for a in (
                sample.q_nb, sample.omega_nb_b, sample.velocity_enu, sample.accel_enu)))
            return _repeat_row(self._specific_force(
                first, llh[:1], None if w_ie is None else w_ie[:1],
                None if w_en is None else w_en[:1]), n)
        self.effects_run.add("specific_force")
        if isinstance(sample, TrajectorySample):  # computed with the truth, from the fit
            if self.spec.earth.rotation:
                self.effects_run.add("coriolis")
            if self.spec.gravity:
                self.effects_run.add("gravity")
            return sample.specific_force_b
        f_n = sample.accel_enu.copy()
        if self.spec.motion.moves and (w_ie is not None or w_en is not None):
            self.effects_run.add("coriolis")
            w = np.zeros_like(f_n)
            if w_ie is not None:
                w += 2.0 * w_ie
            if w_en is not None:
                w += w_en
            f_n += np.cross(w, sample.velocity_enu)
        if self.spec.gravity:
            self.effects_run.add("gravity")
            f_n -= earth.gravity_enu(llh[:, 0], llh[:, 2])
        return quat_rotate(quat_conjugate(sample.q_nb), f_n)

    # ------------------------------------------------------------------ public
    def next_block(self, n: int) -> SimBlock:
        """The next ``n`` output samples (truth and measurements); resumable.

        Generated in pieces of at most :data:`BLOCK_SAMPLES`; ``n`` is at most
        :data:`MAX_SAMPLES_PER_CALL`.
        """
        if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 0:
            raise ValueError(f"n must be a non-negative integer, got {n!r}")
        n = int(n)
        if n > MAX_SAMPLES_PER_CALL:
            raise ValueError(f"n = {n} samples is more than one call returns "
                             f"({MAX_SAMPLES_PER_CALL}); ask in smaller blocks")
        if n <= BLOCK_SAMPLES:
            return self._generate(n)
        return _concatenate([self._generate(min(BLOCK_SAMPLES, n - k0))
                             for k0 in range(0, n, BLOCK_SAMPLES)])

    def _generate(self, n: int) -> SimBlock:
        """The next ``n`` (at most BLOCK_SAMPLES) samples."""
        spec = self.spec
        t_ns = self._stamps(n)
        t = (t_ns - spec.start_time_ns).astype(np.float64) / 1e9
        need_force = spec.accelerometer or self._gyro_unbalance or self._gyro_g_sensitive
        sample, llh, w_ie, w_en, w_ib = self._truth(
            t, need_accel=need_force,
            llh=(None if isinstance(spec.motion, TrajectoryMotion)  # exact from the fit
                 else self._grid_positions(self._k, n)))

        f_ideal = self._specific_force(sample, llh, w_ie, w_en) if need_force else None
        gyro_in, f_in = self._interval_means(t, w_ib, f_ideal)
        gyro_out = gyro_in
        if self._rate_gyro is not None:
            self.effects_run.add(spec.gyro_model)
            f_gyro = None
            if self._gyro_unbalance:
                self.effects_run.add("g_sensitive_drift")
                f_gyro = f_ideal
            gyro_out = self._gyro_indication(gyro_in, f_gyro)
        if self._gyro_sampler is not None:
            gyro_out = self._gyro_sampler.before_errors(gyro_out, f_ideal)
        if self._gyro_errors is not None:
            gyro_out = self._gyro_errors.apply(gyro_out)
            self.effects_run.update(f"gyro.{e}" for e in self._gyro_errors.effects_run)
        elif gyro_out is w_ib:
            gyro_out = w_ib.copy()
        if self._gyro_sampler is not None:
            gyro_out = self._gyro_sampler.clip(gyro_out)
            self.effects_run.update(f"gyro.{e}" for e in self._gyro_sampler.effects_run)

        f_b = None
        if spec.accelerometer:
            f_b = f_in.copy()
            if self._accel_sampler is not None:
                f_b = self._accel_sampler.before_errors(f_b)
            if self._accel_errors is not None:
                f_b = self._accel_errors.apply(f_b)
                self.effects_run.update(f"accelerometer.{e}"
                                        for e in self._accel_errors.effects_run)
            if self._accel_sampler is not None:
                f_b = self._accel_sampler.clip(f_b)
                self.effects_run.update(f"accelerometer.{e}"
                                        for e in self._accel_sampler.effects_run)

        mag = None
        if spec.magnetometer is not None:
            self.effects_run.add("magnetometer")
            mag = measure_field(spec.magnetometer, t, sample.q_nb, self._mag_rng)

        self._k += n

        gimbal = None
        if self._free_gyro is not None:
            self.effects_run.add("free_gyro")
            angles, rates = self._free_gyro.run_until(t)
            gimbal = GimbalBlock(tuple(self._free_gyro.names), np.asarray(angles),
                                 np.asarray(rates))
        elif self._instrument is not None:
            self.effects_run.add(f"instrument.{spec.instrument.type}")
            gimbal = GimbalBlock(*self._instrument.advance(t))

        return SimBlock(
            t_ns=t_ns, omega_ib_b=gyro_out, specific_force_b=f_b, truth_q_nb=sample.q_nb,
            truth_omega_nb_b=sample.omega_nb_b, truth_omega_ib_b=w_ib, position_llh=llh,
            velocity_enu=sample.velocity_enu, gimbal=gimbal, magnetic_field_b=mag,
        )

    def _interval_means(self, t: np.ndarray, w_ib: np.ndarray, f_b: np.ndarray | None):
        """Gyro and accelerometer inputs: the values at ``t``, or for a sensor whose
        bandwidth is ``mean`` the mean over each sample interval (quadrature of the truth)."""
        g_avg = self._gyro_sampler is not None and self._gyro_sampler.averages
        a_avg = self._accel_sampler is not None and self._accel_sampler.averages
        if not (g_avg or a_avg):
            return w_ib, f_b
        sampler = self._gyro_sampler if g_avg else self._accel_sampler
        nodes = sampler.node_times(t).reshape(-1)
        sample, llh, w_ie, w_en, w_nodes = self._truth(nodes, need_accel=a_avg)
        n = t.shape[0]
        if g_avg:
            w_ib = self._gyro_sampler.mean_of(w_nodes.reshape(n, 3, 3))
        if a_avg:
            f_nodes = self._specific_force(sample, llh, w_ie, w_en)
            f_b = self._accel_sampler.mean_of(f_nodes.reshape(n, 3, 3))
        return w_ib, f_b

    @property
    def saturated(self) -> dict[str, int]:
        """Samples with an axis clipped at the output range so far, per named range."""
        out = {}
        for name, s in (("gyro", self._gyro_sampler), ("accelerometer", self._accel_sampler)):
            if s is not None and s.params.range is not None:
                out[name] = s.saturated
        return out

    def _gyro_indication(self, w_ib: np.ndarray, f_b: np.ndarray | None) -> np.ndarray:
        """Rate-gyro output, or for integrating gyros the mean rate over each sample interval
        (indicated-angle increment / dt, as a delta-angle IMU reports it)."""
        triad = self._rate_gyro
        if not triad.integrating:
            return np.asarray(triad.step_block(w_ib, f_b), dtype=np.float64)
        n = w_ib.shape[0]
        if n == 0:
            return np.empty((0, 3))
        k0 = 0
        out = np.empty((n, 3))
        if self._last_angle is None:  # first sample: the indicated rate θ̇ of the initial state
            first = triad.step_block(w_ib[:1], None if f_b is None else f_b[:1])
            out[0] = triad.state[:, 1]
            self._last_angle = first[0]
            k0 = 1
        theta = triad.step_block(w_ib[k0:], None if f_b is None else f_b[k0:])
        if theta.shape[0]:
            prev = np.concatenate((self._last_angle[None, :], theta[:-1]))
            out[k0:] = (theta - prev) / self.dt
            self._last_angle = theta[-1].copy()
        return out

    def imu_variances(self) -> tuple[np.ndarray | None, np.ndarray | None]:
        """Per-axis variance per sample of the gyro ((rad/s)²) and accelerometer ((m/s²)²)
        random errors (white noise, bias instability, quantization).

        An ideal instrument gives zeros ("known perfect"); the accelerometer entry is
        ``None`` when the scene has no accelerometer (publish −1: no estimate).
        Deterministic errors (bias, scale factor, misalignment, rate-gyro dynamics) are
        not random and are not part of the variance.
        """
        gyro = (self._gyro_errors.variances() if self._gyro_errors is not None
                else np.zeros(3))
        if not self.spec.accelerometer:
            return gyro, None
        accel = (self._accel_errors.variances() if self._accel_errors is not None
                 else np.zeros(3))
        return gyro, accel
