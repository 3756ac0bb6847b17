"""Online learning of the gyro bias at rests (issue 33 item 3; sources/ImuBiasLearning.h).

A sensor at rest (true rate 0, gravity along −z) whose gyro carries a constant bias the calibration does
not know (the identity calibration here), with white noise σ: the learnt correction removes the bias, the
output bias_learning_shift says how far it moved, the correction never exceeds bias_learning_limit, a rest
during a fast temperature change teaches nothing, and the FMU through fmpy equals the batch runtime bit for
bit. What the learning buys and that it does no harm on a calibrated unit: benchmarks/bias_learning.py.
"""
from __future__ import annotations

import numpy as np
import pytest

from contract.layout import INPUTS, OUTPUTS, identity_coefficients, settings_array, settings_defaults
from fmu.cosim import run_fmu
from training.fmu_build import build_fmu
from training.runtime import run_batch

RATE_HZ = 100.0
SIGMA = 5e-4               # rad/s per sample
BIAS = 5.0 * SIGMA * np.array([1.0, -1.0, 1.0])   # the 5 σ power-up bias change
RATE = slice(OUTPUTS.index("rate_x"), OUTPUTS.index("rate_x") + 3)
SHIFT = OUTPUTS.index("bias_learning_shift")
#: After 120 s of rest the learnt bias averages ~1 / bias_learning_rate = 100 s of 1 s block means
#: (σ / 10 each): its error is ~σ/10 · √(0.01 / 2) ≈ 0.007 σ, plus the steps the adaptive rate took on
#: the way; 0.2 σ is far above that and far below the 5 σ a broken sign or rule leaves.
LEARNT_TOLERANCE = 0.2 * SIGMA


def rest_recording(seconds: float, bias: np.ndarray, temperature=25.0, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(t, inputs): a still sensor, gyro = bias + noise σ, acc = gravity + noise, a constant field."""
    rng = np.random.default_rng(seed)
    n = int(seconds * RATE_HZ)
    inputs = np.zeros((n, len(INPUTS)))
    inputs[:, 0:3] = bias + SIGMA * rng.standard_normal((n, 3))
    inputs[:, 3:6] = [0.0, 0.0, -9.80665] + 0.005 * rng.standard_normal((n, 3))
    inputs[:, 6:9] = [20.0, 0.0, 43.3]
    inputs[:, 9] = temperature
    return np.arange(n) / RATE_HZ, inputs


def batch(t, inputs, **settings) -> np.ndarray:
    return run_batch(np.asarray(identity_coefficients()), np.asarray(settings_array(settings)), t, inputs)


def test_a_bias_at_rest_is_learnt_and_the_shift_says_how_far():
    t, inputs = rest_recording(120.0, BIAS)
    out = batch(t, inputs)
    last = t >= 100.0
    np.testing.assert_allclose(out[last, RATE].mean(axis=0), 0.0, atol=LEARNT_TOLERANCE)
    assert abs(out[-1, SHIFT] - np.linalg.norm(BIAS)) < LEARNT_TOLERANCE
    off = batch(t, inputs, bias_learning=0.0)
    np.testing.assert_allclose(off[last, RATE].mean(axis=0), BIAS, atol=LEARNT_TOLERANCE)
    assert np.all(off[:, SHIFT] == 0.0)


def test_the_learnt_correction_never_exceeds_the_limit():
    limit = 2.0 * SIGMA
    t, inputs = rest_recording(60.0, BIAS)
    out = batch(t, inputs, bias_learning_limit=limit)
    # the identity calibration has no temperature model: only d0 learns, each axis clipped to ±limit
    assert out[:, SHIFT].max() <= np.sqrt(3.0) * limit * (1 + 1e-12)
    np.testing.assert_allclose(out[-1000:, RATE].mean(axis=0), BIAS - np.sign(BIAS) * limit, atol=LEARNT_TOLERANCE)


def test_a_rest_while_the_temperature_changes_fast_teaches_nothing():
    t, inputs = rest_recording(60.0, BIAS)
    inputs[:, 9] = 25.0 + t * 10.0 / 60.0          # 10 °C/min, twice IMU_BIAS_LEARNING_MAX_TEMPERATURE_RATE
    assert np.all(batch(t, inputs)[:, SHIFT] == 0.0)
    inputs[:, 9] = 25.0 + t * 2.0 / 60.0           # 2 °C/min: learnt
    assert batch(t, inputs)[-1, SHIFT] > 0.9 * np.linalg.norm(BIAS)


def test_motion_teaches_nothing():
    t, inputs = rest_recording(60.0, BIAS)
    inputs[:, 2] += 0.3 * np.sin(2.0 * np.pi * 0.5 * t)   # turning about z, ±17 °/s
    assert np.all(batch(t, inputs)[:, SHIFT] == 0.0)


@pytest.mark.parametrize("fmi_version", [2, 3])
def test_the_fmu_learns_as_the_batch_runtime(tmp_path, fmi_version):
    t, inputs = rest_recording(30.0, BIAS)
    settings = settings_defaults()
    fmu = build_fmu(np.asarray(identity_coefficients()), settings, tmp_path / "ImuFusion.fmu", fmi_version=fmi_version)
    out = run_fmu(fmu, t, inputs)
    np.testing.assert_array_equal(out, batch(t, inputs))
    assert out[-1, SHIFT] > 0.5 * np.linalg.norm(BIAS)
