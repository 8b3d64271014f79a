"""Directional gyro (book §2-5, §2-3): gimbal (cardan) error in bank and pitch, apparent drift
ω_ie sin L (+ transport rate) and its latitude-nut correction; closed forms for the checks.

Geometry.  Outer gimbal axis along the aircraft's z axis (vertical in the aircraft frame), inner
gimbal axis perpendicular to it, rotor axis ``r`` perpendicular to the inner axis.  The rotor
axis in body axes is ``r_b = Rz(ψ_g) Ry(θ_g) e_x``, so the outer gimbal angle (the card reading)
is ``ψ_g = atan2(r_b·e_y, r_b·e_x)`` measured counter-clockwise about body z from the nose to
the rotor axis; with the rotor along north and the aircraft level, ``ψ_g`` equals the true
heading (clockwise from north).  The indicated heading is ``ψ_g`` (plus the heading the rotor
was set to), and the inner gimbal angle ``θ_g = −asin(r_b·e_z)``.

Cardan error (closed form :func:`cardan_indicated_heading`).  With the aircraft at true heading ψ
(clockwise from north), pitch θ and roll φ (REP-103, ``q_nb = Rz(π/2 − ψ) Ry(θ) Rx(φ)``) and the
rotor along north, ``r_b = C_bn e_N = Rx(φ)ᵀ Ry(θ)ᵀ (cos ψ, sin ψ, 0)`` =
``(cos ψ cos θ, cos φ sin ψ + sin φ sin θ cos ψ, …)``, so ::

    tan ψ_g = (cos φ sin ψ + sin φ sin θ cos ψ) / (cos θ cos ψ)

— in a pure bank ``tan ψ_g = cos φ tan ψ``: no error on the cardinal headings, the largest near
the quadrantal ones (``≈ −(φ²/4) sin 2ψ`` for small φ).  The error is geometric: it
vanishes when the aircraft levels out again.

Drift.  The free rotor axis holds its inertial direction, so seen in the ENU frame it turns at
``−ω_in^n × r``: about the vertical that is an apparent drift of the rotor azimuth at
``ω_U = ω_ie sin L + v_E tan L / (R_N + h)`` (eastward in the north hemisphere), and the card
reading falls at that rate.  The latitude nut (a small weight on the inner gimbal) applies a
constant torque giving a precession about the outer gimbal axis at ``ω_ie sin L_nut``,
cancelling the Earth part when set to the latitude flown: residual drift
``ω_ie (sin L − sin L_nut)`` (:func:`directional_gyro_drift_rate`).  That holds while the rotor is
level: the horizontal Earth rate lifts a rotor off north at ``Ω cos L sin α`` and a tilted rotor
drifts at ``Ω sin L − Ω cos L tan β cos α``.  The optional leveling (erection) system precesses the
rotor toward the plane perpendicular to the outer gimbal axis at ``k_l sin θ_g``; at rest it holds
``β ≈ Ω cos L sin α / k_l``, leaving a drift error of at most ``Ω² cos² L / (2 k_l)``.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from gyro_attitude.core.earth import OMEGA_IE, check_latitude, radii_of_curvature
from gyro_attitude.core.instruments.common import (
    ChunkedOutput,
    carrier_point,
    carrier_truth,
    check_times,
    finite,
    integrate_chunked,
    nonnegative,
    positive,
    wrap_2pi,
)
from gyro_attitude.core.motion import Motion
from gyro_attitude.core.rotation import quat_conjugate, quat_rotate

__all__ = [
    "DirectionalGyroParams",
    "DirectionalGyroOutput",
    "DirectionalGyro",
    "cardan_indicated_heading",
    "cardan_error",
    "directional_gyro_drift_rate",
]


def cardan_indicated_heading(heading, pitch, roll) -> np.ndarray:
    """Outer-gimbal reading (rad, [0, 2π)) of a directional gyro whose rotor points north, for
    true ``heading`` (clockwise from north), ``pitch`` and ``roll`` (rad, REP-103), broadcast."""
    psi, th, ph = (np.asarray(x, dtype=np.float64) for x in (heading, pitch, roll))
    if not (np.all(np.isfinite(psi)) and np.all(np.isfinite(th)) and np.all(np.isfinite(ph))):
        raise ValueError("heading, pitch and roll must be finite")
    y = np.cos(ph) * np.sin(psi) + np.sin(ph) * np.sin(th) * np.cos(psi)
    x = np.cos(th) * np.cos(psi)
    return wrap_2pi(np.arctan2(y, x))


def cardan_error(heading, pitch, roll) -> np.ndarray:
    """Indicated minus true heading (rad, wrapped to [−π, π)) of :func:`cardan_indicated_heading`."""
    d = cardan_indicated_heading(heading, pitch, roll) - np.asarray(heading, dtype=np.float64)
    return np.mod(d + np.pi, 2.0 * np.pi) - np.pi


def directional_gyro_drift_rate(latitude: float, v_east: float = 0.0, latitude_nut: float | None = None,
                                height: float = 0.0) -> float:
    """Rate of change of the indicated heading (rad/s) of a level, unaccelerated DG:
    ``−(ω_ie sin L + v_E tan L/(R_N+h)) + ω_ie sin L_nut`` (no nut: the last term is 0)."""
    lat = float(check_latitude(finite(latitude, "latitude")))
    _, r_n = radii_of_curvature(lat)
    drift = OMEGA_IE * math.sin(lat) + finite(v_east, "v_east") * math.tan(lat) / (float(r_n)
                                                                                   + finite(height, "height"))
    nut = 0.0 if latitude_nut is None else OMEGA_IE * math.sin(
        float(check_latitude(finite(latitude_nut, "latitude_nut"), "latitude_nut")))
    return -drift + nut


@dataclass(frozen=True)
class DirectionalGyroParams:
    """``latitude_nut`` (rad, or None for no correction): the latitude the nut is set for;
    ``leveling_gain`` k_l (1/s, 0 = no leveling system)."""

    latitude_nut: float | None = None
    leveling_gain: float = 0.0

    def __post_init__(self):
        nonnegative(self.leveling_gain, "leveling_gain")
        if self.latitude_nut is not None:
            check_latitude(finite(self.latitude_nut, "latitude_nut"), "latitude_nut")


@dataclass(frozen=True)
class DirectionalGyroOutput(ChunkedOutput):
    """Per sample: ``t`` (s), ``heading_true``/``heading_indicated`` (rad clockwise from north,
    [0, 2π)), ``outer_gimbal``/``inner_gimbal`` angles (rad), ``latitude`` (rad)."""

    t: np.ndarray
    heading_true: np.ndarray
    heading_indicated: np.ndarray
    outer_gimbal: np.ndarray
    inner_gimbal: np.ndarray
    latitude: np.ndarray



class DirectionalGyro:
    """A DG on a carrier: ``ṙ = −ω_in^n × r + ω_ie sin L_nut z × r − k_l (r·z)(z − (r·z) r)``
    with ``z = C_nb e_z`` the outer gimbal axis (free rotor, the nut's precession about the outer
    axis, leveling toward the plane perpendicular to it), integrated by DOP853
    (:func:`.common.integrate_chunked`; the state is a slowly turning unit vector, so long steps
    are exact to the tolerance).  The rotor starts along north (a slaved, set DG)."""

    def __init__(self, params: DirectionalGyroParams):
        if not isinstance(params, DirectionalGyroParams):
            raise ValueError(f"params must be DirectionalGyroParams, got {type(params).__name__}")
        self.params = params

    def rhs(self, carrier: Motion, height: float):
        """Right-hand side ``ẏ(t, y)`` of the solver state ``(r_E, r_N, r_U, L)``."""
        nut = 0.0 if self.params.latitude_nut is None else OMEGA_IE * math.sin(self.params.latitude_nut)
        k_l = self.params.leveling_gain

        def rhs(t, y):
            r = y[:3]
            _, w, _, lat_rate = carrier_point(carrier, t, y[3], height)
            dr = -np.cross(w, r)
            if nut or k_l:
                z_n = quat_rotate(carrier.evaluate(np.array([t])).q_nb[0], [0.0, 0.0, 1.0])
                dr += nut * np.cross(z_n, r)
                rz = r @ z_n
                dr -= k_l * rz * (z_n - rz * r)
            return np.array([dr[0], dr[1], dr[2], lat_rate])

        return rhs

    #: Joints published for a scene (rad): the card reading and the two gimbal angles.
    JOINTS = ("heading_indicated", "outer_gimbal", "inner_gimbal")

    def initial_state(self, carrier: Motion, latitude: float, height: float = 0.0) -> np.ndarray:
        """Solver state ``(r_E, r_N, r_U, L)``: the rotor set along north."""
        if not isinstance(carrier, Motion):
            raise ValueError(f"carrier must be a core.motion.Motion, got {type(carrier).__name__}")
        finite(height, "height")
        return np.array([0.0, 1.0, 0.0, float(check_latitude(finite(latitude, "latitude")))])

    def outputs(self, tc: np.ndarray, yc: np.ndarray, carrier: Motion,
                height: float = 0.0) -> DirectionalGyroOutput:
        """Card reading and gimbal angles of solver states ``yc`` at times ``tc``."""
        r = yc[:, :3] / np.linalg.norm(yc[:, :3], axis=1, keepdims=True)
        tr = carrier_truth(carrier, tc, yc[:, 3], height)
        r_b = quat_rotate(quat_conjugate(tr.q_nb), r)
        outer = np.arctan2(r_b[:, 1], r_b[:, 0])
        inner = -np.arcsin(np.clip(r_b[:, 2], -1.0, 1.0))
        return DirectionalGyroOutput(tc, tr.heading, wrap_2pi(outer), outer, inner, yc[:, 3])

    @staticmethod
    def joint_positions(out: DirectionalGyroOutput) -> np.ndarray:
        """``(n, 3)`` angles in the order of :attr:`JOINTS`."""
        return np.stack((out.heading_indicated, out.outer_gimbal, out.inner_gimbal), axis=1)

    def iter_chunks(self, t_grid, carrier: Motion, latitude: float, height: float = 0.0,
                    chunk: int = 4096, rtol: float = 1e-11, atol: float = 1e-13,
                    max_step: float = 10.0) -> Iterator[DirectionalGyroOutput]:
        """Yield :class:`DirectionalGyroOutput` pieces of at most ``chunk`` samples."""
        t = check_times(t_grid)
        height = finite(height, "height")
        y0 = self.initial_state(carrier, latitude, height)
        positive(rtol, "rtol")
        positive(atol, "atol")
        for tc, yc in integrate_chunked(self.rhs(carrier, height), y0, t, chunk, rtol, atol, max_step):
            yield self.outputs(tc, yc, carrier, height)

    def simulate(self, t_grid, carrier: Motion, latitude: float, **kwargs) -> DirectionalGyroOutput:
        """The whole run at once (see :meth:`iter_chunks`)."""
        return DirectionalGyroOutput.concatenate(list(self.iter_chunks(t_grid, carrier, latitude, **kwargs)))
