"""Scenario segments: validated parameters that build a `Motion` from the attitude they start at.

Each segment knows its duration before it is built (the temperature profile needs it) and may
ramp the temperature linearly to `temp_end_c` over its duration (None: hold the temperature).
A segment with `warmup_rise_c` != 0 powers the unit on at its start: self-heating by
warmup_rise_c (1 − exp(−t/warmup_tau_s)) over the segment, decaying after it.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from contract.errors import ScenarioError
from training.frames import euler_from_quat, quat_conjugate, quat_from_euler, quat_multiply, quat_to_rotvec
from training.simulator.trajectory import (Chain, EulerMotion, Figure8Path, GatedClock, HeadingAngles, Motion,
                                           RandomAngles, RandomPath, SineSum, Slew, Still)

#: Body axis names accepted by rotation segments.
AXIS_VECTORS = {"x": np.array([1.0, 0.0, 0.0]), "y": np.array([0.0, 1.0, 0.0]),
                "z": np.array([0.0, 0.0, 1.0])}


@dataclass(frozen=True, kw_only=True)
class Segment(ABC):
    """Common part: final temperature [°C] (None: unchanged), power-on warm-up rise [°C] and
    time constant [s] (rise 0: no power-on at this segment) and a label for messages."""

    temp_end_c: float | None = None
    warmup_rise_c: float = 0.0
    warmup_tau_s: float = 60.0
    label: str = "segment"

    @property
    @abstractmethod
    def duration_s(self) -> float:
        """Length of the segment [s]."""

    @abstractmethod
    def build(self, q_start: np.ndarray, rng: np.random.Generator) -> Motion:
        """The motion starting at attitude q_start (4,); `rng` drives any random choice."""


@dataclass(frozen=True, kw_only=True)
class Hold(Segment):
    """At rest for `hold_s` [s] (a temperature soak or ramp)."""

    hold_s: float

    @property
    def duration_s(self) -> float:
        return self.hold_s

    def build(self, q_start: np.ndarray, rng: np.random.Generator) -> Motion:
        return Still(q_start, self.hold_s)


def _slew_to(q_from: np.ndarray, q_to: np.ndarray, move_s: float) -> Slew:
    """Smooth fixed-axis rotation from q_from to q_to in move_s [s] (bell-shaped rate)."""
    rotvec = quat_to_rotvec(quat_multiply(quat_conjugate(q_from), q_to))
    return Slew(q_from, rotvec, GatedClock(((0.0, move_s),), 0.5 * move_s), move_s)


@dataclass(frozen=True, kw_only=True)
class Positions(Segment):
    """Static multi-position set: for each attitude (M, 3) [yaw, pitch, roll rad], a smooth
    rotation of `move_s` [s] from the previous attitude, then rest for `hold_s` [s]."""

    attitudes: np.ndarray
    hold_s: float
    move_s: float

    @property
    def duration_s(self) -> float:
        return len(self.attitudes) * (self.move_s + self.hold_s)

    def build(self, q_start: np.ndarray, rng: np.random.Generator) -> Motion:
        parts: list[Motion] = []
        current = q_start
        for target in quat_from_euler(self.attitudes):
            parts += [_slew_to(current, target, self.move_s), Still(target, self.hold_s)]
            current = target
        return Chain(parts)


@dataclass(frozen=True, kw_only=True)
class Rotations(Segment):
    """For each body axis, for each signed rate [rad/s]: turn by `angle` [rad] about that axis
    (rate reached after a smooth `ramp_s` [s] ramp), then rest `rest_s` [s]."""

    axes: tuple[str, ...]
    rates: np.ndarray
    angle: float
    ramp_s: float
    rest_s: float

    def _turn_s(self, rate: float) -> float:
        """Duration of one turn [s]: the ramps cost half their length each, so
        angle = |rate| · (D − ramp)."""
        return self.angle / abs(rate) + self.ramp_s

    @property
    def duration_s(self) -> float:
        return len(self.axes) * sum(self._turn_s(r) + self.rest_s for r in self.rates)

    def build(self, q_start: np.ndarray, rng: np.random.Generator) -> Motion:
        parts: list[Motion] = []
        current = q_start
        for axis in self.axes:
            for rate in self.rates:
                turn_s = self._turn_s(rate)
                rotvec = AXIS_VECTORS[axis] * np.sign(rate) * self.angle
                slew = Slew(current, rotvec, GatedClock(((0.0, turn_s),), self.ramp_s), turn_s)
                current = slew.end_attitude()
                parts += [slew, Still(current, self.rest_s)]
        return Chain(parts)


@dataclass(frozen=True, kw_only=True)
class Handheld(Segment):
    """Smooth random handheld motion: rest `rest_s` [s], move `move_s` [s], rest, ... ,
    ending at rest. During a move the Euler rates are band-limited random sums with RMS
    `rate_rms` [rad/s] (pitch squashed into ±max_pitch [rad]) and the translation acceleration
    has RMS `accel_rms` [m/s²] (vector norm); `band_hz` (low, high) [Hz]; gate ramps `ramp_s`."""

    total_s: float
    rest_s: float
    move_s: float
    ramp_s: float
    rate_rms: float
    accel_rms: float
    band_hz: tuple[float, float]
    max_pitch: float

    @property
    def duration_s(self) -> float:
        return self.total_s

    def windows(self) -> tuple[tuple[float, float], ...]:
        """Motion windows (start, length) [s]; the remainder extends the final rest."""
        count = int((self.total_s - self.rest_s) // (self.move_s + self.rest_s))
        return tuple((self.rest_s + k * (self.move_s + self.rest_s), self.move_s)
                     for k in range(count))

    def build(self, q_start: np.ndarray, rng: np.random.Generator) -> Motion:
        ypr = euler_from_quat(q_start)
        if abs(ypr[1]) >= self.max_pitch:
            raise ScenarioError(
                f"{self.label}: handheld motion starts at pitch {np.rad2deg(ypr[1]):.1f}°, "
                f"outside ±max_pitch_deg = {np.rad2deg(self.max_pitch):.1f}°; add a positions "
                f"segment that ends closer to level before it")
        angle_rms = np.array([self.rate_rms, self.rate_rms / self.max_pitch, self.rate_rms])
        angles = RandomAngles(ypr, self.max_pitch,
                              SineSum.random(rng, 3, self.band_hz, angle_rms, order=1))
        path = RandomPath(SineSum.random(rng, 3, self.band_hz,
                                         np.full(3, self.accel_rms / np.sqrt(3.0)), order=2))
        return EulerMotion(GatedClock(self.windows(), self.ramp_s), angles, path, self.total_s)


@dataclass(frozen=True, kw_only=True)
class Figure8(Segment):
    """Slow figure-of-eight: `laps` laps of a lemniscate `length_m` x `width_m` [m] taking
    `period_s` [s] each, body yawing along the path (pitch and roll held), smooth start and
    stop over `ramp_s` [s]. The path is rotated so that it starts along the current heading."""

    length_m: float
    width_m: float
    period_s: float
    laps: int
    ramp_s: float

    @property
    def duration_s(self) -> float:
        return self.laps * self.period_s + self.ramp_s

    def build(self, q_start: np.ndarray, rng: np.random.Generator) -> Motion:
        yaw, pitch, roll = euler_from_quat(q_start)
        rotation = yaw - Figure8Path.initial_heading(self.length_m, self.width_m)
        path = Figure8Path(self.length_m, self.width_m, self.period_s, rotation)
        clock = GatedClock(((0.0, self.duration_s),), self.ramp_s)
        return EulerMotion(clock, HeadingAngles(path, pitch, roll), path, self.duration_s)
