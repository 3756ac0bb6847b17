"""Diagnosed correction terms (sources/ImuTerms.c): signals and corrections against closed forms."""
from __future__ import annotations

import numpy as np
import pytest

from training import layout, runtime

#: The runtime evaluates the same double expressions as the closed forms below; only the order of
#: additions can differ, so agreement is to a few ulps of the magnitudes involved (≤ 1e-12).
CLOSED_FORM_TOLERANCE = 1e-12


def _settings():
    return np.array(layout.settings_array())


def _coefficients(terms):
    blocks = [layout.identity_block()] * 3
    return np.array(layout.pack_coefficients(blocks, layout.terms_block(terms)))


def _recording(n=500, seed=1):
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.005, 0.02, n))
    x = np.column_stack([rng.normal(0, 0.3, (n, 3)), rng.normal([0, 0, -9.8], 1.0, (n, 3)),
                         rng.normal([20, 0, 40], 2.0, (n, 3)), 20 + 0.05 * t])
    return t, x


def test_no_terms_change_nothing():
    t, x = _recording()
    a = runtime.run_batch(_coefficients([]), _settings(), t, x)
    b = runtime.run_batch(np.array(layout.identity_coefficients()), _settings(), t, x)
    assert np.array_equal(a, b)
    assert np.array_equal(a[:, :9], x[:, :9])


def test_g_sensitivity_and_product_terms_match_closed_form():
    t, x = _recording()
    terms = [("gyr_x", "acc_z", None, 1e-3), ("gyr_y", "acc_x", "acc_y", -2e-4),
             ("mag_z", "temp", None, 0.05)]
    out = runtime.run_batch(_coefficients(terms), _settings(), t, x)
    expected_gx = x[:, 0] - 1e-3 * x[:, 5]
    expected_gy = x[:, 1] + 2e-4 * x[:, 3] * x[:, 4]
    expected_mz = x[:, 8] - 0.05 * x[:, 9]
    assert np.max(np.abs(out[:, 0] - expected_gx)) < CLOSED_FORM_TOLERANCE
    assert np.max(np.abs(out[:, 1] - expected_gy)) < CLOSED_FORM_TOLERANCE
    assert np.max(np.abs(out[:, 8] - expected_mz)) < CLOSED_FORM_TOLERANCE * 100


def test_signals_closed_form():
    t, x = _recording()
    s = runtime.term_signals(t, x[:, :9], x[:, 9])
    names = {n: i for i, n in enumerate(layout.TERM_SIGNALS)}
    assert np.array_equal(s[:, :9], x[:, :9])
    assert np.allclose(s[:, names["time"]], t - t[0], rtol=0, atol=1e-12)
    d = np.diff(x[:, 3]) / np.diff(t)
    assert np.allclose(s[1:, names["d_acc_x"]], d, rtol=1e-12, atol=1e-9)
    assert np.isnan(s[0, names["d_acc_x"]])
    # A linear ramp of 0.05 °C/s: the low-passed rate converges to it (time constant 10 s).
    late = t > t[0] + 5 * 10.0
    if late.any():
        assert np.allclose(s[late, names["temp_rate"]], 0.05, atol=0.05 * np.exp(-4))


def test_temperature_rate_converges_on_a_long_ramp():
    t = np.arange(0.0, 120.0, 0.1)
    temp = 10.0 + 0.02 * t
    s = runtime.term_signals(t, np.zeros((t.size, 9)), temp)
    rate = s[:, layout.TERM_SIGNALS.index("temp_rate")]
    # first-order low-pass of a constant backward difference: error decays as exp(-t/10 s)
    assert abs(rate[-1] - 0.02) < 0.02 * np.exp(-100.0 / 10.0) * 2


def test_nan_regressor_skips_the_term():
    # Before the first valid temperature the runtime's guard (sources/ImuGuard.c) passes NaN on;
    # after it, a bad temperature is replaced by the last valid one.
    t, x = _recording(50)
    x[:10, 9] = np.nan
    x[20:30, 9] = np.nan
    out = runtime.run_batch(_coefficients([("gyr_z", "temp", None, 1e-3)]), _settings(), t, x)
    assert np.array_equal(out[:10, 2], x[:10, 2])
    assert np.max(np.abs(out[20:30, 2] - (x[20:30, 2] - 1e-3 * x[19, 9]))) < CLOSED_FORM_TOLERANCE


@pytest.mark.parametrize("bad", [
    [17.0], [1.0, 9.0, 0.0, -1.0, 1.0], [1.0, 0.0, 21.0, -1.0, 1.0], [1.0, 0.0, 0.0, -2.0, 1.0],
    [1.0, 0.0, 0.0, -1.0, np.nan]])
def test_invalid_terms_block_rejected(bad):
    block = bad + [0.0] * (layout.TERMS_BLOCK - len(bad))
    c = np.array(layout.pack_coefficients([layout.identity_block()] * 3, block))
    with pytest.raises(ValueError, match="code -4"):
        runtime.run_batch(c, _settings(), [0.0], np.zeros((1, 10)))


def test_too_many_terms_rejected_in_python():
    with pytest.raises(ValueError, match="at most"):
        layout.terms_block([("gyr_x", "acc_z", None, 1.0)] * (layout.TERMS_MAX + 1))
