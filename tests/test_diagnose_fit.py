"""The significance of a diagnosed candidate is Bonferroni-corrected (training.diagnosis.diagnose_fit):
its one-sided p over the held-out batches is multiplied by the number of candidates tried, capped at 1.
The fit and the held-out errors are stubbed with known numbers so that the test sees the correction
alone: the same errors scored as one of 5 candidates give 5 × the p of one candidate."""
from __future__ import annotations

from types import SimpleNamespace

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
