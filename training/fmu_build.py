"""Build the FMU of a model: run the model on the FMU's built-in reference recording through the
batch runtime (the same C code), then hand coefficients, settings and those reference outputs to
the packer (fmu.packer.pack_fmu), which knows no model."""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np

from contract.errors import BuildError, ModelError
from contract.layout import identity_coefficients, settings_array
from fmu.calibration_file import read_calibration
from fmu.packer import pack_fmu, reference_recording
from fmu.prebuilt import missing_tools, prebuilt_file, write_manifest
from fmu.references import with_parameter_sets
from training.artefact import coefficients_array, load_artefact, settings_dict
from training.runtime import build_runtime, compiler_command, run_batch

#: What the generic FMU says it is (its provenance).
GENERIC = ("generic: no calibration compiled in; set a unit's calibration.ssv as its parameters "
           "(imufmu run --calibration)")


def reference_outputs(coefficients: np.ndarray, settings: dict[str, float]) -> np.ndarray:
    """(N, len(OUTPUTS)) batch-runtime outputs on fmu.packer.reference_recording() with these
    coefficients and parameter values (missing names take the defaults)."""
    t, inputs = reference_recording()
    try:
        values = settings_array(settings)
    except KeyError as e:
        raise ModelError(e.args[0]) from None
    try:
        return run_batch(coefficients, values, t, inputs)
    except ValueError as e:
        raise ModelError(f"cannot compute the reference result: {e}") from e


def build_fmu(coefficients: np.ndarray, settings: dict, out_path: str | Path, **packing) -> Path:
    """Build ImuFusion.fmu at out_path and return its path: fmu.packer.pack_fmu with the model's
    reference outputs; `packing` are pack_fmu's keyword arguments (fmi_version, description,
    provenance, aux_inputs, training_data, notes)."""
    coefficients = np.asarray(coefficients, dtype=float)
    return pack_fmu(coefficients, settings, out_path, reference_outputs(coefficients, settings), **packing)


def build_fmu_from_model(model_path: str | Path | None, out_path: str | Path, fmi_version: int = 2,
                         variants: dict[str, Path] | None = None) -> Path:
    """`imufmu build-fmu`: the FMU of the trained artefact at `model_path` (its coefficients,
    settings, auxiliary inputs, training data and notes) at `out_path`; returns its path. Without a
    model, the generic FMU: no calibration compiled in (identity coefficients, default settings), a unit's
    set at run time from its calibration.ssv (docs/fmu.md, "The calibration as parameters"). `variants`:
    label -> a unit's calibration.ssv, each checked to fit the layout (fmu.calibration_file.read_calibration)
    and embedded as a parameter set (fmu.references).
    Without a C compiler (or CMake) on PATH the generic FMU is the prebuilt one (fmu.prebuilt) with the
    variants added; a trained FMU then cannot be built (BuildError saying how to run the unit instead)."""
    sets = {}
    for label, path in (variants or {}).items():
        read_calibration(path)
        sets[label] = Path(path).read_bytes()
    missing = missing_tools("cmake", compiler_command()[0])
    if missing and model_path is None:
        prebuilt = prebuilt_file(f"fmi{fmi_version}", f"'{missing[0]}' is not on PATH")
        return with_parameter_sets(prebuilt, sets, out_path)
    if missing:
        raise BuildError(f"compiling the FMU of {model_path} needs a C compiler and CMake ('{missing[0]}' is not on "
                         "PATH); without them, run the generic FMU with the unit's calibration: `imufmu build-fmu "
                         "--out G.fmu --variant unit=DIR/calibration.ssv` (prebuilt) and `imufmu run G.fmu DATA "
                         "--variant unit`")
    if model_path is None:
        return build_fmu(np.array(identity_coefficients()), {}, out_path, fmi_version=fmi_version, variants=sets,
                         provenance=GENERIC)
    artefact = load_artefact(model_path)
    return build_fmu(coefficients_array(artefact), settings_dict(artefact), out_path,
                     provenance=f"model {model_path}", fmi_version=fmi_version,
                     aux_inputs=artefact.aux_inputs, training_data=artefact.training_data,
                     notes=artefact.notes, variants=sets)


def build_prebuilt(folder: str | Path) -> dict[str, Path]:
    """`imufmu prebuild`: compile the runtime library and the generic FMU of FMI 2 and 3 into `folder` with
    their manifest (fmu.prebuilt); returns kind -> path. Needs the compiler it spares the user."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths = {"runtime": Path(shutil.copyfile(build_runtime(), folder / "libimufusion.so"))}
    for version in (2, 3):
        paths[f"fmi{version}"] = build_fmu(np.array(identity_coefficients()), {}, folder / f"ImuFusion-fmi{version}.fmu",
                                           fmi_version=version, provenance=GENERIC)
    write_manifest(folder, {kind: path.name for kind, path in paths.items()})
    return paths
