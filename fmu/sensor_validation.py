"""Checks of a built virtual-sensor FMU (ImuSensor; fmu.validator runs them after fmpy's validation): its model
description against its variable table (contract/sensor_variables.py) and the archive's sources/config.h, a
smoke co-simulation at rest, and the start values the initialised binary holds."""
from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np

from contract.errors import ImuFusionError, one_line
from contract.sensor_variables import SENSOR_VARIABLES
from fmu.archive import read_description
from fmu.cosim import initialised_fmu, run_named
from fmu.description_check import (CONFIG_MEMBER, _start_problems, compare, config_variables, described_variables,
                                   table_attributes)

#: How a problem line names the sensor's variable table.
TABLE = "the sensor's variable table (contract/sensor_variables.py)"
#: The raw outputs the smoke run reads.
RAW_OUTPUTS = tuple(v.name for v in SENSOR_VARIABLES if v.causality == "output")
#: Smoke run: 1 s at 100 Hz at rest.
_SMOKE_SAMPLES, _SMOKE_RATE_HZ = 100, 100.0


def sensor_description_problems(path: str | Path) -> list[str]:
    """Every mismatch between the sensor FMU's model description and its variable table and sources/config.h."""
    try:
        description = read_description(path)
        with zipfile.ZipFile(path) as zf:
            config = zf.read(CONFIG_MEMBER).decode()
    except (ImuFusionError, KeyError, UnicodeDecodeError, zipfile.BadZipFile) as e:
        return [f"{path}: cannot read the FMU's sources to check its model description ({one_line(str(e))})"]
    fmi_version = 3 if description.fmiVersion.startswith("3") else 2
    return compare(described_variables(description),
                   {TABLE: table_attributes(SENSOR_VARIABLES, fmi_version), CONFIG_MEMBER: config_variables(config, fmi_version)})


def sensor_smoke_problems(path: str | Path) -> list[str]:
    """Problems of 1 s at rest and level through the sensor: it must run and give finite raw outputs."""
    t = np.arange(_SMOKE_SAMPLES) / _SMOKE_RATE_HZ
    rest = {"true_accel_z": np.full(t.size, -9.80665), "true_q_w": np.ones(t.size), "true_temp": np.full(t.size, 25.0)}
    try:
        raw = run_named(path, t, rest, RAW_OUTPUTS)
    except Exception as e:  # what the FMU raised is the problem to report
        return [f"smoke co-simulation failed: {one_line(str(e))}"]
    bad = [name for j, name in enumerate(RAW_OUTPUTS) if not np.all(np.isfinite(raw[:, j]))]
    return [f"smoke co-simulation gave non-finite outputs: {', '.join(bad)}"] if bad else []


def sensor_behaviour_problems(path: str | Path) -> list[str]:
    """Inputs and parameters whose value in the freshly initialised binary is not the declared start value."""
    try:
        described = described_variables(read_description(path))
        with initialised_fmu(path, instance_name="ImuSensor") as fmu:
            return _start_problems(fmu, described)
    except ImuFusionError as e:
        return [f"{path}: running the FMU to check its model description failed: {one_line(str(e))}"]
