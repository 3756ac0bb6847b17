"""An undeclared effect present in the calibration recording AND in the diagnosed one (issue 30, item 1).

A real sensor carries its effects whenever it runs, so `train` fitted its linear calibration on data
that had the effect: a gyro rate nonlinearity k·ω·|ω| bends the gain `train` fits by k times the
calibration's typical |ω|. The diagnosis refits the triad's gain matrix jointly with every family
(training.diagnosis.candidates.linear_refit), so the family reads the effect itself, and the FMU gets
the joint refit. Before, the same case read [-1.17, 0.989, -2.61] %/(rad/s) for the injected
[1.0, -0.8, 1.2] (wrong signs) and lowered the held-out error by 45.6 %.
"""
from __future__ import annotations

import json

import numpy as np
import pytest

from effects import EFFECTS
from training.artefact import load_artefact
from training.data.io import write_imu_csv
from training.diagnosis.diagnose import diagnose
from training.main_job import SCENARIO_DIR
from training.simulator import load_scenario, simulate
from training.train import train

VARIANTS = SCENARIO_DIR / "variants"
#: The injected rate nonlinearity [1/(rad/s)] per axis (tests/effects.py gyro_rate_scale's default).
K = np.array([0.01, -0.008, 0.012])
#: Issue 30's acceptance: the reading within 15 % of the injected value, per axis.
READING_TOLERANCE = 0.15
#: ... and the held-out error at least 70 % lower (tests/test_diagnose_effects.py MIN_IMPROVEMENT_PCT).
MIN_IMPROVEMENT_PCT = 70.0


@pytest.fixture(scope="module")
def diagnosed(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("refit")
    effect = EFFECTS["gyro_rate_scale"]
    calibration = effect(simulate(load_scenario(VARIANTS / "diag_calibration_clean.toml")), k=tuple(K))
    model = train([calibration], seed=0, progress=False).save(tmp / "model" / "model.json")
    data = effect(simulate(load_scenario(VARIANTS / "diag_effects.toml")), k=tuple(K))
    path = write_imu_csv(data, tmp / "data" / "diag_effects.csv.gz")
    return diagnose([path], model, tmp / "report", seed=0, plots=False, progress=False), tmp


def test_the_nonlinearity_is_read_within_15_percent_and_removed(diagnosed):
    result, tmp = diagnosed
    assert result["iterations"][0]["selected"]["name"] == "angular rate signed square"
    terms = load_artefact(tmp / "report" / "model.json").terms
    read = np.array([sum(t["coefficient"] for t in terms if t["target"] == f"gyr_{a}" and t["a"] == f"gyr_{a}"
                         and t["b"] == f"abs_gyr_{a}") for a in "xyz"])
    assert np.all(np.abs(read - K) <= READING_TOLERANCE * np.abs(K)), read
    assert result["improvement_pct"] >= MIN_IMPROVEMENT_PCT


def test_the_gain_refit_is_carried_and_reported(diagnosed):
    result, tmp = diagnosed
    refit = result["iterations"][0]["selected"]["linear_refit"]["gain_change"]
    # train's gain absorbed k·|ω| averaged over the calibration's rotations: the refit takes it back
    # with the opposite sign of k on every axis
    assert np.all(np.sign(np.diag(refit)) == -np.sign(K)), refit
    names = {t["name"] for t in load_artefact(tmp / "report" / "model.json").terms}
    assert "diagnose: gyr linear calibration refit" in names
    assert "gain matrix refitted jointly" in (tmp / "report" / "report.md").read_text()
    assert json.loads((tmp / "report" / "diagnosis.json").read_text())["iterations"][0]["selected"]["linear_refit"]
