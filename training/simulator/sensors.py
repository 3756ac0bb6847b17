"""Sensor error model: what a MEMS gyroscope, accelerometer and magnetometer make of the truth.

Per triad (units of the triad: rad/s, m/s² or µT; ΔT = T − 25 °C):

    x = S(T) · C · x_true + b(T) + k_rate · dT/dt + w(t) + n,   then saturation and quantisation

    S(T) = diag(1 + s + s1 ΔT + s2 ΔT²)       scale factor and its temperature drift
    C    = I + M, M symmetric, zero diagonal   axis misalignment [rad]. The body frame is *defined*
                                               as the orthogonal frame closest to the sensor axes;
                                               the antisymmetric part of a small misalignment is a
                                               rotation of that frame, so only the symmetric part
                                               is an error.
    b(T) = b0 + b1 ΔT + b2 ΔT²                 bias and its temperature drift
    k_rate · dT/dt                             bias from the temperature rate
    K_g · f                                    gyroscope only: g-sensitivity, bias ∝ specific force
                                               f [m/s²], K_g (3, 3) [(rad/s)/(m/s²)]
    d · t                                      bias drifting linearly with the time since power-on
    w(t)                                       bias random walk, w(0) = 0, increments σ_w √Δt N(0,1)
    f(t)                                       flicker-like bias of bias instability B: the sum of
                                               FLICKER_TERMS first-order Gauss–Markov processes,
                                               τ_k = 10^(k/2) s, σ_k = FLICKER_SIGMA_FACTOR · B, each
                                               from 0 (`flicker_bias`; the C virtual sensor uses the
                                               same construction)
    n                                          white noise, σ = density · √rate_hz

The magnetometer first distorts the body field (hard/soft iron and a cubic nonlinearity):

    v = W · m_b,   m' = v + h + d(v),   d_i(v) = Σ_j c_ij (v_j / m_ref)³   [µT]

so a field of m_ref along axis j adds c_ij to axis i; then the generic triad errors apply to m'.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: Temperature [°C] at which the temperature polynomials are expanded (ΔT = T − 25 °C).
REFERENCE_TEMP_C = 25.0
#: Flicker-like bias (bias instability B): Gauss–Markov terms k = 0..FLICKER_TERMS-1 with correlation
#: times τ_k = 10^(k/2) s (1 s .. 10^4 s, two per decade) ...
FLICKER_TERMS = 9
#: ... each with stationary σ_k = FLICKER_SIGMA_FACTOR · B: the Allan deviation of the sum is then flat at
#: √(2 ln2/π) · B = 0.664 B within ±4 % from 10 s to 1000 s (tests/test_noise_flicker.py measures it).
FLICKER_SIGMA_FACTOR = 0.6125
#: spawn_key entry of the flicker streams: derived from the measurement's SeedSequence without spawning
#: from it, so the other noise streams (and the SeedSequence's spawn counter) stay as they were.
FLICKER_STREAM_KEY = 0xF1C4


def flicker_bias(n: int, rate_hz: float, bias_instability: float, rng: np.random.Generator,
                 axes: int = 3) -> np.ndarray:
    """Flicker-like bias (n, axes) [u] of bias instability `bias_instability` B [u] at `rate_hz` [Hz]:
    Σ_k x_k, x_k(0) = 0, x_k ← a_k x_k + σ_k √(1 − a_k²) w, a_k = exp(−Δt/τ_k), w ~ N(0, 1) drawn as
    (n − 1, axes, FLICKER_TERMS) from `rng`. IEEE 952 flicker floor: σ_Allan = √(2 ln2/π) B."""
    from scipy.signal import lfilter
    out = np.zeros((n, axes))
    if n < 2:
        return out
    w = rng.standard_normal((n - 1, axes, FLICKER_TERMS))
    dt = 1.0 / rate_hz
    for k in range(FLICKER_TERMS):
        a = float(np.exp(-dt / 10.0 ** (k / 2.0)))
        gain = FLICKER_SIGMA_FACTOR * bias_instability * np.sqrt(1.0 - a * a)
        out[1:] += lfilter([gain], [1.0, -a], w[:, :, k], axis=0)
    return out


@dataclass(frozen=True)
class TriadErrors:
    """Error parameters of one triad, in the triad's SI unit u (rad/s, m/s², µT).

    Vectors are (3,) per axis: bias [u], bias_t1 [u/°C], bias_t2 [u/°C²], scale [1],
    scale_t1 [1/°C], scale_t2 [1/°C²], temp_rate [u/(°C/s)]. misalignment (3, 3) [rad]
    symmetric with zero diagonal. Scalars: noise_density [u/√Hz], bias_walk [u/√s], lsb [u],
    bias_instability [u] (flicker-like bias, `flicker_bias`; 0: none and no random numbers drawn),
    full_scale [u] (saturation at ±full_scale). g_sensitivity (3, 3) [u/(m/s²)]: bias per specific
    force (row = axis). drift (3,) [u/s]: bias drift per second since the first sample.
    """

    bias: np.ndarray
    bias_t1: np.ndarray
    bias_t2: np.ndarray
    scale: np.ndarray
    scale_t1: np.ndarray
    scale_t2: np.ndarray
    misalignment: np.ndarray
    temp_rate: np.ndarray
    noise_density: float
    bias_walk: float
    lsb: float
    full_scale: float
    g_sensitivity: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    drift: np.ndarray = field(default_factory=lambda: np.zeros(3))
    bias_instability: float = 0.0

    def response(self, temp_c: float) -> np.ndarray:
        """The raw reading per true value (3, 3) at temperature temp_c [°C]: diag(S(T)) (I + M), so that
        raw = response · truth + bias (noise aside); a calibration A is exact when A · response is a
        rotation."""
        dt_c = temp_c - REFERENCE_TEMP_C
        gain = 1.0 + self.scale + self.scale_t1 * dt_c + self.scale_t2 * dt_c ** 2
        return gain[:, None] * (np.eye(3) + self.misalignment)

    def apply(self, truth: np.ndarray, temp: np.ndarray, temp_rate: np.ndarray, rate_hz: float,
              rng: np.random.Generator, specific_force: np.ndarray | None = None,
              flicker_rng: np.random.Generator | None = None) -> np.ndarray:
        """Measured triad (N, 3) from the true one (N, 3), temperature (N,) [°C] and its rate
        (N,) [°C/s] at `rate_hz` [Hz]; `specific_force` (N, 3) [m/s²] drives g_sensitivity
        (None: no g-sensitivity bias). `flicker_rng`: the separate stream of the flicker bias, required
        when bias_instability > 0 (untouched otherwise)."""
        dt_c = (temp - REFERENCE_TEMP_C)[:, None]
        gain = 1.0 + self.scale + self.scale_t1 * dt_c + self.scale_t2 * dt_c ** 2
        bias = self.bias + self.bias_t1 * dt_c + self.bias_t2 * dt_c ** 2
        coupled = truth @ (np.eye(3) + self.misalignment).T
        x = gain * coupled + bias + self.temp_rate * temp_rate[:, None]
        x = x + self.drift * (np.arange(truth.shape[0]) / rate_hz)[:, None]
        if specific_force is not None:
            x = x + specific_force @ self.g_sensitivity.T
        x = x + self._random_walk(truth.shape[0], rate_hz, rng) + self._white(truth.shape, rate_hz, rng)
        if self.bias_instability > 0.0:
            if flicker_rng is None:
                raise ValueError("TriadErrors.apply: bias_instability > 0 needs flicker_rng (its own stream)")
            x = x + flicker_bias(truth.shape[0], rate_hz, self.bias_instability, flicker_rng)
        return self.digitise(x)

    def _random_walk(self, n: int, rate_hz: float, rng: np.random.Generator) -> np.ndarray:
        """Bias random walk (n, 3), starting at 0, increments σ_w √Δt N(0, 1)."""
        steps = rng.standard_normal((n, 3)) * (self.bias_walk / np.sqrt(rate_hz))
        steps[0] = 0.0
        return np.cumsum(steps, axis=0)

    def _white(self, shape: tuple[int, ...], rate_hz: float, rng: np.random.Generator) -> np.ndarray:
        """White noise with per-sample σ = density · √rate_hz."""
        return rng.standard_normal(shape) * (self.noise_density * np.sqrt(rate_hz))

    def digitise(self, x: np.ndarray) -> np.ndarray:
        """Saturate at ±full_scale, then round to a multiple of the LSB."""
        return self.lsb * np.round(np.clip(x, -self.full_scale, self.full_scale) / self.lsb)


@dataclass(frozen=True)
class MagDistortion:
    """Magnetic distortion around the sensor: hard iron h (3,) [µT], soft iron W (3, 3)
    symmetric [1], cubic coefficients c (3, 3) [µT] at reference field cubic_ref_ut [µT]."""

    hard_iron: np.ndarray
    soft_iron: np.ndarray
    cubic: np.ndarray
    cubic_ref_ut: float

    def apply(self, field: np.ndarray) -> np.ndarray:
        """Distorted field (N, 3) [µT]: v = W m, m' = v + h + c · (v / m_ref)³ (element-wise cube)."""
        v = field @ self.soft_iron.T
        return v + self.hard_iron + (v / self.cubic_ref_ut) ** 3 @ self.cubic.T


@dataclass(frozen=True)
class SensorModel:
    """One physical sensor unit: its name and the errors of its three triads."""

    name: str
    gyr: TriadErrors
    acc: TriadErrors
    mag: TriadErrors
    mag_distortion: MagDistortion

    def measure(self, ref_gyr: np.ndarray, ref_acc: np.ndarray, ref_mag: np.ndarray,
                temp: np.ndarray, temp_rate: np.ndarray, rate_hz: float,
                seed: np.random.SeedSequence) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Raw gyr [rad/s], acc [m/s²], mag [µT] (N, 3 each) from the truth; each triad draws
        from its own stream spawned from `seed`, its flicker bias (when bias_instability > 0) from
        another (`flicker_stream`)."""
        rng_gyr, rng_acc, rng_mag = (np.random.default_rng(s) for s in seed.spawn(3))
        gyr = self.gyr.apply(ref_gyr, temp, temp_rate, rate_hz, rng_gyr, specific_force=ref_acc,
                             flicker_rng=flicker_stream(seed, 0) if self.gyr.bias_instability > 0 else None)
        acc = self.acc.apply(ref_acc, temp, temp_rate, rate_hz, rng_acc,
                             flicker_rng=flicker_stream(seed, 1) if self.acc.bias_instability > 0 else None)
        mag = self.mag.apply(self.mag_distortion.apply(ref_mag), temp, temp_rate, rate_hz, rng_mag,
                             flicker_rng=flicker_stream(seed, 2) if self.mag.bias_instability > 0 else None)
        return gyr, acc, mag


def flicker_stream(seed: np.random.SeedSequence, triad_index: int) -> np.random.Generator:
    """The flicker bias stream of triad `triad_index` (0 gyr, 1 acc, 2 mag) of a measurement seeded by `seed`:
    a child key of `seed` that `seed.spawn` never hands out, made without spawning (the white noise and
    random walk streams stay bit-identical whether or not a triad has a bias instability)."""
    child = np.random.SeedSequence(seed.entropy, spawn_key=(*seed.spawn_key, FLICKER_STREAM_KEY, triad_index),
                                   pool_size=seed.pool_size)
    return np.random.default_rng(child)
