"""The local ENU navigation frame of the q_nb update and its per-interval rotation ζ."""

from __future__ import annotations

import bisect
from dataclasses import dataclass, field
from operator import itemgetter

import numpy as np

from gyro_attitude.core.earth import check_latitude, nav_rate_enu

# A carrier near the Earth: from the deepest mines to far above orbit heights, and well above
# orbital speed (8 km/s); beyond them the transport-rate formulas describe no carrier.
MIN_HEIGHT_M = -1.0e4
MAX_HEIGHT_M = 1.0e6
MAX_SPEED_M_S = 1.0e5


@dataclass(frozen=True)
class NavFrame:
    """Local ENU navigation frame whose rate ``ω_in^n = ω_ie^n + ω_en^n`` is removed.

    ``latitude_rad``, ``longitude_rad``, ``height_m`` (m above WGS-84) and
    ``velocity_enu`` (m/s, (3,)) are constants, or time series aligned with the samples
    (``(N,)`` and ``(N, 3)``).  Only latitude, height and velocity enter ``ω_in^n``.
    """

    latitude_rad: float | np.ndarray
    longitude_rad: float | np.ndarray = 0.0
    height_m: float | np.ndarray = 0.0
    velocity_enu: np.ndarray | tuple = field(default=(0.0, 0.0, 0.0))

    def series_length(self) -> int | None:
        """Number of samples of the time series held, or None for a constant frame."""
        n = None
        for arr, nd in ((self.latitude_rad, 0), (self.height_m, 0), (self.velocity_enu, 1)):
            a = np.asarray(arr)
            if a.ndim > nd:
                n = a.shape[0]
        return n

    def rate_enu(self, n_samples: int | None = None) -> np.ndarray:
        """``ω_in^n`` in rad/s: shape (3,) for constants or (n_samples, 3) for series."""
        lat = check_latitude(self.latitude_rad)
        h = np.asarray(self.height_m, dtype=np.float64)
        v = np.asarray(self.velocity_enu, dtype=np.float64)
        if v.shape[-1:] != (3,):
            raise ValueError(f"velocity_enu must have shape (3,) or (N, 3), got {v.shape}")
        if not (np.all(np.isfinite(h)) and np.all(np.isfinite(v))):
            raise ValueError("NavFrame height_m / velocity_enu contain non-finite values")
        if np.any(h < MIN_HEIGHT_M) or np.any(h > MAX_HEIGHT_M):
            raise ValueError(f"NavFrame height_m must be within [{MIN_HEIGHT_M:g}, "
                             f"{MAX_HEIGHT_M:g}] m, got {np.min(h):g}..{np.max(h):g}")
        if np.any(np.abs(v) > MAX_SPEED_M_S):
            raise ValueError(f"NavFrame velocity_enu must be within ±{MAX_SPEED_M_S:g} m/s per "
                             f"axis, got {np.max(np.abs(v)):g}")
        if lat.ndim > 0 or h.ndim > 0 or v.ndim > 1:
            if n_samples is None:
                raise ValueError("NavFrame holds time series; the sample count is needed")
            for name, arr, nd in (("latitude_rad", lat, 0), ("height_m", h, 0),
                                  ("velocity_enu", v, 1)):
                if arr.ndim > nd and arr.shape[0] != n_samples:
                    raise ValueError(f"NavFrame.{name} has {arr.shape[0]} samples, "
                                     f"expected {n_samples} (one per gyro sample)")
            lat, h = np.broadcast_to(lat, (n_samples,)), np.broadcast_to(h, (n_samples,))
            v = np.broadcast_to(v, (n_samples, 3))
        return nav_rate_enu(lat, h, v)


def nav_rate_for(nav: NavFrame | None, n_samples: int | None = None) -> np.ndarray | None:
    """``ω_in^n`` of ``nav`` for ``n_samples`` (by default its own series length): (3,) or
    (n_samples, 3), None without nav."""
    if nav is None:
        return None
    if not isinstance(nav, NavFrame):
        raise ValueError(f"nav must be a NavFrame or None, got {type(nav).__name__}")
    return nav.rate_enu(nav.series_length() if n_samples is None else n_samples)


def nav_zeta(t_ns: np.ndarray, rate_n: np.ndarray, k: np.ndarray) -> np.ndarray:
    """``ζ_k = ∫ ω_in^n dt`` over intervals ``k`` by the trapezoid (exact for constants)."""
    h = ((t_ns[k] - t_ns[k - 1]) * 1e-9)[:, None]
    if rate_n.ndim == 1:
        return rate_n[None, :] * h
    return 0.5 * (rate_n[k - 1] + rate_n[k]) * h


class VelocitySchedule:
    """Carrier velocities (an odometry topic) applied on the Imu time line, in stamp order.

    Before integrating an Imu sample at ``t``, the newest queued velocity stamped at or before
    ``t`` becomes the nav frame's velocity and holds from that sample on, until a newer one; a
    velocity that arrives after its Imu sample takes effect at the next one.  So the transport
    rate is time-aligned however the two topics interleave, and :func:`velocity_series` gives
    the same velocities for a whole recording.  At most ``kept`` velocities wait (the oldest go
    first); a backward time jump drops them (:meth:`clear`).
    """

    def __init__(self, kept: int = 1000):
        self.kept = int(kept)
        self._queue: list[tuple[int, np.ndarray]] = []

    def __len__(self) -> int:
        return len(self._queue)

    @property
    def last_t_ns(self) -> int | None:
        """Stamp of the newest queued velocity (None when none waits)."""
        return self._queue[-1][0] if self._queue else None

    def add(self, t_ns: int, velocity_enu) -> None:
        v = np.asarray(velocity_enu, dtype=np.float64)
        if v.shape != (3,) or not np.all(np.isfinite(v)):
            raise ValueError(f"velocity must be 3 finite numbers (m/s), got {velocity_enu!r}")
        # in stamp order (a late one inserted after those of equal stamp); the oldest go first
        bisect.insort(self._queue, (int(t_ns), v), key=itemgetter(0))
        if len(self._queue) > self.kept:
            del self._queue[0]

    def newest_due(self, t_ns: int) -> np.ndarray | None:
        """The newest velocity stamped at or before ``t_ns`` (and drop it and older ones), or
        None when none is due."""
        q = self._queue
        k = bisect.bisect_right(q, t_ns, key=itemgetter(0))
        if k == 0:
            return None
        v = q[k - 1][1]
        del q[:k]
        return v

    def clear(self) -> None:
        self._queue.clear()


def velocity_series(imu_t_ns, odom_t_ns, odom_v, initial=(0.0, 0.0, 0.0)) -> np.ndarray:
    """(N, 3) velocity in force at each Imu stamp: that of the newest odometry stamped at or
    before it (``initial`` before the first), as :class:`VelocitySchedule` applies them.
    ``odom_t_ns`` is sorted here (stable: of equal stamps the later message wins)."""
    t = np.asarray(imu_t_ns, dtype=np.int64)
    ot = np.asarray(odom_t_ns, dtype=np.int64)
    ov = np.asarray(odom_v, dtype=np.float64).reshape(-1, 3)
    order = np.argsort(ot, kind="stable")
    ot, ov = ot[order], ov[order]
    k = np.searchsorted(ot, t, side="right") - 1
    out = np.empty((t.size, 3))
    out[:] = np.asarray(initial, dtype=np.float64)
    out[k >= 0] = ov[k[k >= 0]]
    return out


def odometry_velocity(v_child, q_parent_child, child_frame_id: str, frame_id: str) -> np.ndarray:
    """The linear velocity (3,) of a ``nav_msgs/Odometry`` in its ``header.frame_id``: REP-105
    gives ``twist`` in ``child_frame_id``; when that is set and differs from ``frame_id`` it is
    rotated into the parent frame with the pose orientation (which maps child vectors into the
    parent, ``v_parent = C(q) v_child``, as gyro_sim's ``truth/odom`` fills it with q_nb and
    the body velocity); an empty or equal ``child_frame_id``: already in the parent frame.
    ``ValueError`` on a non-finite velocity or a zero or non-finite orientation it needs."""
    from gyro_attitude.core.rotation import quat_rotate

    v = np.asarray(v_child, dtype=np.float64).reshape(3)
    if not np.all(np.isfinite(v)):
        raise ValueError(f"odometry twist.linear is not finite: {v.tolist()}")
    if child_frame_id and child_frame_id != frame_id:
        q = np.asarray(q_parent_child, dtype=np.float64).reshape(4)
        if not np.all(np.isfinite(q)) or float(np.dot(q, q)) < 1e-18:
            raise ValueError(f"odometry pose orientation is zero or not finite: {q.tolist()}")
        v = quat_rotate(q / np.sqrt(np.dot(q, q)), v)
    return v
