"""Checks of a built ImuFusion FMU (FMI 2 or 3): model description, the exported symbols of every
binary it carries (and the DLLs the win64 one imports), smoke co-simulation and the shipped
reference result."""
from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

import fmpy
import numpy as np
from elftools.common.exceptions import ELFError
from elftools.elf.elffile import ELFFile
from fmpy.validation import validate_fmu as fmpy_validate_fmu

from fmu.archive import FmuArchiveError, read_description
from fmu.compiler import WIN64_PLATFORMS, binary_path, win64_binary_path
from fmu.cosim import run_fmu
from fmu.description_check import behaviour_problems, description_problems
from fmu.model_description import MODEL_NAME
from fmu.sensor_validation import sensor_behaviour_problems, sensor_description_problems, sensor_smoke_problems
from contract.sensor_variables import MODEL_NAME as SENSOR_MODEL_NAME
from fmu.packer import REFERENCE_INPUT, REFERENCE_OUTPUT, read_reference_csv
from fmu.pe import MACHINE_AMD64, PeImage, read_pe
from fmu.references import embedded_problems
from contract.errors import ImuFusionError, one_line
from contract.layout import INPUTS, OUTPUTS

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

#: The DLLs (lower case) the win64 binary may import besides the api-ms-win-* API sets: the
#: kernel and the C runtime (msvcrt, or the Universal CRT's ucrtbase) that every Windows has.
WINDOWS_SYSTEM_DLLS = frozenset({"kernel32.dll", "msvcrt.dll", "ucrtbase.dll"})

#: The FMU reproduces its reference output to this bound: FMU (fmpy's CMake) and batch library
#: compile the same C code, both at -O3 but with other flags; only instruction choice may differ.
REFERENCE_TOLERANCE = 1e-12

#: Smoke test: 1 s at 100 Hz, sensor at rest and level in a 20/40 µT field.
_SMOKE_SAMPLES = 100
_SMOKE_RATE_HZ = 100.0


def fmi_version_of(path: str | Path) -> int:
    """2 or 3: the FMI version of the FMU at path (from its modelDescription.xml)."""
    return int(fmpy.read_model_description(str(path), validate=False).fmiVersion[0])


def model_identifier_of(path: str | Path) -> str:
    """The co-simulation model identifier of the FMU at path (ImuFusion, or ImuSensor for the virtual sensor)."""
    return fmpy.read_model_description(str(path), validate=False).coSimulation.modelIdentifier


def binary_member(fmi_version: int = 2, model_name: str = MODEL_NAME) -> str:
    """Path of this platform's binary inside an FMI `fmi_version` FMU archive."""
    return binary_path(Path(), model_name, fmi_version).as_posix()


def binary_members(fmi_version: int = 2, model_name: str = MODEL_NAME) -> dict[str, str]:
    """Path inside an FMI `fmi_version` FMU archive of each binary the packer builds, by platform
    folder name: this platform's (linux64 / x86_64-linux) and the Windows one (win64 /
    x86_64-windows)."""
    here = binary_path(Path(), model_name, fmi_version)
    windows = win64_binary_path(Path(), model_name, fmi_version)
    return {here.parent.name: here.as_posix(), windows.parent.name: windows.as_posix()}


def _library(path: Path, platform: str | None, tmp: str) -> Path:
    """The library file to read: path itself, or (path an .fmu archive) its binary for the
    platform folder `platform` (default this platform's) extracted into tmp; ImuFusionError when
    the FMU lacks it."""
    if not zipfile.is_zipfile(path):
        return path
    version, name = fmi_version_of(path), model_identifier_of(path)
    members = binary_members(version, name)
    if platform is not None and platform not in members:
        raise ImuFusionError(f"no binary check for platform {platform!r} (known: {', '.join(members)})")
    member = binary_member(version, name) if platform is None else members[platform]
    with zipfile.ZipFile(path) as zf:
        if member not in zf.namelist():
            raise ImuFusionError(f"{path}: no binary {member} in the FMU")
        return Path(zf.extract(member, tmp))


def _read_windows_image(library: Path) -> PeImage:
    """The PE header, export and import tables of the .dll at `library`; ImuFusionError when it
    is not a PE image."""
    try:
        return read_pe(library.read_bytes())
    except ValueError as e:
        raise ImuFusionError(f"{library.name} is not a readable Windows DLL: {e}") from e


def _library_exports(library: Path) -> set[str]:
    """What the library exports: a .dll's export name table (fmu.pe), else the defined symbols of the ELF
    image's dynamic symbol table (pyelftools; what `nm -D --defined-only` lists, without binutils)."""
    if library.suffix == ".dll":
        return set(_read_windows_image(library).exports)
    try:
        with library.open("rb") as f:
            table = ELFFile(f).get_section_by_name(".dynsym")
            if table is None:
                raise ELFError("no dynamic symbol table")
            return {s.name for s in table.iter_symbols() if s.name and s["st_shndx"] != "SHN_UNDEF"}
    except ELFError as e:
        raise ImuFusionError(f"{library.name} is not a readable ELF shared library: {one_line(str(e))}") from e


def exported_symbols(path: str | Path, platform: str | None = None) -> set[str]:
    """Names of the functions and data the FMU's binary exports.

    path: an .fmu archive (its binary for the platform folder `platform`, e.g. 'win64'; default
    this platform's) or a library (.dll read as a PE image, anything else with nm). Raises
    ImuFusionError when the binary is missing or unreadable.
    """
    with tempfile.TemporaryDirectory(prefix="imufusion-nm-") as tmp:
        return _library_exports(_library(Path(path), platform, tmp))


def windows_image(path: str | Path, platform: str = WIN64_PLATFORMS[2]) -> PeImage:
    """Machine type, exports and imported DLLs of the FMU's Windows binary (platform folder
    `platform`; path an .fmu or a .dll); ImuFusionError when it is missing or not a PE image."""
    with tempfile.TemporaryDirectory(prefix="imufusion-pe-") as tmp:
        return _read_windows_image(_library(Path(path), platform, tmp))


def is_windows_system_dll(name: str) -> bool:
    """True for a DLL every Windows installation has: WINDOWS_SYSTEM_DLLS or an api-ms-win-* API set."""
    return name.lower() in WINDOWS_SYSTEM_DLLS or name.lower().startswith("api-ms-win-")


def _export_problems(symbols: set[str], fmi_version: int) -> list[str]:
    """Problems with an exported symbol set (it must be exactly EXPORTED_FUNCTIONS[fmi_version])."""
    expected = EXPORTED_FUNCTIONS[fmi_version]
    problems = []
    if symbols - expected:
        problems.append(f"exports non-FMI symbols: {', '.join(sorted(symbols - expected))}")
    if expected - symbols:
        problems.append(f"lacks FMI functions: {', '.join(sorted(expected - symbols))}")
    return problems


def _windows_problems(image: PeImage) -> list[str]:
    """Problems of a Windows binary beyond its exports: it must be an x86-64 image that imports
    only Windows system DLLs (no mingw runtime such as libgcc_s or libwinpthread)."""
    problems = [] if image.machine == MACHINE_AMD64 else [f"is not an x86-64 image (machine {image.machine:#x})"]
    foreign = [name for name in image.imports if not is_windows_system_dll(name)]
    if foreign:
        problems.append(f"imports DLLs that Windows does not have: {', '.join(foreign)}")
    return problems


def _library_problems(library: Path, fmi_version: int) -> list[str]:
    """Problems of one binary: it exports exactly EXPORTED_FUNCTIONS[fmi_version]; a .dll also
    passes `_windows_problems`."""
    try:
        problems = _export_problems(_library_exports(library), fmi_version)
        if library.suffix == ".dll":
            problems += _windows_problems(_read_windows_image(library))
    except ImuFusionError as e:
        return [str(e)]
    return problems


def _symbol_problems(path: Path, fmi_version: int) -> list[str]:
    """Problems of every binary the FMU carries among binary_members (this platform's is
    required by the archive check, the win64 one is there when it was cross-compiled), each
    problem prefixed with the binary's member name and so its platform."""
    problems = []
    with tempfile.TemporaryDirectory(prefix="imufusion-binaries-") as tmp, zipfile.ZipFile(path) as zf:
        present = set(zf.namelist())
        for member in binary_members(fmi_version, model_identifier_of(path)).values():
            if member in present:
                problems += [f"{member}: {p}" for p in _library_problems(Path(zf.extract(member, tmp)), fmi_version)]
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
VALIDATION_CHECKS = ("archive", "fmpy model description", "description matches sources", "parameter sets", "binaries",
                     "fmutool -check", "smoke co-simulation", "description matches binary", "reference result")


#: The checks of a virtual-sensor FMU (`_sensor_checks`), in the order they run.
SENSOR_VALIDATION_CHECKS = ("archive", "fmpy model description", "description matches sources", "binaries",
                            "fmutool -check", "smoke co-simulation", "description matches binary")


def validation_checks(path: str | Path) -> tuple[str, ...]:
    """The checks `validate_fmu` runs on the FMU at path: the virtual sensor's or ImuFusion's."""
    try:
        return SENSOR_VALIDATION_CHECKS if model_identifier_of(path) == SENSOR_MODEL_NAME else VALIDATION_CHECKS
    except Exception:  # an unreadable archive: the archive check reports it
        return VALIDATION_CHECKS


def _sensor_checks(path: Path, counted) -> list[str]:
    """The checks of the virtual-sensor FMU after fmpy's validation (fmu.sensor_validation: its description
    against its variable table and sources, then as for ImuFusion: binaries, fmutool, a smoke co-simulation
    and the start values the binary holds)."""
    problems = counted("description matches sources", sensor_description_problems(path))
    problems += counted("binaries", _symbol_problems(path, fmi_version_of(path)))
    problems += counted("fmutool -check", fmutool_problems(path))
    if not problems:
        problems += counted("smoke co-simulation", sensor_smoke_problems(path))
    if not problems:
        problems += counted("description matches binary", sensor_behaviour_problems(path))
    return problems


def validate_fmu(path: str | Path, checks: list[tuple[str, int]] | None = None) -> list[str]:
    """Every problem found in the FMU (FMI 2 or 3) at path (empty list = valid); `checks`, when
    given, receives (name in VALIDATION_CHECKS, number of problems) for every check that ran. A virtual-sensor
    FMU (model identifier ImuSensor) gets the checks that apply to it (`_sensor_checks`).

    First the archive itself (fmu.archive: a zip within the size caps, safe member names, a
    well-formed modelDescription.xml, this platform's binary present); then fmpy's model-description
    validation (schema, names, model structure, units), that every binary the FMU carries (this
    platform's and win64) exports exactly the 34 FMI 2.0 co-simulation functions or all 75 FMI 3.0
    functions and that the win64 one imports only Windows system DLLs (`_symbol_problems`),
    fmutool's static check (fmu-manipulation-toolbox), a
    1 s smoke co-simulation, and that the FMU reproduces its shipped reference result.
    fmu.description_check compares the model description with the variable table and the
    archive's sources right after fmpy's validation (then every embedded parameter set is checked against
    the model description and the layout, fmu.references), and with the binary (the start values it
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
    if model_identifier_of(path) == SENSOR_MODEL_NAME:
        return problems + _sensor_checks(path, counted)
    problems += counted("description matches sources", description_problems(path))
    problems += counted("parameter sets", embedded_problems(path, read_description(path)))
    problems += counted("binaries", _symbol_problems(path, fmi_version_of(path)))
    problems += counted("fmutool -check", fmutool_problems(path))
    if not problems:
        problems += counted("smoke co-simulation", _smoke_problems(path))
    if not problems:
        problems += counted("description matches binary", behaviour_problems(path))
    if not problems:
        problems += counted("reference result", reference_problems(path))
    return problems
