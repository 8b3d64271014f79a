"""Monte Carlo error budgets: many noise draws of a scene, each estimated as replay would, and the
statistics of the attitude error against the truth over time.

Run ``i`` of a setup simulates the scene (:class:`~gyro_attitude.core.scene.SceneSimulator`, in
memory, no MCAP) with its own seed: the integer drawn from child ``i`` of
``numpy.random.SeedSequence(seed).spawn(runs)``, so run ``i`` is the same whatever the number of
workers, their order or the machine they run on, and ``gyro-attitude simulate SCENE --seed
<that seed>`` writes the very measurements it used.  Every grade uses the same seeds (common
random numbers: grades are compared on the same draws).  The samples go through
:func:`gyro_attitude.offline.replay.estimate_recording`,
the one call into the estimator, with what a replay of that recording reads: the Imu stamps,
rates, the accelerometer when the scene has one, the per-sample gyro covariance the simulator
publishes, the initial attitude from the truth (or levelled), and the local ENU frame (latitude,
height and velocity of the truth) when the scene's gyro sees the Earth's rotation.

Errors of run ``i``, at every attitude:

* ``final_error_rad`` and the per-axis RMS: the body-frame error rotation vector
  ``log(q_true⁻¹ ⊗ q_est)`` (rad);
* heading: the twist about the local vertical of the nav-frame error ``δ = q_est ⊗ q_true⁻¹``,
  ``2·atan2(δ_z, δ_w)`` wrapped to (−π, π] (positive: the estimate is turned counter-clockwise,
  seen from above); tilt: the angle between the true and the estimated vertical in the body
  frame (independent of heading);
* NEES: ``Σ φ_k² / P_kk`` with ``φ = log δ`` the nav-frame error and ``P`` the per-axis
  orientation variance the estimator reports (its axes are the output's, covariance.py).

On a time grid of ``grid_points`` samples (the attitude of the last sample at or before each
grid sample), :func:`grade_statistics` gives the 50/68/95/99th percentiles over the runs of
the error angle, |heading| and tilt, the predicted standard deviations from the reported
variance, and the mean NEES against its two-sided 95 % χ² bounds: for R runs with 3 degrees of
freedom each, ``R·mean`` is χ²(3R) when the reported variance matches the spread.
"""

from __future__ import annotations

import dataclasses
import math
import os
import resource
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from gyro_attitude.core.attitude import NavFrame
from gyro_attitude.core.attitude.modes import Estimator as EstimatorKind
from gyro_attitude.core.attitude.modes import Frame, GyroBiasMode, InitialAttitudeSource, parse_mode
from gyro_attitude.core.attitude.stream import (
    StreamConfig,
)
from gyro_attitude.core.rotation import (
    _log_quat,
    _qmul,
    quat_as_rotvec,
    quat_conjugate,
    quat_multiply,
    quat_rotate,
)
from gyro_attitude.core.scene import MAX_RATE_HZ, SceneSimulator, SceneSpec
from gyro_attitude.core.sensor_errors import SensorErrorParams
from gyro_attitude.core.sim_topics import DEFAULT_FRAME_ID
from gyro_attitude.io.safe_output import raise_if_stop_requested, stop_handled
from gyro_attitude.offline.parallel import (
    CONNECT_TIMEOUT_S,
    NO_WORKER_TIMEOUT_S,
    TaskCost,
    WorkersLost,
    run_tasks,
)
from gyro_attitude.offline.replay import estimate_recording

#: what a run imports where it uses it, preloaded once for a pool's workers: the sensor errors'
#: filters (scipy.signal.lfilter) and the offline estimator's zero-phase filter
TASK_IMPORTS = ("scipy.signal",)

__all__ = [
    "PERCENTILES",
    "GRID_POINTS",
    "MAX_RUNS",
    "MAX_SAMPLES_PER_RUN",
    "Estimator",
    "SCENE_SETTINGS",
    "Grade",
    "MonteCarloSetup",
    "MonteCarloResult",
    "grades_of",
    "run_seeds",
    "run_one",
    "run_montecarlo",
    "grade_statistics",
    "nees_explanation",
    "write_plot",
]

PERCENTILES = (50, 68, 95, 99)
GRID_POINTS = 200
MAX_RUNS = 1_000_000
#: Samples of one run, simulated and estimated at once: a worker holds about 1 kB per sample at
#: its peak (measured: 420 MB for an hour at 100 Hz), so this is about 5 GB per worker.
MAX_SAMPLES_PER_RUN = 5_000_000
NEES_CONFIDENCE = 0.95
_UP = np.array([0.0, 0.0, 1.0])
_CONJ = np.array([-1.0, -1.0, -1.0, 1.0])
#: attitudes per block of the run's error sums (:func:`_body_error_sums`)
ERROR_BLOCK = 16384


# --------------------------------------------------------------------------- set-up
@dataclass(frozen=True)
class Grade:
    """One sensor grade compared: a label and the scene with that grade's sensor errors."""

    label: str
    spec: SceneSpec


def _scaled(p: SensorErrorParams, f: float) -> SensorErrorParams:
    """Every error magnitude of ``p`` times ``f`` (correlation times unchanged)."""
    return dataclasses.replace(
        p, bias=p.bias * f, scale_factor=p.scale_factor * f, misalignment=p.misalignment * f,
        noise_density=p.noise_density * f, bias_instability_sigma=p.bias_instability_sigma * f,
        quantum=p.quantum * f, bias_instability_floor=p.bias_instability_floor * f,
        rate_random_walk=p.rate_random_walk * f)


def grades_of(spec: SceneSpec, grades: Sequence[str], load: Callable[[str], SceneSpec]) \
        -> tuple[Grade, ...]:
    """The grades named by ``grades`` (none: the scene's own).

    Each is ``NAME`` (the gyro and accelerometer errors of scene ``NAME``, or of a YAML path),
    ``NAME*F`` (those scaled by F) or ``*F`` (the scene's own scaled by F); ``load`` reads a
    scene.  ValueError (one line) for a bad factor, an unknown scene or a repeated label.
    """
    if not grades:
        return (Grade(spec.name, spec),)
    out: list[Grade] = []
    for text in grades:
        name, _, factor_text = str(text).strip().partition("*")
        name = name.strip()
        factor = 1.0
        if factor_text:
            try:
                factor = float(factor_text)
            except ValueError:
                factor = math.nan
            if not (math.isfinite(factor) and 0.0 <= factor <= 1e6):
                raise ValueError(f"grade {text!r}: the factor after '*' must be a number in "
                                 f"[0, 1e6], got {factor_text!r}")
        if not name and not factor_text:
            raise ValueError("grade '': give a scene name, NAME*F or *F")
        source = load(name) if name else spec
        g = dataclasses.replace(spec, gyro_errors=_scaled(source.gyro_errors, factor),
                                accel_errors=_scaled(source.accel_errors, factor))
        label = (name or spec.name) + (f"*{factor:g}" if factor_text else "")
        if label in [x.label for x in out]:
            raise ValueError(f"grade {label!r} given twice")
        out.append(Grade(label, g))
    return tuple(out)


def _mc_default_config() -> StreamConfig:
    return StreamConfig(initial_attitude_source=InitialAttitudeSource.TRUTH)


#: Settings a Monte Carlo run takes from its scene, not from the user: the frame (ENU when the
#: scene's gyro sees the Earth's rotation) and where the carrier is and how fast it moves.
SCENE_SETTINGS = ("frame", "latitude_rad", "longitude_rad", "height_m", "velocity_enu")


@dataclass(frozen=True)
class Estimator:
    """How each run is estimated: ``algorithm`` (None: replay's default choice) and the
    estimator settings ``config`` (default: the table's, with the initial attitude from the
    truth at the first Imu stamp, as ``replay --initial-attitude truth``).  The settings of
    :data:`SCENE_SETTINGS` are replaced by the scene's in every run."""

    algorithm: str | None = None
    config: StreamConfig = field(default_factory=_mc_default_config)
    # replay's --estimator; causal by default: a budget is about what the live node delivers
    kind: EstimatorKind = EstimatorKind.CAUSAL

    def __post_init__(self):
        if not isinstance(self.config, StreamConfig):
            raise ValueError("config must be a StreamConfig")
        object.__setattr__(self, "kind", parse_mode(EstimatorKind, self.kind, "estimator"))

    def describe(self) -> dict:
        values = self.config.values()
        return {"algorithm": self.algorithm,
                "config": {k: v for k, v in values.items() if k not in SCENE_SETTINGS}}


def _check_number(name: str, value, lo: float, hi: float, *, lo_open: bool = True) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise ValueError(f"{name} must be a number, got {value!r}")
    v = float(value)
    if not (math.isfinite(v) and (v > lo if lo_open else v >= lo) and v <= hi):
        raise ValueError(f"{name} must be a finite number in {'(' if lo_open else '['}{lo:g}, "
                         f"{hi:g}], got {value!r}")
    return v


def _check_int(name: str, value, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or not lo <= value <= hi:
        raise ValueError(f"{name} must be an integer from {lo} to {hi}, got {value!r}")
    return int(value)


@dataclass(frozen=True)
class MonteCarloSetup:
    """What to run: ``runs`` draws of every grade, ``duration_s`` at ``rate_hz`` (None: the
    first grade's scene rate), seeds from ``seed``, estimated by ``estimator``, statistics on
    ``grid_points`` times.  Checked on construction (ValueError, one line)."""

    grades: tuple[Grade, ...]
    runs: int
    duration_s: float
    rate_hz: float | None = None
    seed: int = 0
    estimator: Estimator = field(default_factory=Estimator)
    grid_points: int = GRID_POINTS

    def __post_init__(self):
        if not self.grades or not all(isinstance(g, Grade) for g in self.grades):
            raise ValueError("at least one grade is needed")
        _check_int("runs", self.runs, 1, MAX_RUNS)
        _check_number("duration", self.duration_s, 0.0, 1e9)
        rate = self.grades[0].spec.rate_hz if self.rate_hz is None else self.rate_hz
        object.__setattr__(self, "rate_hz", _check_number("rate", rate, 0.0, MAX_RATE_HZ))
        _check_int("seed", self.seed, 0, 2**128)
        _check_int("grid points", self.grid_points, 2, 100_000)
        n = self.samples
        if n < 2:
            raise ValueError(f"duration {self.duration_s:g} s at {self.rate_hz:g} Hz gives "
                             f"{n} sample(s); at least 2 are needed")
        if n > MAX_SAMPLES_PER_RUN:
            raise ValueError(f"duration {self.duration_s:g} s at {self.rate_hz:g} Hz is {n:.3g} "
                             f"samples per run; the limit is {MAX_SAMPLES_PER_RUN}")

    @property
    def samples(self) -> int:
        return int(round(self.duration_s * self.rate_hz))

    def grid_indices(self) -> np.ndarray:
        """Sample indices of the time grid (first and last sample included)."""
        g = min(self.grid_points, self.samples)
        return np.unique(np.rint(np.linspace(0, self.samples - 1, g)).astype(np.int64))


def run_seeds(seed: int, runs: int) -> list[int]:
    """Seed of each run: a 64-bit integer from child ``i`` of ``SeedSequence(seed).spawn``
    (child ``i`` does not depend on how many there are)."""
    return [int(c.generate_state(1, np.uint64)[0])
            for c in np.random.SeedSequence(seed).spawn(runs)]


# --------------------------------------------------------------------------- one run
def _scene_frame(spec: SceneSpec, block, config: StreamConfig):
    """``(config, nav)`` for this scene: the settings of :data:`SCENE_SETTINGS` from the scene,
    and the local ENU frame replay would be given (latitude, height and velocity of the truth
    along the path), or None when the scene's gyro sees no Earth rotation (then the nav frame
    is inertial and q_ib = q_nb)."""
    ea = spec.earth
    moves = spec.motion.moves
    if not ea.rotation:
        if ea.transport_rate and moves:
            raise ValueError("a moving scene with transport rate but no Earth rotation has no "
                             "estimator frame (the ENU frame removes both)")
        return config.replace(frame=Frame.INERTIAL), None
    config = config.replace(frame=Frame.ENU, latitude_rad=ea.latitude_rad,
                            longitude_rad=ea.longitude_rad, height_m=ea.height_m,
                            velocity_enu=(0.0, 0.0, 0.0))
    if not moves:
        return config, config.nav_frame()
    llh = block.position_llh
    velocity = block.velocity_enu if ea.transport_rate else np.zeros((len(block.t_ns), 3))
    return config, NavFrame(latitude_rad=llh[:, 0], longitude_rad=llh[:, 1],
                            height_m=llh[:, 2], velocity_enu=velocity)


def _errors(q_est: np.ndarray, q_true: np.ndarray):
    """(body error rotvec (M,3), nav error rotvec (M,3), heading (M,), tilt (M,)) [rad]."""
    body = quat_as_rotvec(quat_multiply(quat_conjugate(q_true), q_est))
    delta = quat_multiply(q_est, quat_conjugate(q_true))
    nav = quat_as_rotvec(delta)
    # the twist about the vertical: with w >= 0, atan2 is within ±π/2, the angle within ±π
    d = np.where(delta[:, 3:4] < 0, -delta, delta)
    heading = 2.0 * np.arctan2(d[:, 2], d[:, 3])
    u_true = quat_rotate(quat_conjugate(q_true), _UP)
    u_est = quat_rotate(quat_conjugate(q_est), _UP)
    tilt = np.arctan2(np.linalg.norm(np.cross(u_true, u_est), axis=1),
                      np.einsum("ij,ij->i", u_true, u_est))
    return body, nav, heading, tilt


def _body_error_sums(q_true: np.ndarray, q_est: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(Σ e², e_last)`` per axis of the body-frame error rotation vectors
    ``e = log(q_true* ⊗ q_est)``, in blocks of :data:`ERROR_BLOCK` rows: the temporaries of
    the product and the logarithm stay in cache, and no (M, 3) series is kept."""
    sq = np.zeros(3)
    e = np.zeros((1, 3))
    for lo in range(0, q_est.shape[0], ERROR_BLOCK):
        # (not normalized first: the logarithm does not depend on the norm)
        e = _log_quat(_qmul(q_true[lo:lo + ERROR_BLOCK] * _CONJ, q_est[lo:lo + ERROR_BLOCK]))
        sq += np.einsum("ij,ij->j", e, e)
    return sq, e[-1]


def simulate_run(spec: SceneSpec, rate_hz: float, samples: int, seed: int):
    """The measurements and truth of one run (a :class:`~gyro_attitude.core.scene.SimBlock`)
    and the per-sample gyro variance the simulator publishes with them."""
    sim = SceneSimulator(spec, rate_hz, seed=seed)
    block = sim.next_block(samples)
    gyro_var, _ = sim.imu_variances()
    return block, gyro_var


def run_one(spec: SceneSpec, setup: MonteCarloSetup, index: int, seed: int, label: str) -> dict:
    """One run: its entry of the ``runs`` list, with the grid series under ``"_grid"``.
    Raises what the simulator or the estimator raise (the caller reports it)."""
    t0, c0 = time.perf_counter(), time.process_time()
    est = setup.estimator
    if spec.accelerometer and not est.config.uses_accelerometer:
        spec = dataclasses.replace(spec, accelerometer=False)
    block, gyro_var = simulate_run(spec, setup.rate_hz, setup.samples, seed)
    t_ns = block.t_ns
    n = t_ns.shape[0]
    cov = np.broadcast_to(np.diag(np.asarray(gyro_var, np.float64)).reshape(9), (n, 9))
    config, nav = _scene_frame(spec, block, est.config)
    got = estimate_recording(t_ns, block.omega_ib_b, block.specific_force_b, cov,
                             DEFAULT_FRAME_ID, config=config, nav=nav, algorithm=est.algorithm,
                             estimator=est.kind, truth=(t_ns, block.truth_q_nb))
    res, first = got.result, got.first
    m = res.index.size
    if m == 0:
        reasons = ", ".join(f"{k} {r}" for r, k in res.counts.items() if k)
        raise ValueError(f"no attitude: every sample skipped ({reasons})")
    sample = res.index + first  # sample indices of the attitudes
    if sample[-1] - sample[0] == m - 1:  # none skipped: a view, not a copy
        q_true = block.truth_q_nb[sample[0]:sample[-1] + 1]
    else:
        q_true = block.truth_q_nb[sample]
    # the body-frame error at every attitude (its RMS); the rest at the grid and the end only.
    # Kernels without the public functions' finiteness and norm checks: both inputs are unit
    # quaternions the simulator and the estimator guarantee.
    body_sq, body_final = _body_error_sums(q_true, res.q)
    grid = setup.grid_indices()
    pos = np.searchsorted(sample, grid, side="right") - 1
    have = pos >= 0
    rows = np.append(np.where(have, pos, 0), m - 1)
    body, nav_err, heading, tilt = _errors(res.q[rows], q_true[rows])
    nan = np.full(grid.shape, np.nan)
    angle = np.where(have, np.linalg.norm(body[:-1], axis=1), nan)
    var = np.full((grid.size + 1, 3), np.nan)
    nees = np.full(grid.size + 1, np.nan)
    if res.variance is not None:
        v = res.variance[rows]
        known = np.append(have, True) & res.variance_known[rows] & (v > 0).all(axis=1)
        var = np.where(known[:, None], v, np.nan)
        nees = np.where(known, np.sum(nav_err ** 2 / np.where(known[:, None], v, 1.0), axis=1),
                        np.nan)
    skipped = {r: int(k) for r, k in res.counts.items() if k}
    final_var = var[-1]
    return {
        "index": int(index), "grade": label, "seed": int(seed),
        "final_error_rad": body_final.tolist(),
        "final_error_angle_rad": float(np.linalg.norm(body_final)),
        "rms_error_rad": np.sqrt(body_sq / m).tolist(),
        "final_heading_error_rad": float(heading[-1]),
        "final_tilt_error_rad": float(tilt[-1]),
        "final_sigma_rad": (np.sqrt(final_var).tolist() if np.isfinite(final_var).all()
                            else None),
        "final_nees": float(nees[-1]) if np.isfinite(nees[-1]) else None,
        "samples": int(n), "attitudes": int(m), "events": skipped,
        "wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0,
        "_grid": {"angle": angle, "heading": np.where(have, heading[:-1], nan),
                  "tilt": np.where(have, tilt[:-1], nan), "var": var[:-1], "nees": nees[:-1]},
    }


def _run_chunk(task) -> list[dict]:
    """Worker entry: the runs ``indices`` of grade ``g`` (a failing run is an entry with
    ``error``, the others go on)."""
    setup, g, indices, seeds = task
    grade = setup.grades[g]
    out = []
    for i, s in zip(indices, seeds, strict=True):
        raise_if_stop_requested()  # (in this process: a stop whose exception was swallowed)
        try:
            out.append(run_one(grade.spec, setup, i, s, grade.label))
        except Exception as exc:  # reported per run: one bad draw must not lose the rest
            raise_if_stop_requested()  # the error is the stop itself, swallowed on its way
            text = str(exc).strip().splitlines()
            out.append({"index": int(i), "grade": grade.label, "seed": int(s),
                        "error": f"{type(exc).__name__}: {text[0] if text else ''}"})
    return out


# --------------------------------------------------------------------------- statistics
def _percentiles(x: np.ndarray) -> dict[str, np.ndarray]:
    """Percentiles over runs (axis 0), NaN where no run has a value."""
    out = {}
    have = np.isfinite(x).any(axis=0)
    for p in PERCENTILES:
        v = np.full(x.shape[1:], np.nan)
        if have.any():
            v[have] = np.nanpercentile(x[:, have], p, axis=0)
        out[f"p{p}"] = v
    return out


def nees_bounds(runs: np.ndarray, dof: int = 3, confidence: float = NEES_CONFIDENCE):
    """Two-sided bounds of the mean NEES over ``runs`` runs (χ²(dof·runs)/runs)."""
    from scipy.stats import chi2  # only for the statistics (0.3 s of imports)

    r = np.asarray(runs, dtype=np.float64)
    lo = np.full(r.shape, np.nan)
    hi = np.full(r.shape, np.nan)
    ok = r > 0
    a = (1.0 - confidence) / 2.0
    lo[ok] = chi2.ppf(a, dof * r[ok]) / r[ok]
    hi[ok] = chi2.ppf(1.0 - a, dof * r[ok]) / r[ok]
    return lo, hi


def grade_statistics(setup: MonteCarloSetup, runs: list[dict]) -> dict:
    """Statistics over the finished runs of one grade (see the module docstring)."""
    ok = [r for r in runs if "error" not in r]
    grid = setup.grid_indices()
    time_s = grid / setup.rate_hz
    out = {"runs_finished": len(ok), "runs_failed": len(runs) - len(ok),
           "time_s": time_s}
    if not ok:
        return out
    angle = np.array([r["_grid"]["angle"] for r in ok])
    heading = np.abs(np.array([r["_grid"]["heading"] for r in ok]))
    tilt = np.array([r["_grid"]["tilt"] for r in ok])
    var = np.array([r["_grid"]["var"] for r in ok])
    nees = np.array([r["_grid"]["nees"] for r in ok])
    out["error_angle_rad"] = _percentiles(angle)
    out["heading_error_rad"] = _percentiles(heading)
    out["tilt_error_rad"] = _percentiles(tilt)
    with np.errstate(invalid="ignore"):
        n_var = np.isfinite(var).all(axis=2).sum(axis=0)
        mean_var = np.where(n_var[:, None] > 0,
                            np.nansum(var, axis=0) / np.maximum(n_var, 1)[:, None], np.nan)
    out["predicted_sigma_rad"] = {
        "angle": np.sqrt(mean_var.sum(axis=1)), "heading": np.sqrt(mean_var[:, 2]),
        "tilt": np.sqrt(mean_var[:, 0] + mean_var[:, 1])}
    n_nees = np.isfinite(nees).sum(axis=0)
    with np.errstate(invalid="ignore"):
        mean_nees = np.where(n_nees > 0, np.nansum(nees, axis=0) / np.maximum(n_nees, 1),
                             np.nan)
    lo, hi = nees_bounds(n_nees)
    checked = n_nees > 0
    within = checked & (mean_nees >= lo) & (mean_nees <= hi)
    final = [r["final_nees"] for r in ok if r["final_nees"] is not None]
    f_lo, f_hi = nees_bounds(np.array([len(final)]))
    out["nees"] = {
        "dof": 3, "confidence": NEES_CONFIDENCE, "runs": n_nees, "mean": mean_nees,
        "lower": lo, "upper": hi,
        "fraction_within": float(within.sum() / checked.sum()) if checked.any() else None,
        "final": {"runs": len(final), "mean": float(np.mean(final)) if final else None,
                  "lower": float(f_lo[0]) if final else None,
                  "upper": float(f_hi[0]) if final else None,
                  "within": bool(f_lo[0] <= np.mean(final) <= f_hi[0]) if final else None}}
    e = np.array([r["final_error_rad"] for r in ok])
    out["final"] = {
        "error_angle_rad": {f"p{p}": float(np.percentile(np.linalg.norm(e, axis=1), p))
                            for p in PERCENTILES},
        "per_axis_mean_rad": e.mean(axis=0).tolist(),
        "per_axis_std_rad": (e.std(axis=0, ddof=1).tolist() if len(ok) > 1 else None),
        "heading_error_rad": {f"p{p}": float(np.percentile(
            np.abs([r["final_heading_error_rad"] for r in ok]), p)) for p in PERCENTILES},
        "tilt_error_rad": {f"p{p}": float(np.percentile(
            [r["final_tilt_error_rad"] for r in ok], p)) for p in PERCENTILES},
    }
    return out


def _si(x) -> str:
    return f"{float(np.max(np.abs(x))):.3g}"


def nees_explanation(spec: SceneSpec, config: StreamConfig, above: bool) -> list[str]:
    """Why the mean NEES of a grade lies outside its band: the terms of ``spec``'s gyro that
    the covariance the estimator reports (core/attitude/covariance.py) leaves out with the
    settings ``config`` (``above``: NEES above the band, the errors are larger than reported),
    or counts as white rate noise though they are not (below the band).  Read off the scene
    and the settings, not fitted: a list of plain sentences (empty when no term explains it).

    The covariance integrates the per-sample gyro variance the simulator publishes (white
    noise N²/dt, the bias instability's stationary σ², quantization q²/(6 dt²)) as white rate
    noise, a bias random walk ``gyro_bias_rw`` between rests, and the standard error of the
    white noise at each rest sample (gyro_bias auto) or ``gyro_bias_sigma_rad_s``."""
    g = spec.gyro_errors
    sampling = spec.gyro_sampling
    turning = spec.motion_type != "stationary"
    mode = config.gyro_bias
    out: list[str] = []
    if not above:
        if np.any(g.quantum > 0):
            out.append(f"quantization ({_si(g.quantum)} rad of integrated output) is counted as "
                       "white rate noise, q²/(6 dt²) a sample, but its angle error stays within "
                       "a quantum: the reported variance grows where the error does not")
        return out
    if np.any(g.bias_instability_floor > 0) or np.any(g.bias_instability_sigma > 0):
        what = (f"Allan floor {_si(g.bias_instability_floor)} rad/s"
                if np.any(g.bias_instability_floor > 0) else
                f"Gauss–Markov σ {_si(g.bias_instability_sigma)} rad/s, τ "
                f"{_si(g.bias_instability_tau)} s")
        out.append(f"bias instability ({what}) is counted as white rate noise, but it is "
                   "correlated over tens to hundreds of seconds: its integral grows faster "
                   "than the reported variance (the covariance has no bias-instability state)")
    k = g.rate_random_walk
    if np.any(k > 0):
        if mode is GyroBiasMode.AUTO:
            out.append(f"rate random walk ({_si(k)} rad/s/√s): with gyro_bias auto the bias "
                       "variance is set at every rest sample from the white-noise spread "
                       "alone (gyro_bias_rw acts only between rests), so the bias drift "
                       "within the averaging window is not in it")
        elif config.gyro_bias_rw < float(np.max(k)):
            out.append(f"rate random walk ({_si(k)} rad/s/√s) against gyro_bias_rw "
                       f"{config.gyro_bias_rw:.3g}")
    fixed = np.abs(g.bias)
    if sampling.turn_on_bias_sigma is not None:
        fixed = fixed + 2.0 * np.asarray(sampling.turn_on_bias_sigma)
    sigma = config.gyro_bias_sigma_rad_s
    if np.any(fixed > 0) and float(np.max(fixed)) > 2.0 * sigma:
        if mode is GyroBiasMode.NONE:
            out.append(f"a fixed gyro bias (up to {_si(fixed)} rad/s) is not subtracted "
                       f"(gyro_bias none) and gyro_bias_sigma_rad_s is {sigma:.3g}")
        elif mode is GyroBiasMode.AUTO and turning:
            out.append(f"a fixed gyro bias (up to {_si(fixed)} rad/s) is subtracted only from "
                       "a rest: where the motion leaves none it stays, with variance "
                       f"gyro_bias_sigma_rad_s² = {sigma:.3g}²")
    if turning and (np.any(g.scale_factor != 0) or np.any(g.misalignment != 0)):
        out.append("scale factor and misalignment errors times the motion's rates are not in "
                   "the covariance")
    if sampling.g_sensitivity is not None:
        out.append("g-sensitivity (rate error from the specific force) is not in the covariance")
    if turning and (spec.gyro_model != "ideal" or sampling.bandwidth is not None):
        out.append(f"the {spec.gyro_model if spec.gyro_model != 'ideal' else 'band-limited'} "
                   "gyro's dynamic error on the motion is not in the covariance")
    return out


# --------------------------------------------------------------------------- the whole set
@dataclass
class MonteCarloResult:
    """Runs finished (``runs``: one entry per run, grade by grade in index order; a failed run
    has ``error``), whether the set was ``interrupted``, the wall time and where it ran;
    ``cost`` what the processes that ran it used (:class:`~.parallel.TaskCost`; None when
    interrupted), ``own_cpu_s`` this process's CPU seconds over the set (in a pool: submitting,
    collecting; in this process: the runs too), ``load_average`` the 1-minute load average
    of the machine at the start and the end (what the wall time competed with)."""

    setup: MonteCarloSetup
    runs: list[dict]
    interrupted: bool
    wall_s: float
    workers: int
    scheduler: str | None
    cost: TaskCost | None = None
    own_cpu_s: float | None = None
    load_average: tuple[float, float] | None = None
    #: why the set ended before every run finished (the Dask cluster lost its workers), or None
    stopped: str | None = None

    @property
    def complete(self) -> bool:
        return not self.interrupted and self.stopped is None and \
            len(self.runs) == self.setup.runs * len(self.setup.grades)

    @property
    def failed(self) -> list[dict]:
        return [r for r in self.runs if "error" in r]

    def statistics(self) -> list[dict]:
        out = []
        for g in self.setup.grades:
            st = {"label": g.label, **grade_statistics(
                self.setup, [r for r in self.runs if r["grade"] == g.label])}
            final = st.get("nees", {}).get("final")
            if final is not None and final["within"] is False:
                # outside its band: which of the scene's terms the reported covariance misses
                above = final["mean"] > final["upper"]
                final["outside"] = "above" if above else "below"
                final["explanation"] = nees_explanation(
                    g.spec, self.setup.estimator.config, above)
            out.append(st)
        return out

    def cost_per_run_s(self) -> float | None:
        """Wall time of the whole set per finished run (pool start-up included)."""
        done = [r for r in self.runs if "error" not in r]
        return self.wall_s / len(done) if done else None

    def total_cpu_s(self) -> float | None:
        """CPU seconds of every process of ours that worked on the set (the workers' whole
        lives and this process's share; None on Dask or when interrupted)."""
        if self.cost is None or self.cost.cpu_s is None or self.own_cpu_s is None:
            return None
        if self.scheduler is None and self.workers == 1:
            return self.own_cpu_s  # the runs ran in this process: counted once
        return self.cost.cpu_s + self.own_cpu_s

    def to_json(self) -> dict:
        s = self.setup
        done = [r for r in self.runs if "error" not in r]
        total_cpu = self.total_cpu_s()
        return _jsonable({
            "scene": s.grades[0].spec.name, "runs_requested": s.runs,
            "duration_s": s.duration_s, "rate_hz": s.rate_hz, "samples_per_run": s.samples,
            "seed": s.seed, "grades": [g.label for g in s.grades],
            "estimator": s.estimator.describe(),
            "complete": self.complete, "interrupted": self.interrupted,
            "stopped": self.stopped,
            "runs_finished": len(done), "runs_failed": len(self.failed),
            "workers": self.workers, "scheduler": self.scheduler, "wall_s": self.wall_s,
            "cost_per_run_s": self.cost_per_run_s(),
            # everything our processes spent, per run: start-up, transfer and waits included
            "cpu_s": total_cpu,
            "total_cpu_per_run_s": (total_cpu / len(done) if done and total_cpu is not None
                                    else None),
            "worker_processes": None if self.cost is None else self.cost.processes,
            "pool_startup_s": None if self.cost is None else self.cost.startup_s,
            "load_average_1min": (None if self.load_average is None
                                  else list(self.load_average)),
            "compute_per_run_s": (float(np.mean([r["wall_s"] for r in done])) if done
                                  else None),
            "cpu_per_run_s": float(np.mean([r["cpu_s"] for r in done])) if done else None,
            "runs": [{k: v for k, v in r.items() if k != "_grid"} for r in self.runs],
            "statistics": self.statistics(),
        })


def _jsonable(x):
    """Lists for arrays, None for NaN (JSON has no NaN)."""
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    if isinstance(x, np.generic):
        return _jsonable(x.item())
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


_RUNS_PER_TASK = 4


def _chunks(setup: MonteCarloSetup, workers: int) -> list[tuple]:
    """Tasks of a few runs each: enough that every worker has many (the last task, which
    may run while the other workers have nothing left, is short: at most
    :data:`_RUNS_PER_TASK` runs), few enough that the per-task cost vanishes (a task's
    set-up pickles to ~5 kB and a run's result to ~12 kB, a round trip of a few ms against
    the tenths of a second of a run)."""
    seeds = run_seeds(setup.seed, setup.runs)
    total = setup.runs * len(setup.grades)
    size = max(1, min(_RUNS_PER_TASK, math.ceil(total / (16 * max(workers, 1)))))
    tasks = []
    for g in range(len(setup.grades)):
        for a in range(0, setup.runs, size):
            idx = list(range(a, min(a + size, setup.runs)))
            tasks.append((setup, g, idx, [seeds[i] for i in idx]))
    return tasks


def run_montecarlo(setup: MonteCarloSetup, *, workers: int = 1, scheduler: str | None = None,
                   progress: bool = False,
                   connect_timeout_s: float = CONNECT_TIMEOUT_S,
                   no_worker_timeout_s: float = NO_WORKER_TIMEOUT_S) -> MonteCarloResult:
    """Every run of ``setup`` on ``workers`` local processes (1: this process) or the Dask
    scheduler at ``scheduler``.  A Ctrl-C returns what finished with ``interrupted`` set; a
    Dask cluster without a worker for ``no_worker_timeout_s`` returns what finished with
    ``stopped`` saying so.  Raises :class:`~.parallel.SchedulerUnreachable` and ValueError for
    bad arguments."""
    tasks = _chunks(setup, 16 if scheduler else workers)
    results: dict[int, list[dict]] = {}
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=setup.runs * len(setup.grades), unit="run", desc="montecarlo",
                   leave=False)

    def on_result(i, value):
        results[i] = value

    def on_error(i, message):  # the task function itself failed (not one of its runs)
        _, g, idx, seeds = tasks[i]
        results[i] = [{"index": k, "grade": setup.grades[g].label, "seed": s,
                       "error": message} for k, s in zip(idx, seeds, strict=True)]

    def advance(i):
        if bar is not None:
            bar.update(len(tasks[i][2]))

    interrupted = False
    stopped = None
    cost = None
    load0 = _load_average()
    t0, c0 = time.perf_counter(), _own_cpu_s()
    try:
        cost = run_tasks(_run_chunk, tasks, on_result, workers=workers, scheduler=scheduler,
                         on_error=on_error, progress=advance,
                         connect_timeout_s=connect_timeout_s, help_while_starting=True,
                         preload=TASK_IMPORTS, no_worker_timeout_s=no_worker_timeout_s)
    except KeyboardInterrupt:
        interrupted = True
        stop_handled()  # the runs that finished are written (``--json`` marked partial)
    except WorkersLost as exc:
        stopped = str(exc)  # the runs that finished are kept
    finally:
        if bar is not None:
            bar.close()
    wall, own = time.perf_counter() - t0, _own_cpu_s() - c0
    runs = [r for i in sorted(results) for r in results[i]]
    order = {g.label: k for k, g in enumerate(setup.grades)}
    runs.sort(key=lambda r: (order[r["grade"]], r["index"]))
    return MonteCarloResult(setup, runs, interrupted, wall, workers, scheduler, cost, own,
                            (load0, _load_average()), stopped)


def _own_cpu_s() -> float:
    u = resource.getrusage(resource.RUSAGE_SELF)  # every thread of this process
    return u.ru_utime + u.ru_stime


def _load_average() -> float:
    try:
        return os.getloadavg()[0]
    except OSError:  # not available on this platform
        return math.nan


# --------------------------------------------------------------------------- plot
def write_plot(result: MonteCarloResult, stats: list[dict], png, *, force: bool = True) -> None:
    """PNG: one row per grade; error angle, |heading| and tilt over time as percentile bands
    (50/68/95/99) with the predicted 1σ and 3σ of the reported variance; written through a
    temporary file renamed into place."""
    # matplotlib here only: 0.5 s of imports a run without --plot does not pay
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from gyro_attitude.io.safe_output import SafeOutput, plot_format

    rows = [s for s in stats if "error_angle_rad" in s]
    if not rows:
        raise ValueError("no run finished: nothing to plot")
    fig, axes = plt.subplots(len(rows), 3, figsize=(13, 3.2 * len(rows)), squeeze=False,
                             constrained_layout=True)
    span = result.setup.duration_s
    unit, scale = ("h", 3600.0) if span >= 7200 else (("min", 60.0) if span >= 300 else ("s", 1.0))
    shades = {50: 0.55, 68: 0.4, 95: 0.25, 99: 0.12}
    for row, st in zip(axes, rows, strict=True):
        t = np.asarray(st["time_s"], dtype=float) / scale
        for ax, key, pred_key, title in (
                (row[0], "error_angle_rad", "angle", "attitude error angle"),
                (row[1], "heading_error_rad", "heading", "|heading error|"),
                (row[2], "tilt_error_rad", "tilt", "tilt error")):
            bands = st[key]
            for p in reversed(PERCENTILES):
                y = np.degrees(np.asarray(bands[f"p{p}"], dtype=float))
                ax.fill_between(t, 0.0, y, color="tab:blue", alpha=shades[p], lw=0,
                                label=f"p{p}")
            sigma = np.degrees(np.asarray(st["predicted_sigma_rad"][pred_key], dtype=float))
            if np.isfinite(sigma).any():
                ax.plot(t, sigma, "k--", lw=1, label="predicted 1σ")
                ax.plot(t, 3 * sigma, "k:", lw=1, label="predicted 3σ")
            ax.set_title(f"{st['label']}: {title} ({st['runs_finished']} runs)", fontsize=9)
            ax.set_xlabel(f"time [{unit}]")
            ax.set_ylabel("deg")
            ax.grid(True, alpha=0.3)
        row[0].legend(fontsize=7, loc="upper left")
    try:
        with SafeOutput(png, force=force) as tmp:
            fig.savefig(tmp, dpi=100, format=plot_format(png))
    finally:
        plt.close(fig)
