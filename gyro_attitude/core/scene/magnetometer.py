"""The scene's magnetometer: the Earth's field (World Magnetic Model, or given by declination,
inclination and intensity) seen in the body, with hard iron, soft iron, noise and disturbances.

Scene section (optional; the field in the file in µT, published in tesla)::

    magnetometer:
      model: wmm | given            # wmm (default): WMM-2025 at the scene's start position
      decimal_year: 2026.5          # wmm: the date, in WMM-2025's validity [2025, 2030)
      declination_deg: 4.9          # given: east of true north
      inclination_deg: 68.0         # given: dip, positive down (northern hemisphere)
      intensity_ut: 50.0            # given: |B|
      hard_iron_ut: [x, y, z]       # offset added in the sensor (body) frame
      soft_iron: [[..], [..], [..]] # 3x3 matrix applied to the external field (identity)
      noise_ut: 0.1                 # white noise 1σ per sample and axis
      disturbances:                 # extra field for a time (a magnet brought near)
        - {start_s: 20, duration_s: 10, field_ut: [30, -20, 10], frame: body | enu}

Measurement: ``m_b = S (C_bn (B_n + d_n)) + d_b + h + n``: a disturbance in ``enu`` is external
(a magnet fixed in the room: soft iron acts on it), one in ``body`` moves with the sensor (a
magnet carried along: like hard iron).  The field is evaluated once, at the start position
(a scene's path moves the field by far less than the sensor noise).

Why WMM through NOAA's ``wmm-calculator`` (pinned in requirements.txt, with its ``geomaglib``):
it is the model heading references use (WMM is the navigation standard of the DoD, NATO and the
IHO; IGRF is the scientific reference, and agrees with WMM to ~0.1 µT), it is the model NOAA NCEI
itself publishes and maintains (WMM-2025 coefficients, released 2026), pure Python with numpy
only.  The candidates looked at: ``ppigrf`` (IGRF-14, pure numpy, but needs pandas for its
dates), ``pygeomag`` (a WMM port, one maintainer, per-point scalar calls), ``wmm2020`` /
``igrf`` (compiled extensions of the previous models, not updated since 2021).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from gyro_attitude.core.scene.fields import Field, Fields, Kind, degrees, keys_of, read_fields

__all__ = ["MagnetometerSpec", "MAGNETOMETER_FIELDS", "parse_magnetometer", "geomagnetic_field",
           "measure_field", "WMM_YEARS"]

#: Validity of the WMM-2025 coefficients shipped with the pinned wmm-calculator.
WMM_YEARS = (2025.0, 2030.0)
UT = 1e-6

_DISTURBANCE_FIELDS = (
    Field("start_s", Kind.NUMBER, "s", lo=0.0),
    Field("duration_s", Kind.NUMBER, "s", lo=0.0, lo_open=True),
    Field("field_ut", Kind.VECTOR3, "µT", lo=-1e4, hi=1e4, scale=UT),
    Field("frame", Kind.STRING, default="enu", choices=("enu", "body")),
)
MAGNETOMETER_FIELDS = (
    Field("model", Kind.STRING, default="wmm", choices=("wmm", "given"),
          help="wmm: WMM-2025 at the start position; given: declination/inclination/intensity"),
    Field("decimal_year", Kind.NUMBER, "year", 2025.5, lo=WMM_YEARS[0], hi=WMM_YEARS[1],
          hi_open=True),
    degrees("declination_deg", None, -180.0, 180.0, help="east of true north"),
    degrees("inclination_deg", None, -90.0, 90.0, help="dip, positive down"),
    Field("intensity_ut", Kind.NUMBER, "µT", None, lo=0.0, lo_open=True, hi=1e4, scale=UT),
    Field("hard_iron_ut", Kind.VECTOR3, "µT", np.zeros(3), lo=-1e4, hi=1e4, scale=UT),
    Field("noise_ut", Kind.NUMBER, "µT", 0.0, lo=0.0, hi=1e4, scale=UT),
    Field("disturbances", Kind.LIST, default=(), fields=_DISTURBANCE_FIELDS),
)
_GIVEN = ("declination_deg", "inclination_deg", "intensity_ut")


@dataclass(frozen=True)
class MagnetometerSpec:
    """A scene's magnetometer in SI: ``field_enu`` (3,) tesla, the model's ``declination``,
    ``inclination`` (rad) and ``intensity`` (T), ``hard_iron`` (3,) T, ``soft_iron`` (3, 3),
    ``noise`` 1σ T, ``disturbances`` ((t0_s, t1_s, field (3,) T, frame), ...)."""

    model: str
    field_enu: np.ndarray
    declination: float
    inclination: float
    intensity: float
    hard_iron: np.ndarray
    soft_iron: np.ndarray
    noise: float
    disturbances: tuple = ()


def field_from_angles(declination: float, inclination: float, intensity: float) -> np.ndarray:
    """The ENU field (T) of declination (east of north), inclination (down), intensity."""
    h = intensity * math.cos(inclination)
    return np.array([h * math.sin(declination), h * math.cos(declination),
                     -intensity * math.sin(inclination)])


def geomagnetic_field(latitude_rad: float, longitude_rad: float, height_m: float,
                      decimal_year: float) -> np.ndarray:
    """WMM-2025's main field (ENU, tesla) at a geodetic position and date."""
    from wmm import wmm_calc  # lazy: the model loads its coefficient file

    model = wmm_calc()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # its blackout-zone note near the magnetic poles
        model.setup_env(math.degrees(latitude_rad), math.degrees(longitude_rad),
                        height_m / 1000.0, unit="km")
        model.setup_time(dyear=decimal_year)
        north, east, down = (float(np.asarray(x).reshape(-1)[0])
                             for x in (model.get_Bx(), model.get_By(), model.get_Bz()))
    b = np.array([east, north, -down]) * 1e-9  # nT, NED -> tesla, ENU
    if not np.all(np.isfinite(b)):
        raise ValueError("magnetometer.model: WMM gave no field at this position")
    return b


def parse_magnetometer(f: Fields | None, latitude_rad: float, longitude_rad: float,
                       height_m: float) -> MagnetometerSpec | None:
    """The ``magnetometer:`` section (``f`` from ``Fields.section``) or None when absent."""
    if f is None:
        return None
    v = read_fields(f, MAGNETOMETER_FIELDS)
    soft = np.eye(3)
    if f.has("soft_iron"):
        soft = f.array("soft_iron", (3, 3))
        if abs(np.linalg.det(soft)) < 1e-6 or np.abs(soft).max() > 100:
            raise ValueError(f"{f.key('soft_iron')}: must be an invertible matrix of gains "
                             "(|det| >= 1e-6, entries <= 100)")
    given = [k for k in _GIVEN if v[k] is not None]
    if v["model"] == "given":
        missing = [k for k in _GIVEN if v[k] is None]
        if missing:
            raise ValueError(f"{f.key(missing[0])}: required with model given")
        if f.has("decimal_year"):
            raise ValueError(f"{f.key('decimal_year')}: only with model wmm")
        dec, inc, inten = v["declination_deg"], v["inclination_deg"], v["intensity_ut"]
        b = field_from_angles(dec, inc, inten)
    else:
        if given:
            raise ValueError(f"{f.key(given[0])}: only with model given (model is wmm)")
        b = geomagnetic_field(latitude_rad, longitude_rad, height_m, v["decimal_year"])
        inten = float(np.linalg.norm(b))
        dec = math.atan2(b[0], b[1])
        inc = math.atan2(-b[2], math.hypot(b[0], b[1]))
    dist = tuple((d["start_s"], d["start_s"] + d["duration_s"], np.asarray(d["field_ut"]),
                  d["frame"]) for d in v["disturbances"])
    return MagnetometerSpec(v["model"], b, dec, inc, inten, np.asarray(v["hard_iron_ut"]),
                            soft, v["noise_ut"], dist)


MAGNETOMETER_KEYS = keys_of(MAGNETOMETER_FIELDS) + ("soft_iron",)


def measure_field(spec: MagnetometerSpec, t_s: np.ndarray, q_nb: np.ndarray,
                  rng: np.random.Generator) -> np.ndarray:
    """The magnetometer's output (N, 3) tesla at scene times ``t_s`` and attitudes ``q_nb``."""
    from gyro_attitude.core.rotation import quat_conjugate, quat_rotate

    n = t_s.shape[0]
    ext = np.broadcast_to(spec.field_enu, (n, 3)).copy()
    body_extra = np.zeros((n, 3))
    for t0, t1, vec, frame in spec.disturbances:
        on = (t_s >= t0) & (t_s < t1)
        if on.any():
            (ext if frame == "enu" else body_extra)[on] += vec
    m = quat_rotate(quat_conjugate(q_nb), ext) @ spec.soft_iron.T + body_extra + spec.hard_iron
    noise = rng.standard_normal((n, 3))  # drawn always: the stream does not depend on settings
    if spec.noise > 0:
        m += spec.noise * noise
    return m


def magnetometer_covariance(spec: MagnetometerSpec) -> np.ndarray:
    """Row-major 3x3 covariance (T²) of the published field: σ² on the diagonal, or all zeros
    ("unknown", REP-145) for a noise-free sensor."""
    return np.diag(np.full(3, spec.noise * spec.noise)).reshape(9)
