"""The diagnosis works in the sensor axes whatever the model's mounting (issue 35's z-up boards): the
recording's references are in the sensor axes, and the FMU applies its correction terms before it turns
the triads into the body axes (sources/ImuPipeline.c). Diagnosed in the body axes, a z-up model's terms
were fitted in one frame and applied in the other (x-io with an injected motor current: the field norm
5.6 → 13.0 µT with the current's terms instead of 0.93 µT)."""
from __future__ import annotations

import numpy as np

from contract.layout import TRIAD_ORDER, settings_defaults
from contract.mounting import IDENTITY, MOUNT_SETTINGS, Z_UP
from training.artefact import ModelArtefact
from training.diagnosis.diagnose import residuals, targets_of
from training.main_job import SCENARIO_DIR
from training.models.thermal import ThermalModel
from training.simulator import load_scenario, simulate


def _model(codes) -> ModelArtefact:
    return ModelArtefact(seed=0, thermal={k: ThermalModel.identity(enabled=False) for k in TRIAD_ORDER},
                         settings={**settings_defaults(), **dict(zip(MOUNT_SETTINGS, map(float, codes)))}, notes=[])


def test_a_z_up_mounting_changes_nothing_the_diagnosis_sees():
    data = simulate(load_scenario(SCENARIO_DIR / "variants" / "diag_effects.toml"))
    targets = {**targets_of(data), "mag_norm": "norm"}
    sensor, z_up = (residuals(_model(codes), [data], targets) for codes in (IDENTITY, Z_UP))
    for target in targets:
        assert np.allclose(z_up.residual[target], sensor.residual[target], atol=1e-12, equal_nan=True), target
    for name in ("gyr_x", "gyr_y", "acc_z", "mag_y", "abs_gyr_z"):
        assert np.allclose(z_up.signals[name], sensor.signals[name], atol=1e-12, equal_nan=True), name
