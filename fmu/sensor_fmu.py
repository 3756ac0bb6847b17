"""The virtual-sensor FMU (ImuSensor, docs/virtual_sensor.md): the trained chain compiled in and run
backwards (sources/ImuSensor.c) plus the noise as parameters, packed from the same source tree as the
ImuFusion FMU with the sensor's model files (sources/sensor/) staged in place of ImuFusion's."""
from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import numpy as np

from contract.errors import ModelError
from contract.sensor_variables import MODEL_NAME, SENSOR_VARIABLES, sensor_parameters
from fmu.build_description import BUILD_DESCRIPTION, build_description_xml
from fmu.compiler import SOURCE_DIR, check_fmi_version, fmu_source_files
from fmu.header import HEADER_NAME, coefficient_header
from fmu.model_description import DEFAULT_EXPERIMENT, description_xml
from fmu.packer import _zip_directory, compile_binaries, model_guid
from fmu.provenance import build_time

#: The sensor's own model files, staged in place of the ImuFusion files of the same name (model.c: the
#: ImuFusion model, replaced by SensorModel.c).
SENSOR_DIR = SOURCE_DIR / "sensor"
REPLACED = frozenset({"model.c", "config.h", "ModelData.h"})

DESCRIPTION = ("Virtual sensor: what the calibrated IMU and magnetometer output for a true motion (the trained "
               "corrections run backwards) with its characterised noise")


def sensor_source_files(fmi_version: int) -> list[Path]:
    """The .c and .h files of the sensor FMU: the shared runtime and core, and sources/sensor/'s."""
    shared = [p for p in fmu_source_files(fmi_version=fmi_version) if p.name not in REPLACED]
    return sorted(shared + sorted(SENSOR_DIR.glob("*.[ch]")), key=lambda p: p.name)


def sensor_values(overrides: dict[str, float]) -> dict[str, float]:
    """Every sensor parameter by name: its default, overridden by `overrides`; ModelError for an unknown name
    or a value outside the declared range."""
    values = {v.name: float(v.default) for v in sensor_parameters()}
    for name, value in overrides.items():
        if name not in values:
            raise ModelError(f"unknown virtual-sensor parameter '{name}'")
        r = next(v.range for v in sensor_parameters() if v.name == name)
        if not (r.min <= float(value) <= r.max):
            raise ModelError(f"virtual-sensor parameter {name} = {value:g} is outside [{r.min:g}, {r.max:g}] {r.unit or ''}")
        values[name] = float(value)
    return values


def pack_sensor_fmu(coefficients: np.ndarray, chain_settings: dict, parameters: dict[str, float],
                    out_path: str | Path, fmi_version: int = 2, provenance: str = "", rate_hz: float | None = None) -> Path:
    """Build ImuSensor.fmu at out_path: the trained chain (`coefficients`, the ImuFusion `chain_settings` by name)
    compiled in, `parameters` the sensor's start values by name (sensor_values), the default experiment's step
    1 / rate_hz. Raises ModelError for bad values, BuildError when compilation fails."""
    out_path = Path(out_path)
    check_fmi_version(fmi_version)
    values = sensor_values(parameters)
    sources = sensor_source_files(fmi_version)
    guid = model_guid(coefficients, {**chain_settings, **{f"sensor.{k}": v for k, v in values.items()}}, sources,
                      SENSOR_VARIABLES)
    c_files = [p.name for p in sources if p.suffix == ".c"]
    experiment = dict(DEFAULT_EXPERIMENT, **({"stepSize": 1.0 / rate_hz} if rate_hz else {}))
    files = {"modelDescription.xml": description_xml(MODEL_NAME, SENSOR_VARIABLES, values, guid,
                                                     f"{DESCRIPTION}. {provenance}".strip(), c_files, fmi_version,
                                                     build_time(), [], experiment),
             f"sources/{HEADER_NAME}": coefficient_header(coefficients, chain_settings, guid, provenance)}
    if fmi_version == 3:
        files[BUILD_DESCRIPTION] = build_description_xml(c_files, MODEL_NAME)
    with tempfile.TemporaryDirectory(prefix="imusensor-fmu-") as tmp:
        stage = Path(tmp)
        (stage / "sources").mkdir()
        for path in sources:
            shutil.copyfile(path, stage / "sources" / path.name)
        for name, content in files.items():
            (stage / name).parent.mkdir(parents=True, exist_ok=True)
            (stage / name).write_text(content)
        compile_binaries(stage, out_path)
        out_path.parent.mkdir(parents=True, exist_ok=True)
        partial = out_path.with_name(out_path.name + ".partial")
        _zip_directory(stage, partial)
        partial.replace(out_path)
    return out_path
