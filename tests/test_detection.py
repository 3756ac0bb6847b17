"""Detection limits (issue 30, item 3) are the loop's own selection rule: an effect of a family at the
limit `imufmu diagnose` states is selected by the selection's fit and test run directly on the residual
with that effect added, and one 3 % smaller is not.

The limit is found by injecting the family's effect and searching its size with fits that use the
linearity of every least-squares fit in the residual (training.diagnosis.detection); this test adds the
effect for real and runs the ordinary fit (training.diagnosis.diagnose_fit.fit_candidates). The two are
the same mathematics, so the bound is the search's resolution (2^(1/64), 1.1 %) with a margin: a wrong
combination of the two fits, a wrong search or a wrong scale fails it.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from contract.layout import TRIAD_ORDER, settings_defaults
from training.artefact import ModelArtefact
from training.diagnosis import detection
from training.diagnosis.candidates import build_candidates
from training.diagnosis.diagnose import ALPHA, MIN_EXPLAINED, _rate, residuals, targets_of
from training.diagnosis.diagnose_fit import fit_candidates, metric, offset_fit, predict
from training.main_job import SCENARIO_DIR
from training.models.thermal import ThermalModel
from training.simulator import load_scenario, simulate

#: (target, family): a signal's own nonlinearity (fitted with instruments, beside the gain refit), an
#: outside signal, a time shift, a cross-sensitivity and a norm target's family.
FAMILIES = [("gyr", "angular rate signed square"), ("acc", "temperature rate"), ("gyr", "angular rate time shift"),
            ("acc", "angular rate squared"), ("mag", "angular rate")]


#: An effect this much below the limit is not selected: the search's resolution, 1.1 %, with a margin.
BELOW = 0.03


@pytest.fixture(scope="module")
def setting():
    """Residuals of the simulated diagnosis recording with the identity model (the offset and the gain
    refit take up the uncalibrated bias and gain), its candidates and the loop's rule."""
    data = simulate(load_scenario(SCENARIO_DIR / "variants" / "diag_effects.toml"))
    model = ModelArtefact(seed=0, thermal={k: ThermalModel.identity(enabled=False) for k in TRIAD_ORDER},
                          settings=settings_defaults(), notes=[])
    targets = targets_of(data)
    r = residuals(model, [data], targets)
    candidates = build_candidates(r.signals, list(targets))
    return r, candidates, detection.Rule(MIN_EXPLAINED, ALPHA, len(candidates)), _rate([data])


def _selected_directly(r, c, effect: np.ndarray, rule) -> bool:
    injected = replace(r, residual={**r.residual, c.target: r.residual[c.target] + effect})
    base = offset_fit(c.target, injected)
    fit = fit_candidates((c,), injected, base, base, rule.n_tests)
    return fit is not None and fit.explained_fraction >= rule.min_explained and fit.p_value < rule.alpha


@pytest.mark.parametrize("target, family", FAMILIES, ids=[f"{t}: {f}" for t, f in FAMILIES])
def test_an_effect_at_the_limit_is_selected_and_one_3_percent_smaller_is_not(setting, target, family):
    r, candidates, rule, rate = setting
    c = next(c for c in candidates if c.target == target and c.name == family)
    limit = detection.detection_limit(r, c, rule, rate)
    assert limit["status"] == detection.LIMIT and limit["rms"] > 0, limit
    unit = predict(detection._as_fit(c, detection._direction(c, r)), r)
    scale = limit["rms"] / metric(replace(r, residual={c.target: unit}), c.target)
    assert _selected_directly(r, c, scale * unit, rule), limit
    assert not _selected_directly(r, c, (1.0 - BELOW) * scale * unit, rule), limit


def test_a_family_the_residual_holds_already_is_reported_present(setting):
    """The identity model leaves the simulated gyro's bias drift with temperature (and the uncalibrated
    magnetometer's iron) in the residual: those families are selected without any effect added, and
    the limit says so instead of a size."""
    r, candidates, rule, rate = setting
    c = next(c for c in candidates if c.target == "gyr" and c.name == "temperature")
    assert _selected_directly(r, c, np.zeros_like(r.residual["gyr"]), rule)
    assert detection.detection_limit(r, c, rule, rate)["status"] == detection.PRESENT


def test_the_p_value_is_bonferroni_corrected_over_the_candidates(setting):
    """The selection's p-value is the test's p times the candidate count (capped at 1): the same effect,
    at its detection limit so that its raw p is neither 0 nor 1, fitted as one test and as the loop's
    n_tests."""
    r, candidates, rule, rate = setting
    c = next(c for c in candidates if c.target == "gyr" and c.name == "angular rate signed square")
    limit = detection.detection_limit(r, c, rule, rate)
    unit = predict(detection._as_fit(c, detection._direction(c, r)), r)
    scale = limit["rms"] / metric(replace(r, residual={c.target: unit}), c.target)
    injected = replace(r, residual={**r.residual, c.target: r.residual[c.target] + scale * unit})
    base = offset_fit(c.target, injected)
    single, corrected = (fit_candidates((c,), injected, base, base, n) for n in (1, rule.n_tests))
    assert rule.n_tests > 1 and 0.0 < single.p_value < corrected.p_value < 1.0
    assert corrected.p_value == pytest.approx(rule.n_tests * single.p_value, rel=1e-12)
