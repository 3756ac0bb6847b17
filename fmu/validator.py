"""Checks of a built ImuFusion FMU (FMI 2 or 3): model description, exported symbols, smoke
co-simulation and the shipped reference result."""
from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

import fmpy
import numpy as np
from fmpy.validation import validate_fmu as fmpy_validate_fmu

from fmu.archive import FmuArchiveError, read_description
from fmu.compiler import binary_path
from fmu.cosim import run_fmu
from fmu.description_check import behaviour_problems, description_problems
from fmu.model_description import MODEL_NAME
from fmu.packer import REFERENCE_INPUT, REFERENCE_OUTPUT, read_reference_csv
from training.errors import ImuFusionError, one_line
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

#: Every FMI 3.0 function (fmi3Functions.h): exactly what the FMI 3 binary exports.
FMI3_FUNCTIONS = frozenset({
    "fmi3GetVersion", "fmi3SetDebugLogging", "fmi3InstantiateModelExchange",
    "fmi3InstantiateCoSimulation", "fmi3InstantiateScheduledExecution", "fmi3FreeInstance",
    "fmi3EnterInitializationMode", "fmi3ExitInitializationMode", "fmi3EnterEventMode", "fmi3Terminate",
    "fmi3Reset", "fmi3GetFloat32", "fmi3GetFloat64", "fmi3GetInt8", "fmi3GetUInt8", "fmi3GetInt16",
    "fmi3GetUInt16", "fmi3GetInt32", "fmi3GetUInt32", "fmi3GetInt64", "fmi3GetUInt64", "fmi3GetBoolean",
    "fmi3GetString", "fmi3GetBinary", "fmi3GetClock", "fmi3SetFloat32", "fmi3SetFloat64", "fmi3SetInt8",
    "fmi3SetUInt8", "fmi3SetInt16", "fmi3SetUInt16", "fmi3SetInt32", "fmi3SetUInt32", "fmi3SetInt64",
    "fmi3SetUInt64", "fmi3SetBoolean", "fmi3SetString", "fmi3SetBinary", "fmi3SetClock",
    "fmi3GetNumberOfVariableDependencies", "fmi3GetVariableDependencies", "fmi3GetFMUState",
    "fmi3SetFMUState", "fmi3FreeFMUState", "fmi3SerializedFMUStateSize", "fmi3SerializeFMUState",
    "fmi3DeserializeFMUState", "fmi3GetDirectionalDerivative", "fmi3GetAdjointDerivative",
    "fmi3EnterConfigurationMode", "fmi3ExitConfigurationMode", "fmi3GetIntervalDecimal",
    "fmi3GetIntervalFraction", "fmi3GetShiftDecimal", "fmi3GetShiftFraction", "fmi3SetIntervalDecimal",
    "fmi3SetIntervalFraction", "fmi3SetShiftDecimal", "fmi3SetShiftFraction", "fmi3EvaluateDiscreteStates",
    "fmi3UpdateDiscreteStates", "fmi3EnterContinuousTimeMode", "fmi3CompletedIntegratorStep", "fmi3SetTime",
    "fmi3SetContinuousStates", "fmi3GetContinuousStateDerivatives", "fmi3GetEventIndicators",
    "fmi3GetContinuousStates", "fmi3GetNominalsOfContinuousStates", "fmi3GetNumberOfEventIndicators",
    "fmi3GetNumberOfContinuousStates", "fmi3EnterStepMode", "fmi3GetOutputDerivatives", "fmi3DoStep",
    "fmi3ActivateModelPartition",
})

#: The exported function set of each FMI version.
EXPORTED_FUNCTIONS = {2: FMI2_CS_FUNCTIONS, 3: FMI3_FUNCTIONS}

#: The FMU reproduces its reference output to this bound: FMU (fmpy's CMake, -O3) and batch
#: library (-O2) compile the same C code; only instruction choice may differ.
REFERENCE_TOLERANCE = 1e-12

#: Smoke test: 1 s at 100 Hz, sensor at rest and level in a 20/40 µT field.
_SMOKE_SAMPLES = 100
_SMOKE_RATE_HZ = 100.0


def fmi_version_of(path: str | Path) -> int:
    """2 or 3: the FMI version of the FMU at path (from its modelDescription.xml)."""
    return int(fmpy.read_model_description(str(path), validate=False).fmiVersion[0])


def binary_member(fmi_version: int = 2) -> str:
    """Path of this platform's binary inside an FMI `fmi_version` FMU archive."""
    return binary_path(Path(), MODEL_NAME, fmi_version).as_posix()


def exported_symbols(path: str | Path) -> set[str]:
    """Names of the functions and data the FMU's binary exports (`nm -D --defined-only`).

    path: an .fmu archive or a shared library. Raises ImuFusionError when the binary is missing
    or nm fails.
    """
    path = Path(path)
    with tempfile.TemporaryDirectory(prefix="imufusion-nm-") as tmp:
        library = path
        if zipfile.is_zipfile(path):
            member = binary_member(fmi_version_of(path))
            with zipfile.ZipFile(path) as zf:
                if member not in zf.namelist():
                    raise ImuFusionError(f"{path}: no binary {member} in the FMU")
                library = Path(zf.extract(member, tmp))
        result = subprocess.run(["nm", "-D", "--defined-only", str(library)],
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if result.returncode != 0:
        raise ImuFusionError(f"nm failed on {path}: {one_line(result.stdout)}")
    return {line.split()[-1] for line in result.stdout.splitlines() if line.strip()}


def _symbol_problems(path: Path, fmi_version: int) -> list[str]:
    """Problems with the exported symbol set (it must be exactly EXPORTED_FUNCTIONS[fmi_version])."""
    try:
        symbols = exported_symbols(path)
    except ImuFusionError as e:
        return [str(e)]
    expected = EXPORTED_FUNCTIONS[fmi_version]
    problems = []
    if symbols - expected:
        problems.append(f"the binary exports non-FMI symbols: {', '.join(sorted(symbols - expected))}")
    if expected - symbols:
        problems.append(f"the binary lacks FMI functions: {', '.join(sorted(expected - symbols))}")
    return problems


def fmutool_problems(path: str | Path) -> list[str]:
    """Problems that fmu-manipulation-toolbox's static checker (`fmutool -input FMU -check`)
    reports: its conformity and semantic checks must both pass without an error or warning line."""
    tool = shutil.which("fmutool", path=str(Path(sys.executable).parent)) or shutil.which("fmutool")
    if tool is None:
        return ["fmutool (package fmu-manipulation-toolbox) is not installed"]
    result = subprocess.run([tool, "-input", str(path), "-check"], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    report = result.stdout
    version = fmi_version_of(path)
    passed = (f"compliant with FMI-{version}.0" in report and f"No semantic error against the FMI-{version}" in report
              and result.returncode == 0)
    bad_lines = [line for line in report.splitlines() if line.startswith(("ERROR", "WARNING"))]
    return [] if passed and not bad_lines else [f"fmutool -check reported problems: {one_line(report)}"]


def reference_problems(path: str | Path) -> list[str]:
    """Problems reproducing the shipped reference: the FMU run on extra/.../reference_input.csv
    must give reference_output.csv within REFERENCE_TOLERANCE."""
    try:
        with zipfile.ZipFile(path) as zf:
            in_names, inputs = read_reference_csv(zf.read(REFERENCE_INPUT).decode())
            out_names, expected = read_reference_csv(zf.read(REFERENCE_OUTPUT).decode())
    except (KeyError, ValueError) as e:
        return [f"the FMU's reference result is missing or malformed: {e}"]
    if in_names != ("t", *INPUTS) or out_names != ("t", *OUTPUTS):
        return ["the reference CSV columns do not match the FMU's inputs and outputs"]
    try:
        outputs = run_fmu(path, inputs[:, 0], inputs[:, 1:])
    except Exception as e:
        return [f"co-simulating the reference input failed: {e}"]
    error = float(np.max(np.abs(outputs - expected[:, 1:])))
    if not error <= REFERENCE_TOLERANCE:
        return [f"the FMU does not reproduce its reference output: max difference {error:g} > {REFERENCE_TOLERANCE:g}"]
    return []


def _smoke_problems(path: Path) -> list[str]:
    """Problems of a short co-simulation at rest: it must run and give finite outputs."""
    t = np.arange(_SMOKE_SAMPLES) / _SMOKE_RATE_HZ
    sample = {"acc_z": -9.80665, "mag_x": 20.0, "mag_z": 40.0, "temp": 25.0}  # auxiliary inputs 0
    inputs = np.tile([sample.get(name, 0.0) for name in INPUTS], (t.size, 1))
    try:
        outputs = run_fmu(path, t, inputs)
    except Exception as e:
        return [f"smoke co-simulation failed: {e}"]
    bad = [OUTPUTS[j] for j in range(len(OUTPUTS)) if not np.all(np.isfinite(outputs[:, j]))]
    return [f"smoke co-simulation gave non-finite outputs: {', '.join(bad)}"] if bad else []


#: The checks of `validate_fmu` in the order they run (a failed check skips those after it).
VALIDATION_CHECKS = ("archive", "fmpy model description", "description matches sources", "exported symbols",
                     "fmutool -check", "smoke co-simulation", "description matches binary", "reference result")


def validate_fmu(path: str | Path, checks: list[tuple[str, int]] | None = None) -> list[str]:
    """Every problem found in the FMU (FMI 2 or 3) at path (empty list = valid); `checks`, when
    given, receives (name in VALIDATION_CHECKS, number of problems) for every check that ran.

    First the archive itself (fmu.archive: a zip within the size caps, safe member names, a
    well-formed modelDescription.xml, the binary present); then fmpy's model-description validation
    (schema, names, model structure, units), that the binary exports exactly the 34 FMI 2.0 co-simulation functions or all 75 FMI 3.0 functions,
    fmutool's static check (fmu-manipulation-toolbox), a
    1 s smoke co-simulation, and that the FMU reproduces its shipped reference result.
    fmu.description_check compares the model description with the variable table and the
    archive's sources right after fmpy's validation, and with the binary (the start values it
    holds, corrected triad outputs that follow their inputs) after the smoke co-simulation.
    """
    path = Path(path)
    ran = [] if checks is None else checks

    def counted(name: str, found: list[str]) -> list[str]:
        ran.append((name, len(found)))
        return found
    try:
        read_description(path)
    except FmuArchiveError as e:
        return counted("archive", [str(e)])
    counted("archive", [])
    problems = counted("fmpy model description", [one_line(p) for p in fmpy_validate_fmu(str(path))])
    if problems:
        return problems
    problems += counted("description matches sources", description_problems(path))
    problems += counted("exported symbols", _symbol_problems(path, fmi_version_of(path)))
    problems += counted("fmutool -check", fmutool_problems(path))
    if not problems:
        problems += counted("smoke co-simulation", _smoke_problems(path))
    if not problems:
        problems += counted("description matches binary", behaviour_problems(path))
    if not problems:
        problems += counted("reference result", reference_problems(path))
    return problems
