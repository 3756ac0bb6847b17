"""Motion primitives: analytic attitude, body rate and acceleration as functions of time.

Every motion is defined in closed form, so the truth is self-consistent to rounding error:
the body rate is the exact derivative of the attitude (q' = ½ q ⊗ [0, ω_b]) and the
acceleration the exact second derivative of the position. No numerical integration is
involved, which is more accurate than integrating the rate in sub-steps and costs nothing
at any sample rate.

Smooth starts and stops use a *gated clock*: a motion is written as a function of a warped
time τ(t) = ∫ g(t) dt, where the gate g rises from 0 to 1 and back with quintic smooth steps.
Then d/dt f(τ) = f'(τ)·g and d²/dt² f(τ) = f''(τ)·g² + f'(τ)·g', all closed form; where g = 0
the body is at rest.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from training.frames import body_rate_from_euler, quat_from_euler, quat_from_rotvec, quat_multiply


# ----------------------------------------------------------------------------- smooth steps

def _step(x: np.ndarray) -> np.ndarray:
    """Quintic smooth step S(x) = 10x³ − 15x⁴ + 6x⁵ on [0, 1], 0 below, 1 above
    (zero first and second derivative at both ends)."""
    x = np.clip(x, 0.0, 1.0)
    return x ** 3 * (10.0 - 15.0 * x + 6.0 * x * x)


def _step_slope(x: np.ndarray) -> np.ndarray:
    """dS/dx = 30 x² (1 − x)² on [0, 1], 0 outside."""
    x = np.clip(x, 0.0, 1.0)
    return 30.0 * x * x * (1.0 - x) ** 2


def _step_integral(x: np.ndarray) -> np.ndarray:
    """∫₀ˣ S = 2.5x⁴ − 3x⁵ + x⁶ on [0, 1], 0 below, x − ½ above (∫₀¹ S = ½)."""
    inside = np.clip(x, 0.0, 1.0)
    return inside ** 4 * (2.5 - 3.0 * inside + inside * inside) + np.maximum(x - 1.0, 0.0)


@dataclass(frozen=True)
class GatedClock:
    """Warped time τ(t) = ∫₀ᵗ g, where the gate g is 1 inside each window (start, length) [s]
    and ramps smoothly from 0 over the first `ramp_s` and back to 0 over the last `ramp_s`:
    g(t) = Σ_w S((t − a)/r) − S((t − a − L + r)/r). Each window adds L − r to τ."""

    windows: tuple[tuple[float, float], ...]
    ramp_s: float

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """τ [s], g = dτ/dt [1] and g' [1/s] at times t (N,) [s]."""
        r = self.ramp_s
        tau, gate, slope = (np.zeros_like(t, dtype=float) for _ in range(3))
        for start, length in self.windows:
            up, down = (t - start) / r, (t - start - length + r) / r
            tau += r * (_step_integral(up) - _step_integral(down))
            gate += _step(up) - _step(down)
            slope += (_step_slope(up) - _step_slope(down)) / r
        return tau, gate, slope

    @property
    def total(self) -> float:
        """τ at the end of the last window [s]."""
        return sum(length - self.ramp_s for _, length in self.windows)


# ----------------------------------------------------------------------------- random signals

@dataclass(frozen=True)
class SineSum:
    """Band-limited random signal per column: x_c(τ) = Σ_k a_ck [sin(2π f_ck τ + φ_ck) − sin φ_ck],
    so x(0) = 0. Arrays (C, K): amplitudes [unit], frequencies [Hz], phases [rad]."""

    amplitude: np.ndarray
    frequency_hz: np.ndarray
    phase: np.ndarray

    @classmethod
    def random(cls, rng: np.random.Generator, columns: int, band_hz: tuple[float, float],
               rms: np.ndarray, order: int, components: int = 12) -> "SineSum":
        """Random sum whose `order`-th derivative has a flat spectrum in `band_hz` and RMS
        `rms` (C,) per column (band-limited white noise in that derivative).

        Frequencies uniform in the band, phases uniform, derivative amplitudes Rayleigh scaled
        so that RMS(x⁽ⁿ⁾)² = Σ_k d_k² / 2 = rms²; signal amplitudes a_k = d_k / (2π f_k)ⁿ.
        """
        freq = rng.uniform(band_hz[0], band_hz[1], size=(columns, components))
        phase = rng.uniform(0.0, 2.0 * np.pi, size=(columns, components))
        raw = rng.rayleigh(1.0, size=(columns, components))
        scale = np.asarray(rms, dtype=float) / np.sqrt(0.5 * np.sum(raw ** 2, axis=1))
        return cls(raw * scale[:, None] / (2.0 * np.pi * freq) ** order, freq, phase)

    def derivative(self, tau: np.ndarray, order: int) -> np.ndarray:
        """The `order`-th derivative (0, 1 or 2) at τ (N,) -> (N, C)."""
        omega = 2.0 * np.pi * self.frequency_hz
        arg = tau[:, None, None] * omega[None] + self.phase[None]
        if order == 0:
            terms = np.sin(arg) - np.sin(self.phase)[None]
        elif order == 1:
            terms = omega * np.cos(arg)
        else:
            terms = -omega ** 2 * np.sin(arg)
        return np.sum(self.amplitude[None] * terms, axis=2)


# ----------------------------------------------------------------------------- motions

@dataclass
class MotionSamples:
    """Truth at N instants: attitude q (N, 4) body -> NED, body rate (N, 3) [rad/s],
    kinematic acceleration in NED (N, 3) [m/s²] (gravity not included)."""

    q: np.ndarray
    rate: np.ndarray
    acc_nav: np.ndarray


class Motion(ABC):
    """A piece of trajectory on local time [0, duration_s]."""

    duration_s: float

    @abstractmethod
    def sample(self, t: np.ndarray) -> MotionSamples:
        """Truth at local times t (N,) [s], 0 ≤ t ≤ duration_s."""

    def end_attitude(self) -> np.ndarray:
        """Attitude (4,) at the end of the motion (the start of the next one)."""
        return self.sample(np.array([self.duration_s])).q[0]


class Still(Motion):
    """At rest at attitude q (4,) for `duration_s` [s]."""

    def __init__(self, q: np.ndarray, duration_s: float):
        self.q, self.duration_s = np.asarray(q, dtype=float), float(duration_s)

    def sample(self, t: np.ndarray) -> MotionSamples:
        n = t.shape[0]
        return MotionSamples(np.tile(self.q, (n, 1)), np.zeros((n, 3)), np.zeros((n, 3)))


class Slew(Motion):
    """Rotation about a fixed body axis: q(t) = q0 ⊗ exp(r · s(t)), s = τ/τ_end from 0 to 1,
    hence ω_b = r · s'(t) = r · g(t)/τ_end exactly (r and its exponential commute)."""

    def __init__(self, q0: np.ndarray, rotvec: np.ndarray, clock: GatedClock, duration_s: float):
        self.q0, self.rotvec = np.asarray(q0, dtype=float), np.asarray(rotvec, dtype=float)
        self.clock, self.duration_s = clock, float(duration_s)

    def sample(self, t: np.ndarray) -> MotionSamples:
        tau, gate, _ = self.clock.evaluate(t)
        progress, speed = tau / self.clock.total, gate / self.clock.total
        q = quat_multiply(self.q0, quat_from_rotvec(progress[:, None] * self.rotvec))
        return MotionSamples(q, speed[:, None] * self.rotvec, np.zeros((t.shape[0], 3)))


class AngleTrack(ABC):
    """Euler angles as a function of warped time τ."""

    @abstractmethod
    def evaluate(self, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """ZYX angles (N, 3) [rad] and their τ-derivatives (N, 3) [rad/s]."""


class PathTrack(ABC):
    """Position in NED as a function of warped time τ."""

    @abstractmethod
    def evaluate(self, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """First and second τ-derivatives of the position (N, 3) [m/s, m/s²]."""


class EulerMotion(Motion):
    """Attitude from Euler angles ψ(τ), θ(τ), φ(τ) and position p(τ) on a gated clock.

    ω_b follows from the Euler rates (`body_rate_from_euler`) with d/dt = g · d/dτ;
    a_n = p''(τ) g² + p'(τ) g'.
    """

    def __init__(self, clock: GatedClock, angles: AngleTrack, path: PathTrack, duration_s: float):
        self.clock, self.angles, self.path = clock, angles, path
        self.duration_s = float(duration_s)

    def sample(self, t: np.ndarray) -> MotionSamples:
        tau, gate, slope = self.clock.evaluate(t)
        ypr, ypr_tau = self.angles.evaluate(tau)
        vel_tau, acc_tau = self.path.evaluate(tau)
        rate = body_rate_from_euler(ypr, ypr_tau * gate[:, None])
        acc = acc_tau * (gate ** 2)[:, None] + vel_tau * slope[:, None]
        return MotionSamples(quat_from_euler(ypr), rate, acc)


class Chain(Motion):
    """Motions played one after another; local time runs over the sum of their durations."""

    def __init__(self, parts: list[Motion]):
        self.parts = parts
        durations = np.array([p.duration_s for p in parts])
        self.starts = np.concatenate([[0.0], np.cumsum(durations)[:-1]])
        self.duration_s = float(np.sum(durations))

    def sample(self, t: np.ndarray) -> MotionSamples:
        which = np.clip(np.searchsorted(self.starts, t, side="right") - 1, 0, len(self.parts) - 1)
        out = MotionSamples(np.empty((t.shape[0], 4)), np.empty((t.shape[0], 3)),
                            np.empty((t.shape[0], 3)))
        for index in np.unique(which):
            rows = which == index
            part = self.parts[index].sample(t[rows] - self.starts[index])
            out.q[rows], out.rate[rows], out.acc_nav[rows] = part.q, part.rate, part.acc_nav
        return out

    def end_attitude(self) -> np.ndarray:
        return self.parts[-1].end_attitude()


# ----------------------------------------------------------------------------- tracks

class RandomAngles(AngleTrack):
    """Handheld attitude: ψ = ψ0 + Y(τ), θ = θ_max tanh(atanh(θ0/θ_max) + P(τ)), φ = φ0 + R(τ)
    with band-limited random sums Y, P, R; the tanh keeps |θ| < θ_max (Euler angles stay well
    defined) while θ ≈ θ0 + θ_max·P near level."""

    def __init__(self, start_ypr: np.ndarray, max_pitch: float, sines: SineSum):
        self.start, self.max_pitch, self.sines = np.asarray(start_ypr, float), max_pitch, sines
        self.pitch_offset = np.arctanh(self.start[1] / max_pitch)

    def evaluate(self, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        value, slope = self.sines.derivative(tau, 0), self.sines.derivative(tau, 1)
        squashed = np.tanh(self.pitch_offset + value[:, 1])
        ypr = self.start + value
        ypr[:, 1] = self.max_pitch * squashed
        ypr_tau = slope.copy()
        ypr_tau[:, 1] = self.max_pitch * (1.0 - squashed ** 2) * slope[:, 1]  # d tanh = sech²
        return ypr, ypr_tau


class RandomPath(PathTrack):
    """Band-limited random translation p(τ) = Σ sines per NED axis (bounded displacement)."""

    def __init__(self, sines: SineSum):
        self.sines = sines

    def evaluate(self, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.sines.derivative(tau, 1), self.sines.derivative(tau, 2)


class Figure8Path(PathTrack):
    """Lemniscate of Gerono in the horizontal plane, rotated by `heading0` about down:
    p(τ) = Rz(β) · [L/2 · sin Ωτ, W/2 · sin 2Ωτ, 0], Ω = 2π/period. Its velocity never vanishes
    (cos Ωτ and cos 2Ωτ are never zero together), so the heading is always defined."""

    def __init__(self, length_m: float, width_m: float, period_s: float, rotation: float):
        self.half_length, self.half_width = 0.5 * length_m, 0.5 * width_m
        self.omega, self.rotation = 2.0 * np.pi / period_s, rotation

    @staticmethod
    def initial_heading(length_m: float, width_m: float) -> float:
        """Heading of the unrotated path at τ = 0 [rad]: atan2(W Ω, L/2 Ω) = atan2(2W, L)."""
        return float(np.arctan2(2.0 * width_m, length_m))

    def evaluate(self, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        w, a, b = self.omega, self.half_length, self.half_width
        vel = np.stack([a * w * np.cos(w * tau), 2 * b * w * np.cos(2 * w * tau),
                        np.zeros_like(tau)], axis=-1)
        acc = np.stack([-a * w * w * np.sin(w * tau), -4 * b * w * w * np.sin(2 * w * tau),
                        np.zeros_like(tau)], axis=-1)
        return self._rotate(vel), self._rotate(acc)

    def _rotate(self, v: np.ndarray) -> np.ndarray:
        """Rotate horizontal vectors (N, 3) by the path rotation about the down axis."""
        c, s = np.cos(self.rotation), np.sin(self.rotation)
        return np.stack([c * v[:, 0] - s * v[:, 1], s * v[:, 0] + c * v[:, 1], v[:, 2]], axis=-1)


class HeadingAngles(AngleTrack):
    """Yaw along the velocity of a path, ψ = atan2(v_E, v_N), pitch and roll held:
    ψ' = (v_N a_E − v_E a_N) / (v_N² + v_E²)."""

    def __init__(self, path: PathTrack, pitch: float, roll: float):
        self.path, self.pitch, self.roll = path, pitch, roll

    def evaluate(self, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        vel, acc = self.path.evaluate(tau)
        yaw = np.arctan2(vel[:, 1], vel[:, 0])
        yaw_rate = (vel[:, 0] * acc[:, 1] - vel[:, 1] * acc[:, 0]) / (vel[:, 0] ** 2 + vel[:, 1] ** 2)
        ypr = np.stack([yaw, np.full_like(yaw, self.pitch), np.full_like(yaw, self.roll)], axis=-1)
        return ypr, np.stack([yaw_rate, np.zeros_like(yaw), np.zeros_like(yaw)], axis=-1)
