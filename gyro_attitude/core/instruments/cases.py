"""The instrument cases the book's applications call for (to become scenes): each a named
instrument, carrier, latitude and time grid, ready to simulate."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from gyro_attitude.core.earth import OMEGA_IE
from gyro_attitude.core.instruments.directional_gyro import DirectionalGyro, DirectionalGyroParams
from gyro_attitude.core.instruments.gyrocompass import (
    Gyrocompass,
    GyrocompassParams,
    gyrocompass_equilibrium,
)
from gyro_attitude.core.instruments.vertical_gyro import VerticalGyro, VerticalGyroParams
from gyro_attitude.core.motion import (
    ConstantVelocity,
    CoordinatedTurn,
    Motion,
    ProfileSegment,
    SegmentProfile,
    Stationary,
)

__all__ = ["InstrumentCase", "CASES", "instrument_case"]


@dataclass(frozen=True)
class InstrumentCase:
    """``instrument`` (an object with ``simulate(t_grid, carrier, latitude, **kwargs)``),
    ``carrier``, ``latitude`` (rad), ``t_grid`` (s) and the extra ``options`` of ``simulate``."""

    name: str
    description: str
    instrument: object
    carrier: Motion
    latitude: float
    t_grid: np.ndarray
    options: dict = field(default_factory=dict)

    def simulate(self, **overrides):
        return self.instrument.simulate(self.t_grid, self.carrier, self.latitude,
                                        **{**self.options, **overrides})


def _gyrocompass_settling() -> InstrumentCase:
    lat = math.radians(45.0)
    return InstrumentCase(
        "gyrocompass_settling",
        "Gyrocompass at rest at 45°N, undamped, Schuler-tuned (84.4 min), axis started 2° east",
        Gyrocompass(GyrocompassParams.schuler_tuned(10.0, lat)), Stationary((0.0, 0.0, math.pi / 2)),
        lat, np.arange(0.0, 4 * 3600.0 + 1.0, 10.0),
        {"azimuth0": math.radians(2.0), "max_step": 60.0})


def _gyrocompass_ship() -> InstrumentCase:
    lat = math.radians(45.0)
    return InstrumentCase(
        "gyrocompass_ship",
        "Damped (ζ = 0.5) Schuler-tuned gyrocompass on a ship at 10 m/s due north from 45°N: "
        "settles on the speed error (+1.8°) within 6 h",
        Gyrocompass(GyrocompassParams.schuler_tuned(10.0, lat, damping_ratio=0.5)),
        ConstantVelocity(10.0, (0.0, 0.0, math.pi / 2)), lat, np.arange(0.0, 6 * 3600.0 + 1.0, 30.0),
        {"max_step": 60.0})


def course_change_carrier(speed: float = 10.0, turn_s: float = 60.0, before_s: float = 300.0,
                          after_s: float = 3 * 3600.0) -> SegmentProfile:
    """North at ``speed``, then a 90° turn to east in ``turn_s`` (constant ENU acceleration)."""
    return SegmentProfile(
        [ProfileSegment(before_s),
         ProfileSegment(turn_s, (0.0, 0.0, -(math.pi / 2) / turn_s), (speed / turn_s, -speed / turn_s, 0.0)),
         ProfileSegment(after_s)],
        attitude_rad=(0.0, 0.0, math.pi / 2), velocity_enu=(0.0, speed, 0.0))


def _gyrocompass_course_change(schuler_tuned: bool = True) -> InstrumentCase:
    lat = math.radians(45.0)
    params = (GyrocompassParams.schuler_tuned(10.0, lat) if schuler_tuned
              else GyrocompassParams.with_period(10.0, 3600.0, lat))
    # started at its settle point on the northerly course (Coriolis on the pendulum included)
    a0, b0 = gyrocompass_equilibrium(params, lat, (0.0, 10.0, 0.0),
                                     (-2.0 * OMEGA_IE * math.sin(lat) * 10.0, 0.0))
    name = "gyrocompass_course_change" + ("" if schuler_tuned else "_untuned")
    return InstrumentCase(
        name,
        "Undamped gyrocompass settled on a northerly course at 10 m/s, 45°N, turning east in 60 s: "
        + ("Schuler-tuned, no ballistic deflection" if schuler_tuned
           else "60-min period, ballistic deflection ≈ 1.7°"),
        Gyrocompass(params), course_change_carrier(), lat, np.arange(0.0, 300.0 + 60.0 + 3 * 3600.0, 5.0),
        {"azimuth0": a0, "elevation0": b0, "max_step": 10.0})


def _vertical_gyro_turn() -> InstrumentCase:
    return InstrumentCase(
        "vertical_gyro_turn",
        "Vertical gyro, proportional erection k = 0.02/s, aircraft at 120 m/s in a 3°/s left turn "
        "at 50°N: steady turn error",
        VerticalGyro(VerticalGyroParams(erection_gain=0.02)), CoordinatedTurn(120.0, math.radians(3.0)),
        math.radians(50.0), np.arange(0.0, 600.0, 0.5), {"max_step": 5.0})


def _directional_gyro_bank() -> InstrumentCase:
    return InstrumentCase(
        "directional_gyro_bank",
        "Directional gyro with latitude nut at 50°N in a 3°/s coordinated turn at 120 m/s "
        "(bank 32.6°): cardan error over a full turn",
        DirectionalGyro(DirectionalGyroParams(latitude_nut=math.radians(50.0))),
        CoordinatedTurn(120.0, math.radians(3.0)), math.radians(50.0), np.arange(0.0, 120.0, 0.25),
        {"max_step": 0.5})


CASES = {
    "gyrocompass_settling": _gyrocompass_settling,
    "gyrocompass_ship": _gyrocompass_ship,
    "gyrocompass_course_change": _gyrocompass_course_change,
    "gyrocompass_course_change_untuned": lambda: _gyrocompass_course_change(False),
    "vertical_gyro_turn": _vertical_gyro_turn,
    "directional_gyro_bank": _directional_gyro_bank,
}


def instrument_case(name: str) -> InstrumentCase:
    """The case called ``name`` (one of :data:`CASES`)."""
    if name not in CASES:
        raise ValueError(f"unknown instrument case {name!r}; known: {', '.join(CASES)}")
    return CASES[name]()
