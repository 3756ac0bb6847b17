"""The significance of a diagnosed candidate is Bonferroni-corrected (training.diagnosis.diagnose_fit):
its one-sided p over the held-out batches is multiplied by the number of candidates tried, capped at 1.
The fit and the held-out errors are stubbed with known numbers so that the test sees the correction
alone: the same errors scored as one of 5 candidates give 5 × the p of one candidate."""
from __future__ import annotations

from types import SimpleNamespace

from dataclasses import replace

import numpy as np

from training.diagnosis import diagnose_fit

#: Held-out rows and the batches they fall in (the diagnosis's held-out blocks).
ROWS, BATCHES = 400, 8


def _stubbed(monkeypatch):
    """Errors of the base and of the candidate fit on ROWS held-out rows: the candidate removes a part
    of the base's error that varies by batch, so the batch test gives a p well inside (0, 1)."""
    rng = np.random.default_rng(0)
    batch = np.repeat(np.arange(BATCHES), ROWS // BATCHES)
    base = rng.standard_normal(ROWS)
    better = base * np.where(batch % 3 == 0, 1.0, 0.95) + 0.05 * rng.standard_normal(ROWS)
    errors = {"base": base, "candidate": better}
    monkeypatch.setattr(diagnose_fit, "fit_beta", lambda cands, target, r: np.zeros(3))
    monkeypatch.setattr(diagnose_fit, "test_errors",
                        lambda cands, beta, target, r: (errors["candidate" if cands else "base"], np.arange(ROWS)))
    r = SimpleNamespace(test=np.ones(ROWS, dtype=bool), block=batch, signals={})  # no signals: no linear refit
    candidate = SimpleNamespace(target="gyr", kind="terms")
    base_fit = diagnose_fit.Fit((), np.zeros(3), 0.0, 0.0, 1.0)
    return candidate, r, base_fit


def test_the_p_value_is_multiplied_by_the_candidates_tried(monkeypatch):
    candidate, r, base = _stubbed(monkeypatch)
    one = diagnose_fit.fit_candidates((candidate,), r, base, base, n_tests=1).p_value
    five = diagnose_fit.fit_candidates((candidate,), r, base, base, n_tests=5).p_value
    assert 0.0 < one < 0.2
    assert five == min(1.0, 5.0 * one)
    assert diagnose_fit.fit_candidates((candidate,), r, base, base, n_tests=1000).p_value == 1.0


def _gyro_residuals(reference: np.ndarray, bias: np.ndarray) -> diagnose_fit.Residuals:
    """Residuals of a gyro whose compensated signal is reference + bias (N, 3) [rad/s]."""
    n = len(reference)
    signal = reference + bias
    signals = {f"gyr_{a}": signal[:, i] for i, a in enumerate("xyz")}
    rows = np.ones(n, dtype=bool)
    return diagnose_fit.Residuals(t=np.arange(n) * 0.01, starts=np.array([0]), signals=signals,
                                  instruments={"gyr": signals}, residual={"gyr": bias}, direction={},
                                  train=rows, test=rows, holdout=rows, fitted=rows, block=np.zeros(n, int),
                                  excited=diagnose_fit.excitation(signals, {"gyr": bias}, rows))


def test_the_gain_is_refitted_only_where_the_reference_excites_it():
    # A static gyro against ref_gyr = 0: its signal is its (drifting) bias, and a "gain" on it would
    # absorb the drift that the temperature family must report (pan_thermal). A turning gyro: refitted.
    rng = np.random.default_rng(1)
    drift = np.linspace(0.0, 0.05, ROWS)[:, None] * np.array([1.0, -0.5, 0.2]) + 1e-4 * rng.standard_normal((ROWS, 3))
    turning = np.column_stack([np.sin(np.arange(ROWS) / 20.0 + p) for p in (0.0, 1.0, 2.0)])
    static = _gyro_residuals(np.zeros((ROWS, 3)), drift)
    moving = _gyro_residuals(turning, drift)
    terms = SimpleNamespace(kind="terms")
    assert diagnose_fit.refit_for((terms,), "gyr", static) is None
    assert diagnose_fit.refit_for((terms,), "gyr", moving).name == "linear calibration"
    lag = SimpleNamespace(kind="lag", triad="gyr")
    assert diagnose_fit.refit_for((lag,), "gyr", moving) is None
    # a shift scanned beyond the linear range is not linearised: the gain is refitted beside it
    assert diagnose_fit.refit_for((lag,), "gyr", replace(moving, wide_shifts={"gyr": 0.2})).name == "linear calibration"


def test_a_calibration_bent_beyond_the_reference_still_gets_its_gain_refitted():
    # an effect in the calibration recording bent train's gain: the residual (a 150 % gain error on x)
    # is larger than the reference, but linear in the signal; the reference still excites the gain
    turning = np.column_stack([np.sin(np.arange(ROWS) / 20.0 + p) for p in (0.0, 1.0, 2.0)])
    bent = turning * np.array([1.5, 0.1, -0.1]) + 1e-3 * np.random.default_rng(3).standard_normal((ROWS, 3))
    assert _gyro_residuals(turning, bent).excited["gyr"]


def test_before_and_after_an_effect_are_compared_on_the_same_rows():
    """A norm residual leaves out its disturbed rows, judged anew on each residual: the comparison that
    accepts an effect uses the held-out rows finite in both (x-io with an injected motor current: the
    current's rows came back once corrected, and 5.4 → 9.1 µT compared different samples)."""
    from dataclasses import replace
    from training.diagnosis.diagnose import metric, paired_metric
    rng = np.random.default_rng(2)
    before = _gyro_residuals(np.zeros((ROWS, 3)), rng.standard_normal((ROWS, 3)))
    after_values = 0.5 * before.residual["gyr"]
    before.residual["gyr"][:40] = np.nan             # rows the residual before left out
    after_values[-40:] = np.nan                      # rows the residual after leaves out
    after = replace(before, residual={"gyr": after_values})
    both = np.zeros(ROWS, bool)
    both[40:-40] = True
    assert paired_metric(before, after, "gyr") == (metric(replace(before, holdout=both), "gyr"),
                                                   metric(replace(after, holdout=both), "gyr"))
    assert paired_metric(before, after, "gyr")[1] == 0.5 * paired_metric(before, after, "gyr")[0]
