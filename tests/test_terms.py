"""Diagnosed correction terms (sources/ImuTerms.c): signals and corrections against closed forms."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from contract import layout
from training import runtime

#: The runtime evaluates the same double expressions as the closed forms below; only the order of
#: additions can differ, so agreement is to a few ulps of the magnitudes involved (≤ 1e-12).
CLOSED_FORM_TOLERANCE = 1e-12
#: Regressor bounds that no signal of these recordings reaches: the term is never clamped.
UNBOUNDED = (-1e300, 1e300)
SOURCES = Path(__file__).resolve().parents[1] / "sources"
#: ImuGuardIssueAux of sources/ImuGuard.h.
AUX_BIT = 1 << int(re.search(r"ImuGuardIssueAux = 1 << (\d+)", (SOURCES / "ImuGuard.h").read_text()).group(1))


def _settings():
    return np.array(layout.settings_array())


def _coefficients(terms):
    """Identity thermal blocks and the terms: (target, a, b, coefficient) unbounded, or with (lo, hi)."""
    blocks = [layout.identity_block()] * 3
    full = [term if len(term) == 6 else (*term, *UNBOUNDED) for term in terms]
    return np.array(layout.pack_coefficients(blocks, layout.terms_block(full)))


def _recording(n=500, seed=1):
    """(t, inputs): random triads, a temperature ramp and random auxiliary inputs (INPUTS order)."""
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.005, 0.02, n))
    x = np.column_stack([rng.normal(0, 0.3, (n, 3)), rng.normal([0, 0, -9.8], 1.0, (n, 3)),
                         rng.normal([20, 0, 40], 2.0, (n, 3)), 20 + 0.05 * t,
                         rng.normal(0, 2.0, (n, len(layout.AUX_INPUTS)))])
    return t, x


def _column(name):
    return layout.INPUTS.index(name)


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
    aux = x[:, _column("aux_1"):]
    s = runtime.term_signals(t, x[:, :9], x[:, 9], aux)
    names = {n: i for i, n in enumerate(layout.TERM_SIGNALS)}
    assert s.shape == (t.size, len(layout.TERM_SIGNALS))
    assert np.array_equal(s[:, :9], x[:, :9])
    assert np.array_equal(s[:, [names[f"abs_{n}"] for n in layout.TERM_TARGETS]], np.abs(x[:, :9]))
    assert np.all(s[:, names["one"]] == 1.0)
    assert np.array_equal(s[:, [names[n] for n in layout.AUX_INPUTS]], aux)
    assert np.all(runtime.term_signals(t, x[:, :9], x[:, 9])[:, [names[n] for n in layout.AUX_INPUTS]] == 0.0)
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


def test_regressor_is_clamped_to_its_bounds():
    # A regressor beyond hi contributes coefficient·hi, below lo coefficient·lo, between them itself.
    t, x = _recording()
    lo, hi = -0.2, 0.1
    out = runtime.run_batch(_coefficients([("gyr_z", "gyr_x", None, 0.5, lo, hi)]), _settings(), t, x)
    gx = x[:, 0]
    assert (gx > hi).any() and (gx < lo).any() and ((gx > lo) & (gx < hi)).any()
    expected = x[:, 2] - 0.5 * np.clip(gx, lo, hi)
    assert np.max(np.abs(out[:, 2] - expected)) < CLOSED_FORM_TOLERANCE
    beyond = gx > hi
    assert np.array_equal(out[beyond, 2], x[beyond, 2] - 0.5 * hi)


def test_one_is_an_offset_and_abs_makes_a_signed_power():
    t, x = _recording()
    terms = [("acc_y", "one", None, 0.25, 0.0, 2.0), ("gyr_x", "gyr_x", "abs_gyr_x", 0.1, *UNBOUNDED)]
    out = runtime.run_batch(_coefficients(terms), _settings(), t, x)
    assert np.max(np.abs(out[:, 4] - (x[:, 4] - 0.25))) < CLOSED_FORM_TOLERANCE
    assert np.max(np.abs(out[:, 0] - (x[:, 0] - 0.1 * x[:, 0] * np.abs(x[:, 0])))) < CLOSED_FORM_TOLERANCE


def test_aux_terms_read_the_auxiliary_inputs():
    # A term on aux_k reads input aux_k of the same sample; a non-finite aux cell is bad input: the
    # guard holds the last finite value (issue 31 item 6: it used to skip the term without a flag).
    t, x = _recording()
    x[5:9, _column("aux_3")] = np.nan
    terms = [("mag_x", "aux_3", None, 0.7), ("gyr_y", "aux_1", "acc_z", 1e-3)]
    out, bits = runtime.run_batch_issues(_coefficients(terms), _settings(), t, x)
    aux3 = x[:, _column("aux_3")].copy()
    aux3[5:9] = aux3[4]
    assert np.max(np.abs(out[:, 6] - (x[:, 6] - 0.7 * aux3))) < CLOSED_FORM_TOLERANCE * 100
    expected_gy = x[:, 1] - 1e-3 * x[:, _column("aux_1")] * x[:, 5]
    assert np.max(np.abs(out[:, 1] - expected_gy)) < CLOSED_FORM_TOLERANCE
    np.testing.assert_array_equal(np.flatnonzero(bits & AUX_BIT), np.arange(5, 9))


def test_a_non_finite_aux_input_before_any_finite_one_skips_its_term_and_is_flagged():
    t, x = _recording()
    x[:3, _column("aux_2")] = np.nan
    out, bits = runtime.run_batch_issues(_coefficients([("acc_x", "aux_2", None, 0.5)]), _settings(), t, x)
    np.testing.assert_array_equal(out[:3, 3], x[:3, 3])
    assert np.all(bits[:3] & AUX_BIT) and not np.any(bits[3:] & AUX_BIT)


def test_an_unused_aux_input_is_never_bad_input():
    t, x = _recording()
    x[:, _column("aux_4")] = np.nan
    _, bits = runtime.run_batch_issues(_coefficients([("acc_x", "aux_2", None, 0.5)]), _settings(), t, x)
    assert not np.any(bits & AUX_BIT)


def test_the_fmu_warns_about_a_bad_aux_input_by_name_and_a_clamped_one_without_blaming_the_temperature(tmp_path):
    """aux_1 NaN for 5 samples: one Warning naming aux_1 and the value held; aux_1 = 1e300 for 5
    samples: the term's regressor is clamped to its fitted bounds, one Warning naming the correction
    terms and not the temperature (which is inside every range), calibration_valid = 0 there."""
    from fmu.cosim import run_fmu
    from training.fmu_build import build_fmu
    n = 60
    t = np.arange(n) * 0.01
    x = np.zeros((n, len(layout.INPUTS)))
    x[:, 5], x[:, 6], x[:, 8], x[:, 9], x[:, _column("aux_1")] = -9.80665, 20.0, 40.0, 25.0, 1.0
    x[10:15, _column("aux_1")] = np.nan
    x[30:35, _column("aux_1")] = 1e300
    fmu = build_fmu(_coefficients([("gyr_y", "aux_1", None, 0.01, -5.0, 5.0)]), {}, tmp_path / "ImuFusion.fmu",
                    aux_inputs=[{"column": "aux_1", "unit": "V", "meaning": "supply voltage"}])
    log: list[str] = []
    out = run_fmu(fmu, t, x, log=log)
    np.testing.assert_allclose(out[10:15, 1], -0.01)  # the held 1 V
    warnings = [m for m in log if m.startswith("[WARNING]")]
    assert len(warnings) == 2, log
    assert "bad auxiliary input aux_1 = nan (not finite)" in warnings[0] and "last finite value 1 " in warnings[0]
    assert "outside the calibrated range of the correction terms" in warnings[1] and "temperature" not in warnings[1]
    calibration_valid = out[:, layout.OUTPUTS.index("calibration_valid")]
    np.testing.assert_array_equal(np.flatnonzero(calibration_valid == 0.0), np.arange(30, 35))


def test_signal_vocabulary_matches_the_c_enum():
    # ImuSigAbsGyrX <-> abs_gyr_x: the C enum of ImuTerms.h and layout.TERM_SIGNALS, same order.
    body = re.search(r"typedef enum \{(.*?)IMU_TERM_SIGNAL_COUNT", (SOURCES / "ImuTerms.h").read_text(), re.S)
    names = re.findall(r"ImuSig(\w+)", re.sub(r"/\*.*?\*/", "", body.group(1)))
    snake = [re.sub(r"(?<=[a-z0-9])(?=[A-Z0-9])|(?<=[A-Z])(?=[A-Z][a-z])", "_", n).lower() for n in names]
    assert tuple(snake) == layout.TERM_SIGNALS


N_SIGNALS = len(layout.TERM_SIGNALS)


@pytest.mark.parametrize("bad", [
    [layout.TERMS_MAX + 1.0], [1.0, 9.0, 0.0, -1.0, 1.0, 0.0, 1.0], [1.0, 0.0, N_SIGNALS, -1.0, 1.0, 0.0, 1.0],
    [1.0, 0.0, 0.0, -2.0, 1.0, 0.0, 1.0], [1.0, 0.0, 0.0, -1.0, np.nan, 0.0, 1.0],
    [1.0, 0.0, 0.0, -1.0, 1.0, np.nan, 1.0], [1.0, 0.0, 0.0, -1.0, 1.0, 0.0, np.inf],
    [1.0, 0.0, 0.0, -1.0, 1.0, 1.0, 0.0]])
def test_invalid_terms_block_rejected(bad):
    block = bad + [0.0] * (layout.TERMS_BLOCK - len(bad))
    c = np.array(layout.pack_coefficients([layout.identity_block()] * 3, block))
    with pytest.raises(ValueError, match="code -4"):
        runtime.run_batch(c, _settings(), [0.0], np.zeros((1, len(layout.INPUTS))))


def test_too_many_terms_rejected_in_python():
    with pytest.raises(ValueError, match="at most"):
        layout.terms_block([("gyr_x", "acc_z", None, 1.0, *UNBOUNDED)] * (layout.TERMS_MAX + 1))


def test_the_most_terms_fit_the_runtime():
    t, x = _recording(50)
    terms = [("gyr_x", "one", None, 1e-3, 0.0, 1.0)] * layout.TERMS_MAX
    out = runtime.run_batch(_coefficients(terms), _settings(), t, x)
    assert np.max(np.abs(out[:, 0] - (x[:, 0] - layout.TERMS_MAX * 1e-3))) < CLOSED_FORM_TOLERANCE
