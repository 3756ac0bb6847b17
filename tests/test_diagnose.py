"""`imufmu diagnose` on simulated sensors with one known missing effect each (scenarios/variants/diag_*)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from training.artefact import coefficients_array, load_artefact
from training.data.io import write_imu_csv
from training.diagnosis.diagnose import diagnose
from training.main_job import SCENARIO_DIR
from training.simulator import load_scenario, simulate
from training.train import train

VARIANTS = SCENARIO_DIR / "variants"
#: Issue 7: the held-out gyro rate error must fall by at least 70 % once g-sensitivity is added
#: (g-sensitivity ≈ 0.18 °/s RMS against 0.03 °/s white noise leaves room for ~83 %).
GSENS_MIN_IMPROVEMENT_PCT = 70.0
KEYS = {"target", "metric", "candidates", "selected", "before", "after", "improvement_pct"}
#: The two further effects must lower their held-out error by at least half. The magnetometer drift
#: (0.4 µT/min) sits on 0.1 µT white noise, which caps the achievable drop at ~60 %; the
#: accelerometer's temperature-rate bias (0.08 m/s² at 20 °C/min) sits on 0.01 m/s² noise (~80 %).
OTHER_MIN_IMPROVEMENT_PCT = 50.0


def run_case(case: str, tmp: Path) -> dict:
    """Train on the short calibration of the case's sensor, diagnose its held-out dynamic recording."""
    cal = simulate(load_scenario(VARIANTS / f"diag_calibration_{case}.toml"))
    model = train([cal], seed=0, progress=False).save(tmp / "model" / "model.json")
    data = simulate(load_scenario(VARIANTS / f"diag_{case}.toml"))
    path = write_imu_csv(data, tmp / "data" / f"{data.name}.csv.gz")
    return diagnose([path], model, tmp / "report", seed=0)


@pytest.fixture(scope="module")
def gsens(tmp_path_factory):
    """The g-sensitivity case, with every significance test the diagnosis made recorded as (families
    fitted together, the families of the base it is tested against, the residuals it is fitted on, the
    count it was Bonferroni-corrected by) in the order made."""
    from training.diagnosis import diagnose as module
    tmp, tests, alive = tmp_path_factory.mktemp("gsens"), [], {}
    fit = module.fit_candidates

    def recorded(cands, r, base, offset_only, n_tests):
        alive[id(r)] = r    # held, so that no later residuals reuse the id
        tests.append((tuple(c.name for c in cands), tuple(c.name for c in base.candidates), id(r), n_tests))
        return fit(cands, r, base, offset_only, n_tests)

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(module, "fit_candidates", recorded)
        result = run_case("gsens", tmp)
    return result, tmp, tests


def test_diagnosis_is_deterministic(gsens):
    result, tmp, _ = gsens
    again = diagnose(sorted((tmp / "data").glob("*.csv.gz")), tmp / "model" / "model.json", tmp / "again",
                     seed=0, plots=False)
    assert json.loads(json.dumps(again)) == json.loads(json.dumps(result))
    assert (tmp / "again" / "model.json").read_bytes() == (tmp / "report" / "model.json").read_bytes()


def test_each_p_value_is_corrected_by_the_number_of_families_tried_beside_it(gsens):
    # A round of tests is the families scored alone in one selection, or the additions tried to the same
    # selected ones (a family, or train's bias model as one step), on one set of residuals; each p is
    # multiplied by that round's size.
    _, _, tests = gsens
    rounds: list[list[int]] = []
    previous = None
    for _, base, residuals, n_tests in tests:
        key = (base, residuals)
        if key != previous:
            rounds.append([])
        rounds[-1].append(n_tests)
        previous = key
    assert len(rounds) >= 2 and max(len(r) for r in rounds) > 1
    assert all(set(r) == {len(r)} for r in rounds), [(len(r), sorted(set(r))) for r in rounds]


def test_gyro_g_sensitivity_is_found_and_removed(gsens):
    result, _, _ = gsens
    assert result["selected"]["target"] == "gyr"
    assert set(result["selected"]["regressors"]) == {"acc_x", "acc_y", "acc_z"}
    assert result["improvement_pct"] >= GSENS_MIN_IMPROVEMENT_PCT


def test_report_files_and_fixed_keys(gsens):
    result, tmp, _ = gsens
    doc = json.loads((tmp / "report" / "diagnosis.json").read_text())
    assert KEYS <= set(doc) and doc == json.loads(json.dumps(result))
    assert all({"name", "target", "regressors", "explained_fraction", "p_value"} <= set(c) for c in doc["candidates"])
    assert {"name", "target", "regressors"} <= set(doc["selected"])
    for name in ("report.md", "model.json", "residual_time.png", "residual_vs_regressor.png", "before_after.png"):
        assert (tmp / "report" / name).is_file()


def test_new_artefact_carries_the_terms_into_the_runtime(gsens):
    _, tmp, _ = gsens
    art = load_artefact(tmp / "report" / "model.json")
    assert {t["a"] for t in art.terms} >= {"acc_x", "acc_y", "acc_z"}
    c = coefficients_array(art)
    base = coefficients_array(load_artefact(tmp / "model" / "model.json"))
    assert not np.array_equal(c, base)


# The simulated bias follows the instantaneous temperature rate: the runtime's 1 s low-pass of it
# (temp_rate_fast) is its reading, the 10 s one lags each rate reversal.
@pytest.mark.parametrize("case,target,regressor", [("acc_temp_rate", "acc", "temp_rate_fast"),
                                                    ("mag_drift", "mag", "time")])
def test_other_effects_are_found(case, target, regressor, tmp_path):
    result = run_case(case, tmp_path)
    assert result["selected"]["target"] == target and result["selected"]["regressors"] == [regressor]
    assert result["improvement_pct"] >= OTHER_MIN_IMPROVEMENT_PCT


def test_no_missing_effect_reports_nothing(tmp_path):
    result = run_case("clean", tmp_path)
    assert result["selected"] is None and result["after"] == result["before"]
    assert result["improvement_pct"] == 0.0
    assert "nothing significant left" in (tmp_path / "report" / "report.md").read_text()
