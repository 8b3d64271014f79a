"""Gyro horizon / vertical gyro with an erection system (book §2-5, §5-3, §5-4): indicated roll and
pitch on a moving aircraft, and the closed-form errors of the erection law in a turn and under
linear acceleration.

Model (precession equations of :mod:`.common`).  The rotor's spin axis ``s`` (unit, ENU) is meant
to stay vertical.  The erection system senses the apparent vertical ``f̂ = f/|f|`` (the specific
force direction: what a pendulum or liquid level sees) and precesses ``s`` toward it:

* ``proportional``: ``ṡ_e = k (f̂ − (s·f̂) s)`` — rate ``k sin θ`` toward ``f̂`` for an angle θ;
* ``constant_rate``: ``ṡ_e = ε (f̂ − (s·f̂) s) / max(|f̂ − (s·f̂) s|, sin θ_lin)`` — a constant rate
  ``ε`` once ``θ > θ_lin``, proportional (gain ε/θ_lin) inside the linear zone (real
  constant-rate erectors have that zone; without it the law chatters about the vertical).

With the drift of a free axis in the rotating frame, ``ṡ = ṡ_e − ω_in^n × s``.  The gimbals: outer
axis along the aircraft's longitudinal (x) axis, inner axis perpendicular to it and to ``s``, so
the gimbal angles are the roll and pitch of the aircraft relative to the frame whose up is ``s``
(:func:`.common.roll_pitch_from_up` with ``s`` in body axes): the indicated roll and pitch.

Steady coordinated turn, proportional law (derivation of :func:`vertical_gyro_turn_indication`).
Turn rate ω about the vertical, bank φ with ``tan φ = V|ω|/g``.  The apparent vertical is the
aircraft's own z axis, ``f̂ = sin φ x̂_c + cos φ ẑ`` (x̂_c horizontal toward the turn centre), which
is fixed in a frame turning with the aircraft.  Neglecting Earth and transport rate, in that frame
the axis is steady when ``k (f̂ − μ s) = ω ẑ × s``, ``μ = s·f̂``.  With ``s = a x̂_c + b ŷ + c ẑ``,
``ŷ = ẑ × x̂_c``, the three components read::

    k (sin φ − μ a) = −ω b,     −k μ b = ω a,     k (cos φ − μ c) = 0

so ``a = k² μ sin φ / (k² μ² + ω²)``, ``b = −k ω sin φ / (k² μ² + ω²)``, ``c = cos φ / μ``, and
``μ = a sin φ + c cos φ`` gives for ``m = μ²`` the quadratic ``k² m² + (ω² − k²) m − ω² cos² φ = 0``
(positive root; ``m = 1`` for φ = 0).  Then ``s`` in body axes (x along the velocity, y left,
z = f̂) gives the indicated roll and pitch.  Limits: ``k ≪ ω`` → ``s`` stays near the true
vertical (roll error ≈ φ k²/ω², pitch error ≈ φ k/ω); ``k ≫ ω`` → ``s`` follows ``f̂`` and the
horizon shows wings level (roll error → φ).  That is why real horizons cut the erection out in
turns.

Linear acceleration a along track (proportional law): ``f̂`` tilts back by ``θ_a = atan(a/g)`` and
the axis angle obeys ``θ̇ = k sin(θ_a − θ)``, whose solution ``tan((θ_a − θ)/2) =
tan(θ_a/2) e^{−kt}`` is the indicated nose-up pitch error θ
(:func:`vertical_gyro_acceleration_error`).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from gyro_attitude.core.earth import OMEGA_IE, STANDARD_GRAVITY, check_latitude
from gyro_attitude.core.instruments.common import (
    ChunkedOutput,
    carrier_point,
    carrier_truth,
    check_times,
    finite,
    integrate_chunked,
    nonnegative,
    positive,
    roll_pitch_from_up,
)
from gyro_attitude.core.motion import Motion
from gyro_attitude.core.rotation import quat_conjugate, quat_rotate

__all__ = [
    "ERECTION_LAWS",
    "VerticalGyroParams",
    "VerticalGyroOutput",
    "VerticalGyro",
    "vertical_gyro_turn_indication",
    "vertical_gyro_acceleration_error",
    "vertical_gyro_rest_tilt",
]

ERECTION_LAWS = ("proportional", "constant_rate")


@dataclass(frozen=True)
class VerticalGyroParams:
    """``erection_law`` ('proportional' | 'constant_rate'); ``erection_gain`` k (1/s) of the
    proportional law; ``erection_rate`` ε (rad/s) and ``linear_zone`` θ_lin (rad) of the
    constant-rate law."""

    erection_law: str = "proportional"
    erection_gain: float = 0.02
    erection_rate: float = math.radians(3.0) / 60.0
    linear_zone: float = math.radians(0.5)

    def __post_init__(self):
        if self.erection_law not in ERECTION_LAWS:
            raise ValueError(f"erection_law must be one of {ERECTION_LAWS}, got {self.erection_law!r}")
        positive(self.erection_gain, "erection_gain")
        positive(self.erection_rate, "erection_rate")
        lz = positive(self.linear_zone, "linear_zone")
        if lz >= math.pi / 2:
            raise ValueError(f"linear_zone must be < π/2 rad, got {self.linear_zone!r}")


@dataclass(frozen=True)
class VerticalGyroOutput(ChunkedOutput):
    """Per sample: ``t`` (s), ``roll_indicated``/``pitch_indicated`` (the outer and inner gimbal
    angles, rad, REP-103 signs), ``roll_true``/``pitch_true`` (rad), ``spin_axis_tilt`` (angle of
    ``s`` from the true vertical, rad), ``latitude`` (rad)."""

    t: np.ndarray
    roll_indicated: np.ndarray
    pitch_indicated: np.ndarray
    roll_true: np.ndarray
    pitch_true: np.ndarray
    spin_axis_tilt: np.ndarray
    latitude: np.ndarray



class VerticalGyro:
    """A vertical gyro on a carrier: :meth:`simulate` or :meth:`iter_chunks` (bounded memory).
    DOP853 (:func:`.common.integrate_chunked`): the erection gain is slow (k ≲ 0.1/s) and smooth
    except at the constant-rate law's linear-zone edge, where step control handles the kink."""

    def __init__(self, params: VerticalGyroParams):
        if not isinstance(params, VerticalGyroParams):
            raise ValueError(f"params must be VerticalGyroParams, got {type(params).__name__}")
        self.params = params

    def rhs(self, carrier: Motion, height: float):
        """Right-hand side ``ẏ(t, y)`` of the solver state ``(s_E, s_N, s_U, L)``."""
        p = self.params
        proportional = p.erection_law == "proportional"
        sin_lin = math.sin(p.linear_zone)

        def rhs(t, y):
            s = y[:3] / math.sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2])
            f, w, _, lat_rate = carrier_point(carrier, t, y[3], height)
            fh = f / math.sqrt(f @ f)
            e = fh - (s @ fh) * s  # toward the apparent vertical, |e| = sin θ
            if proportional:
                e *= p.erection_gain
            else:
                e *= p.erection_rate / max(math.sqrt(e @ e), sin_lin)
            ds = e - np.cross(w, s)
            return np.array([ds[0], ds[1], ds[2], lat_rate])

        return rhs

    #: Joints published for a scene (rad): outer gimbal = indicated roll, inner = indicated pitch.
    JOINTS = ("roll_indicated", "pitch_indicated")

    def initial_state(self, carrier: Motion, latitude: float, height: float = 0.0,
                      spin_axis0=(0.0, 0.0, 1.0)) -> np.ndarray:
        """Solver state ``(s_E, s_N, s_U, L)``; ``spin_axis0`` in ENU (normalized)."""
        if not isinstance(carrier, Motion):
            raise ValueError(f"carrier must be a core.motion.Motion, got {type(carrier).__name__}")
        lat0 = float(check_latitude(finite(latitude, "latitude")))
        finite(height, "height")
        s0 = np.asarray(spin_axis0, dtype=np.float64)
        if s0.shape != (3,) or not np.all(np.isfinite(s0)) or np.linalg.norm(s0) == 0.0:
            raise ValueError(f"spin_axis0 must be a finite nonzero 3-vector, got {spin_axis0!r}")
        s0 = s0 / np.linalg.norm(s0)
        if s0[2] <= 0.0:
            raise ValueError("spin_axis0 must point above the horizon")
        return np.array([s0[0], s0[1], s0[2], lat0])

    def outputs(self, tc: np.ndarray, yc: np.ndarray, carrier: Motion,
                height: float = 0.0) -> VerticalGyroOutput:
        """Indicated and true roll/pitch of solver states ``yc`` at times ``tc``."""
        s = yc[:, :3] / np.linalg.norm(yc[:, :3], axis=1, keepdims=True)
        tr = carrier_truth(carrier, tc, yc[:, 3], height)
        q_bn = quat_conjugate(tr.q_nb)
        roll_i, pitch_i = roll_pitch_from_up(quat_rotate(q_bn, s))
        roll_t, pitch_t = roll_pitch_from_up(quat_rotate(q_bn, [0.0, 0.0, 1.0]))
        tilt = np.arccos(np.clip(s[:, 2], -1.0, 1.0))
        return VerticalGyroOutput(tc, roll_i, pitch_i, roll_t, pitch_t, tilt, yc[:, 3])

    @staticmethod
    def joint_positions(out: VerticalGyroOutput) -> np.ndarray:
        """``(n, 2)`` angles in the order of :attr:`JOINTS`."""
        return np.stack((out.roll_indicated, out.pitch_indicated), axis=1)

    def iter_chunks(self, t_grid, carrier: Motion, latitude: float, height: float = 0.0,
                    spin_axis0=(0.0, 0.0, 1.0), chunk: int = 4096, rtol: float = 1e-10,
                    atol: float = 1e-12, max_step: float = 1.0) -> Iterator[VerticalGyroOutput]:
        """Yield :class:`VerticalGyroOutput` pieces of at most ``chunk`` samples.

        ``spin_axis0``: initial spin axis in ENU (normalized; default the true vertical).
        """
        t = check_times(t_grid)
        height = finite(height, "height")
        y0 = self.initial_state(carrier, latitude, height, spin_axis0)
        positive(rtol, "rtol")
        positive(atol, "atol")
        for tc, yc in integrate_chunked(self.rhs(carrier, height), y0, t, chunk, rtol, atol, max_step):
            yield self.outputs(tc, yc, carrier, height)

    def simulate(self, t_grid, carrier: Motion, latitude: float, **kwargs) -> VerticalGyroOutput:
        """The whole run at once (see :meth:`iter_chunks`)."""
        return VerticalGyroOutput.concatenate(list(self.iter_chunks(t_grid, carrier, latitude, **kwargs)))


def vertical_gyro_turn_indication(turn_rate: float, bank: float,
                                  erection_gain: float) -> tuple[float, float]:
    """Steady indicated ``(roll, pitch)`` (rad, REP-103) in a coordinated level turn, proportional
    erection with gain ``k``, Earth and transport rate neglected (module docstring).

    ``turn_rate`` ω (rad/s, + = left), ``bank`` φ = atan(V|ω|/g) ≥ 0 (rad, its magnitude).  The
    true attitude is roll = −φ for a left turn, +φ for a right turn, pitch 0.
    """
    w = finite(turn_rate, "turn_rate")
    phi = nonnegative(bank, "bank")
    if phi >= math.pi / 2:
        raise ValueError(f"bank must be < π/2, got {bank!r}")
    k = positive(erection_gain, "erection_gain")
    sp, cp = math.sin(phi), math.cos(phi)
    # positive root of k² m² + (ω² − k²) m − ω² cos²φ = 0, written to avoid cancellation
    bq = w * w - k * k
    disc = math.sqrt(bq * bq + 4.0 * k * k * w * w * cp * cp)
    m = (2.0 * w * w * cp * cp / (bq + disc)) if bq > 0.0 else ((disc - bq) / (2.0 * k * k))
    mu = math.sqrt(m)
    den = k * k * m + w * w
    a = k * k * mu * sp / den
    b = -k * w * sp / den
    c = cp / mu
    if w >= 0.0:  # left turn: body x = −ŷ, body y = cos φ x̂_c − sin φ ẑ
        s_b = (-b, a * cp - c * sp, a * sp + c * cp)
    else:  # right turn: body x = ŷ, body y = −cos φ x̂_c + sin φ ẑ
        s_b = (b, -a * cp + c * sp, a * sp + c * cp)
    roll, pitch = roll_pitch_from_up(np.array(s_b))
    return float(roll), float(pitch)


def vertical_gyro_acceleration_error(accel: float, erection_gain: float, t,
                                     gravity: float = STANDARD_GRAVITY):
    """Indicated pitch (rad, REP-103: negative = nose up) after ``t`` s of a constant along-track
    ``accel`` (m/s²) from a vertical start, proportional erection:
    ``θ = θ_a − 2 atan(tan(θ_a/2) e^{−kt})``, ``θ_a = atan(a/g)``, pitch_indicated = −θ."""
    theta_a = math.atan2(finite(accel, "accel"), positive(gravity, "gravity"))
    k = positive(erection_gain, "erection_gain")
    t = np.asarray(t, dtype=np.float64)
    return -(theta_a - 2.0 * np.arctan(math.tan(0.5 * theta_a) * np.exp(-k * t)))


def vertical_gyro_rest_tilt(latitude: float, erection_gain: float) -> tuple[float, float]:
    """Steady spin-axis offset ``(s_E, s_N)`` (rad) at rest, proportional erection.

    The free axis drifts at ``−ω_ie × ẑ`` = ``(−Ω cos L, 0)`` horizontally and the vertical Earth
    rate turns the offset about the vertical: ``k s + Ω sin L (ẑ × s) = (−Ω cos L, 0)``, i.e. in
    complex form ``s_E + i s_N = −Ω cos L / (k + i Ω sin L)``."""
    lat = float(check_latitude(finite(latitude, "latitude")))
    z = -OMEGA_IE * math.cos(lat) / complex(positive(erection_gain, "erection_gain"),
                                            OMEGA_IE * math.sin(lat))
    return z.real, z.imag
