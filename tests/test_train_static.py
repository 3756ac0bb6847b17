"""train() on a static log: the gains are not identifiable, so only the bias B(T) is fitted."""
from __future__ import annotations

import numpy as np

from training.data.dataset import ImuData
from training.models.thermal import apply_thermal
from training.train import MIN_EXCITATION, train

#: White noise σ of the synthetic gyro [rad/s]; the fitted bias may miss the true one by a few
#: σ/√N per coefficient, so 1e-4 rad/s (0.006 °/s) over the range is a generous bound.
NOISE = 1e-3
BIAS_TOLERANCE = 1e-4


def _static_log(n: int = 20000, seed: int = 0) -> tuple[ImuData, np.ndarray]:
    """A static gyro cooling from 24 to 16 °C with a quadratic bias; no accelerometer, no field."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.02
    temp = 24.0 - 8.0 * t / t[-1]
    d = temp - 20.0
    bias = np.column_stack([0.001 * d + 2e-5 * d ** 2 - 0.07, -0.0005 * d + 0.06, 0.03 + 0 * d])
    gyr = bias + rng.normal(0.0, NOISE, (n, 3))
    nan3 = np.full((n, 3), np.nan)
    data = ImuData(t=t, gyr=gyr, acc=nan3, mag=nan3.copy(), temp=temp, ref_gyr=np.zeros((n, 3)),
                   meta={"rate_hz": 50.0}, name="static")
    return data, bias


def test_static_gyro_gets_a_bias_only_model():
    data, bias = _static_log()
    artefact = train([data], seed=0, progress=False)
    model = artefact.thermal["gyr"]
    assert np.array_equal(model.A, np.eye(3)) and not model.g.any()
    assert artefact.fit_stats["gyr"]["bias_only"] is True
    assert artefact.fit_stats["gyr"]["weakest_excitation"] < MIN_EXCITATION["gyr"]
    assert any("bias B(T) only" in n for n in artefact.notes)
    corrected = apply_thermal(model, data.gyr - 0.0, data.temp)
    fitted_bias = data.gyr - corrected
    assert np.max(np.abs(fitted_bias - bias)) < BIAS_TOLERANCE
    # rotation still reaches the output: a static-trained model must not zero the rates
    assert np.allclose(apply_thermal(model, bias + 1.0, data.temp), 1.0, atol=BIAS_TOLERANCE)
