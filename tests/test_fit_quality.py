"""Issue 15, item 3: a fit outside what the sensor class allows is a warning in the printed summary.

Bounds come from training/models/fit_quality.py (datasheet tolerances with a margin). The end-to-end case
trains on the two-soak recording with the accelerometer's sensitivity 15 % high — three times the
5 % class tolerance — so its fitted gain A_ii ≈ 1/1.15 = 0.870 must be flagged, and the same
recording at the true sensitivity must not be.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from contract.layout import TRIAD_ORDER, settings_defaults
from training.artefact import ModelArtefact
from training.main_job import SCENARIO_DIR
from training.models.fit_quality import (CROSS_AXIS_LIMIT_DEG, GYRO_NOISE_CLASS, SCALE_TOLERANCE,
                                         fit_warnings, noise_warnings)
from training.models.thermal import ThermalModel
from training.reports.calibration_report import summary_text
from training.simulator import load_scenario, simulate
from training.train import train

SCENARIO = SCENARIO_DIR / "variants" / "two_soaks.toml"
#: Accelerometer sensitivity error of the out-of-class sensor [1] (3x SCALE_TOLERANCE["acc"]).
ACC_SENSITIVITY = 1.15


def _model(a: np.ndarray) -> ThermalModel:
    """A degree-0 model with matrix a and zero bias."""
    return ThermalModel(True, 25.0, 1.0, 0, a, np.zeros((3, 0)), np.zeros((3, 1)))


def _identities() -> dict[str, ThermalModel]:
    return {t: ThermalModel.identity() for t in TRIAD_ORDER}


def _cross(angle_deg: float) -> np.ndarray:
    """Symmetric A with an xy cross-axis term of angle_deg."""
    a = np.eye(3)
    a[0, 1] = a[1, 0] = np.tan(np.deg2rad(angle_deg))
    return a


def test_an_identity_calibration_has_no_warning():
    assert fit_warnings(_identities(), settings_defaults()) == []


@pytest.mark.parametrize("triad", TRIAD_ORDER)
def test_a_gain_beyond_the_class_tolerance_is_a_warning_naming_the_axis(triad):
    models = _identities()
    models[triad] = _model(np.diag([1.0, 1.0 + 1.5 * SCALE_TOLERANCE[triad], 1.0]))
    warnings = fit_warnings(models, settings_defaults())
    assert len(warnings) == 1 and warnings[0].startswith(f"{triad}: warning: scale factor y")
    models[triad] = _model(np.diag([1.0, 1.0 + 0.5 * SCALE_TOLERANCE[triad], 1.0]))
    assert fit_warnings(models, settings_defaults()) == []


@pytest.mark.parametrize("triad", TRIAD_ORDER)
def test_a_misalignment_of_degrees_is_a_warning(triad):
    models = _identities()
    models[triad] = _model(_cross(1.5 * CROSS_AXIS_LIMIT_DEG[triad]))
    warnings = fit_warnings(models, settings_defaults())
    assert [w.split(" = ")[0] for w in warnings] == [f"{triad}: warning: misalignment xy", f"{triad}: warning: misalignment yx"]
    models[triad] = _model(_cross(0.5 * CROSS_AXIS_LIMIT_DEG[triad]))
    assert fit_warnings(models, settings_defaults()) == []


def test_a_triad_kept_at_the_identity_is_not_checked():
    models = _identities()
    models["gyr"] = replace(_model(np.diag([2.0, 2.0, 2.0])), enabled=False)
    assert fit_warnings(models, settings_defaults()) == []


def test_a_noise_density_outside_the_mems_class_is_a_warning_and_the_default_is_not_checked():
    lo, hi = GYRO_NOISE_CLASS
    settings = settings_defaults()
    assert noise_warnings(settings) == []
    for density, flagged in ((lo / 3, True), (np.sqrt(lo * hi), False), (hi * 3, True)):
        settings["gyro_noise"] = density
        assert bool(noise_warnings(settings)) == flagged, density


@pytest.fixture(scope="module")
def soaks():
    return simulate(load_scenario(SCENARIO))


def test_train_prints_an_out_of_class_accelerometer_gain_as_a_warning(soaks):
    scaled = replace(soaks, acc=soaks.acc * ACC_SENSITIVITY)
    art = train([scaled], seed=0, progress=False)
    assert abs(art.thermal["acc"].A[2, 2] - 1 / ACC_SENSITIVITY) < 0.01
    summary = summary_text(art, [scaled])
    assert "WARNINGS" in summary and "! acc: warning: scale factor z" in summary


def test_train_on_an_in_class_sensor_prints_no_gain_or_misalignment_warning(soaks):
    art = train([soaks], seed=0, progress=False)
    assert not [n for n in art.notes if "warning: scale factor" in n or "warning: misalignment" in n]


def test_summary_of_an_artefact_without_warnings_has_no_warning_block():
    art = ModelArtefact(seed=0, thermal=_identities(), settings=settings_defaults(), notes=["field_norm: 50 µT"])
    assert "WARNINGS" not in summary_text(art, [])
