"""An undeclared effect present in the calibration recording AND in the diagnosed one (issue 30).

A real sensor carries its effects whenever it runs, so `train` fitted its linear calibration on data
that had the effect: a gyro rate nonlinearity k·ω·|ω| bends the gain `train` fits by k times the
calibration's typical |ω|. The diagnosis refits the triad's gain matrix jointly with every family
(training.diagnosis.candidates.linear_refit), so the family reads the effect itself, and the FMU gets
the joint refit. Before, the rate nonlinearity read [-1.17, 0.989, -2.61] %/(rad/s) for the injected
[1.0, -0.8, 1.2] (wrong signs) and lowered the held-out error by 45.6 %; a supply-voltage gyro bias
beside an irrelevant aux column was taken as "all aux columns" together (53 % lower, no reading).

The three cases the issue names, and two whose effect a trained neural stage learned in part from the
calibration (the PSO-BP network a temperature-rate bias, the ELM a magnetometer 200 ms late): the
diagnosis switches that stage off when the effect's family, the linear refit and train's bias model
leave less without it (training.diagnosis.diagnose._proposals). Before, neither was found (0.184 °/s
and 25.7 µT left). The table of every effect in both
recordings is docs/diagnosis/effects_in_calibration.md (benchmarks/diagnose_effects.py --in-calibration).
"""
from __future__ import annotations

import json

import numpy as np
import pytest

from effects import EFFECTS, regressor_family
from training.artefact import load_artefact
from training.data.io import write_imu_csv
from training.diagnosis.diagnose import diagnose
from training.main_job import SCENARIO_DIR
from training.simulator import load_scenario, simulate
from training.train import train

VARIANTS = SCENARIO_DIR / "variants"
#: Issue 30's acceptance: the reading within 15 % of the injected value, per coefficient ...
READING_TOLERANCE = 0.15
#: ... and the held-out error at least 70 % lower (tests/test_diagnose_effects.py MIN_IMPROVEMENT_PCT),
MIN_IMPROVEMENT_PCT = 70.0
#: or at the noise floor: the triad's white noise per sample, 0.03 °/s and 0.1 µT (tests/effects.py),
#: within 10 % (what a fit of a few dozen coefficients on the training blocks leaves on the held-out ones).
NOISE_FLOOR, FLOOR_MARGIN = {"gyr": 0.03, "mag": 0.10}, 1.10
#: Families of train's bias model B(T) (regressor_family of "temp", "temp*temp"): refitting them beside
#: an effect undoes what the effect bent in the calibration; they are not another effect.
BIAS_MODEL_FAMILIES = {"temp", "temp*temp"}
#: The injected effects and what reads them: (magnitude, the terms (target, a, b) whose coefficients read it
#: or "lag_<triad>" for the runtime's time shift [s], the injected values in the terms' units
#: [1/(rad/s), 1/(rad/s), rad/s per V, rad/s per °C/s, s], the neural stage the diagnosis must switch off).
CASES = {
    "gyro_rate_scale": ({"k": (0.01, -0.008, 0.012)},
                        [(f"gyr_{a}", f"gyr_{a}", f"abs_gyr_{a}") for a in "xyz"], (0.01, -0.008, 0.012), None),
    "gyro_cross_products": ({"k": (0.006, -0.005)},
                            [("gyr_y", "gyr_x", "gyr_z"), ("gyr_z", "gyr_x", "gyr_y")], (0.006, -0.005), None),
    "supply_gyro_bias": ({"c_dps_per_v": (0.8, -0.6, 0.7)},
                         [(f"gyr_{a}", "aux_1", None) for a in "xyz"], np.radians([0.8, -0.6, 0.7]), None),
    "temp_rate_bias": ({"c_dps_per_c_per_min": (0.05, -0.04, 0.045)},
                       [(f"gyr_{a}", "temp_rate", None) for a in "xyz"], 60.0 * np.radians([0.05, -0.04, 0.045]),
                       "enable_psobp"),
    "mag_long_delay": ({"samples": 20}, "lag_mag", (0.2,), "enable_elm"),
}


def _read(model, keys) -> np.ndarray:
    """The diagnosed model's reading of an effect: its lag setting, or the summed coefficients of its terms."""
    if isinstance(keys, str):
        return np.array([model.settings[keys]])
    return np.array([sum(t["coefficient"] for t in model.terms if (t["target"], t["a"], t["b"]) == key) for key in keys])


@pytest.fixture(scope="module")
def diagnosed(tmp_path_factory):
    """name -> (result, folder): each case trained on the calibration recording with the effect and
    diagnosed on the held-out recording with it (the same aux waveform seeds as the benchmark)."""
    calibration = simulate(load_scenario(VARIANTS / "diag_calibration_clean.toml"))
    test = simulate(load_scenario(VARIANTS / "diag_effects.toml"))
    out = {}
    for name, (magnitude, _, _, _) in CASES.items():
        tmp, effect = tmp_path_factory.mktemp(name), EFFECTS[name]
        model = train([effect(calibration, np.random.default_rng(3), **magnitude)], seed=0,
                      progress=False).save(tmp / "model" / "model.json")
        path = write_imu_csv(effect(test, np.random.default_rng(7), **magnitude), tmp / "data" / "diag_effects.csv.gz")
        out[name] = (diagnose([path], model, tmp / "report", seed=0, plots=False, progress=False, limits=False), tmp)
    return out


@pytest.mark.parametrize("name", sorted(CASES))
def test_the_effect_is_found_read_within_15_percent_and_removed(diagnosed, name):
    result, tmp = diagnosed[name]
    first = {regressor_family(r) for r in result["iterations"][0]["selected"]["regressors"]}
    # beside the effect only the forms of train's own bias model, which the effect bent too (a supply
    # sag that differed between the calibration's soaks bends the bias(T) train fitted), never the decoy
    assert set(EFFECTS[name].family) <= first <= set(EFFECTS[name].family) | BIAS_MODEL_FAMILIES, first
    assert not any("aux_fan_speed" in r for it in result["iterations"] for r in it["selected"]["regressors"])
    _, keys, injected, stage = CASES[name]
    read = _read(load_artefact(tmp / "report" / "model.json"), keys)
    assert np.all(np.abs(read - injected) <= READING_TOLERANCE * np.abs(injected)), read
    assert result["iterations"][0]["selected"]["stage_off"] == stage
    at_floor = result["after"] <= FLOOR_MARGIN * NOISE_FLOOR[EFFECTS[name].target]
    assert result["improvement_pct"] >= MIN_IMPROVEMENT_PCT or at_floor, (result["improvement_pct"], result["after"])


def test_the_gain_refit_is_carried_and_reported(diagnosed):
    result, tmp = diagnosed["gyro_rate_scale"]
    refit = result["iterations"][0]["selected"]["linear_refit"]["gain_change"]
    # train's gain absorbed k·|ω| averaged over the calibration's rotations: the refit takes it back
    # with the opposite sign of k on every axis
    assert np.all(np.sign(np.diag(refit)) == -np.sign(CASES["gyro_rate_scale"][2])), refit
    names = {t["name"] for t in load_artefact(tmp / "report" / "model.json").terms}
    assert "diagnose: gyr linear calibration refit" in names
    assert "gain matrix refitted jointly" in (tmp / "report" / "report.md").read_text()
    assert json.loads((tmp / "report" / "diagnosis.json").read_text())["iterations"][0]["selected"]["linear_refit"]


def test_a_trained_stage_is_traded_only_for_a_clear_improvement():
    # an effect that switches the ELM or the PSO-BP network off must lower the held-out squared error by
    # MIN_EXPLAINED (5 %), the share a family must explain to be selected; any other by any amount
    from training.diagnosis.diagnose import _accepted
    assert _accepted(1.0, 0.99, "")
    assert not _accepted(1.0, 0.98, "enable_elm")
    assert _accepted(1.0, 0.97, "enable_psobp")
    assert not _accepted(1.0, 1.0, "")


def test_the_particle_filter_is_one_of_the_field_stages_the_sweep_switches_off():
    """The particle filter follows the hard and soft iron online, so a switched current's field is a hard-iron
    change to it: `train` switched it on for BROAD with a motor current in the calibration, and with it on the
    current's family read nothing (field error 14.9 µT); swept with it off, the current is read within 4 %
    and the error falls to 0.90 µT (benchmarks/diagnose_real_injected.py). Each field stage that is on is swept
    off alone; a stage that is off is not swept."""
    from dataclasses import replace
    from training.artefact import ModelArtefact
    from training.diagnosis.diagnose import _stages_off
    base = ModelArtefact(seed=0, thermal={}, settings={"enable_pf": 1.0, "enable_elm": 1.0, "enable_psobp": 1.0})
    off = dict((setting, art.settings) for art, setting in _stages_off(base, "mag"))
    assert set(off) == {"enable_pf", "enable_elm"}
    assert off["enable_pf"]["enable_pf"] == 0.0 and off["enable_pf"]["enable_elm"] == 1.0
    assert [s for _, s in _stages_off(replace(base, settings={"enable_pf": 0.0}), "mag")] == []
    assert [s for _, s in _stages_off(base, "gyr")] == ["enable_psobp"]
