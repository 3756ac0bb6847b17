"""The trained FMU's inputs shared by the FMU tests: its coefficients and settings, a synthetic
recording to run it on, and the bound between FMU and batch runtime."""
from __future__ import annotations

import numpy as np

from contract.layout import AUX_INPUTS, MAX_DEGREE, TRIAD_BLOCK, identity_coefficients

#: FMU (compiled with fmpy's CMake) and batch library run the same C code with other flags; only the
#: compiler's instruction choice may differ, far below this bound.
GOLDEN_TOLERANCE = 1e-12

#: Settings of the "trained" FMU: every parameter differs from its default. The lags make the
#: time-alignment buffer (sources/ImuAlign.h) part of every FMU-state and golden check.
TRAINED_SETTINGS = {"declination": 0.05, "field_norm": 48.0, "gyro_noise": 5e-4,
                    "gyro_bias_residual": 2e-4, "mse_time_constant": 0.5, "angle_noise": 0.02,
                    "enable_thermal": 1.0, "lag_gyr": -0.015, "lag_mag": 0.02}


def trained_coefficients() -> np.ndarray:
    """A non-identity coefficient array: symmetric A near I, degree-2 gain and bias polynomials."""
    rng = np.random.default_rng(7)
    c = np.array(identity_coefficients())
    for triad in range(3):
        o = 1 + triad * TRIAD_BLOCK
        c[o + 1:o + 4] = [25.0, 10.0, 2.0]                      # t0 [°C], ts [°C], degree
        a = np.eye(3) + 0.01 * rng.standard_normal((3, 3))
        c[o + 4:o + 13] = ((a + a.T) / 2).ravel()
        g = c[o + 13:o + 13 + 3 * MAX_DEGREE].reshape(3, MAX_DEGREE)
        g[:, :2] = 1e-3 * rng.standard_normal((3, 2))
        b = c[o + 13 + 3 * MAX_DEGREE:o + TRIAD_BLOCK - 3].reshape(3, MAX_DEGREE + 1)
        b[:, :3] = 1e-2 * rng.standard_normal((3, 3))
    return c


def synthetic_recording(n: int = 600) -> tuple[np.ndarray, np.ndarray]:
    """(t, inputs): a rotating, noisy sensor with jittered 50–200 Hz steps, a 120 s gap, a
    stretch of unknown (NaN) temperature and slow sines on the auxiliary inputs."""
    rng = np.random.default_rng(1)
    dt = rng.uniform(0.005, 0.02, n)
    dt[n // 2] = 120.0
    t = np.concatenate([[0.0], np.cumsum(dt[:-1])])
    s = np.arange(n) / 100.0
    gyr = np.stack([0.3 * np.sin(1.1 * s), 0.2 * np.cos(0.7 * s), 0.5 * np.sin(0.3 * s)], axis=1)
    roll, pitch = 0.2 * np.sin(0.5 * s), 0.1 * np.cos(0.4 * s)
    acc = 9.80665 * np.stack([np.sin(pitch), -np.sin(roll) * np.cos(pitch),
                              -np.cos(roll) * np.cos(pitch)], axis=1)
    mag = np.stack([20.0 * np.cos(0.3 * s), -20.0 * np.sin(0.3 * s), np.full(n, 40.0)], axis=1)
    temp = 20.0 + 10.0 * s / s[-1]
    temp[n // 4:n // 4 + 20] = np.nan
    aux = np.column_stack([np.cos(k * s) for k in range(1, len(AUX_INPUTS) + 1)])
    raw = np.column_stack([gyr, acc, mag, temp, aux])
    raw[:, :9] += 0.01 * rng.standard_normal((n, 9))
    return t, raw
