"""Checks of a built ImuFusion FMU: model description, exported symbols, smoke co-simulation."""
from __future__ import annotations

import subprocess
import tempfile
import zipfile
from pathlib import Path

import fmpy
import numpy as np
from fmpy.validation import validate_fmu as fmpy_validate_fmu

from fmu.cosim import run_fmu
from fmu.model_description import MODEL_NAME
from training.errors import ImuFusionError
from training.layout import INPUTS, OUTPUTS

#: The 25 common and 9 co-simulation functions of FMI 2.0: exactly what the binary exports.
FMI2_CS_FUNCTIONS = frozenset({
    "fmi2GetTypesPlatform", "fmi2GetVersion", "fmi2SetDebugLogging", "fmi2Instantiate",
    "fmi2FreeInstance", "fmi2SetupExperiment", "fmi2EnterInitializationMode",
    "fmi2ExitInitializationMode", "fmi2Terminate", "fmi2Reset", "fmi2GetReal", "fmi2GetInteger",
    "fmi2GetBoolean", "fmi2GetString", "fmi2SetReal", "fmi2SetInteger", "fmi2SetBoolean",
    "fmi2SetString", "fmi2GetFMUstate", "fmi2SetFMUstate", "fmi2FreeFMUstate",
    "fmi2SerializedFMUstateSize", "fmi2SerializeFMUstate", "fmi2DeSerializeFMUstate",
    "fmi2GetDirectionalDerivative",
    "fmi2SetRealInputDerivatives", "fmi2GetRealOutputDerivatives", "fmi2DoStep", "fmi2CancelStep",
    "fmi2GetStatus", "fmi2GetRealStatus", "fmi2GetIntegerStatus", "fmi2GetBooleanStatus",
    "fmi2GetStringStatus",
})

#: Smoke test: 1 s at 100 Hz, sensor at rest and level in a 20/40 µT field.
_SMOKE_SAMPLES = 100
_SMOKE_RATE_HZ = 100.0


def binary_member() -> str:
    """Path of this platform's binary inside the FMU archive."""
    return f"binaries/{fmpy.platform}/{MODEL_NAME}{fmpy.sharedLibraryExtension}"


def exported_symbols(path: str | Path) -> set[str]:
    """Names of the functions and data the FMU's binary exports (`nm -D --defined-only`).

    path: an .fmu archive or a shared library. Raises ImuFusionError when the binary is missing
    or nm fails.
    """
    path = Path(path)
    with tempfile.TemporaryDirectory(prefix="imufusion-nm-") as tmp:
        library = path
        if zipfile.is_zipfile(path):
            with zipfile.ZipFile(path) as zf:
                if binary_member() not in zf.namelist():
                    raise ImuFusionError(f"{path}: no binary {binary_member()} in the FMU")
                library = Path(zf.extract(binary_member(), tmp))
        result = subprocess.run(["nm", "-D", "--defined-only", str(library)],
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if result.returncode != 0:
        raise ImuFusionError(f"nm failed on {path}:\n{result.stdout}")
    return {line.split()[-1] for line in result.stdout.splitlines() if line.strip()}


def _symbol_problems(path: Path) -> list[str]:
    """Problems with the exported symbol set (it must be exactly FMI2_CS_FUNCTIONS)."""
    try:
        symbols = exported_symbols(path)
    except ImuFusionError as e:
        return [str(e)]
    problems = []
    if symbols - FMI2_CS_FUNCTIONS:
        problems.append(f"the binary exports non-FMI symbols: {', '.join(sorted(symbols - FMI2_CS_FUNCTIONS))}")
    if FMI2_CS_FUNCTIONS - symbols:
        problems.append(f"the binary lacks FMI functions: {', '.join(sorted(FMI2_CS_FUNCTIONS - symbols))}")
    return problems


def _smoke_problems(path: Path) -> list[str]:
    """Problems of a short co-simulation at rest: it must run and give finite outputs."""
    t = np.arange(_SMOKE_SAMPLES) / _SMOKE_RATE_HZ
    sample = dict(zip(INPUTS, (0.0, 0.0, 0.0, 0.0, 0.0, -9.80665, 20.0, 0.0, 40.0, 25.0)))
    inputs = np.tile([sample[name] for name in INPUTS], (t.size, 1))
    try:
        outputs = run_fmu(path, t, inputs)
    except Exception as e:
        return [f"smoke co-simulation failed: {e}"]
    bad = [OUTPUTS[j] for j in range(len(OUTPUTS)) if not np.all(np.isfinite(outputs[:, j]))]
    return [f"smoke co-simulation gave non-finite outputs: {', '.join(bad)}"] if bad else []


def validate_fmu(path: str | Path) -> list[str]:
    """Every problem found in the FMU at path (empty list = valid).

    Checks fmpy's model-description validation (schema, names, model structure, units), that the
    binary exports exactly the 34 FMI 2.0 co-simulation functions, and a 1 s smoke co-simulation.
    """
    path = Path(path)
    if not zipfile.is_zipfile(path):
        return [f"{path}: not an FMU (an FMU is a zip archive)"]
    problems = list(fmpy_validate_fmu(str(path)))
    problems += _symbol_problems(path)
    if not problems:
        problems += _smoke_problems(path)
    return problems
