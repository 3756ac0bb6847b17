"""Compile the FMU's platform binary from its sources/ with fmpy's CMake project."""
from __future__ import annotations

import subprocess
import tempfile
from pathlib import Path

import fmpy
from fmpy.build import create_cmake_settings

from training.errors import BuildError

#: The repository's C sources: exactly what goes into the FMU's sources/ folder (minus EXCLUDED).
SOURCE_DIR = Path(__file__).resolve().parent.parent / "sources"

#: FMI versions the sources build, with the wrapper file of each.
WRAPPERS = {2: "fmi2Functions.c", 3: "fmi3Functions.c"}

#: Repository sources that are in no FMU: a generated coefficient header left in the tree (the
#: other version's wrapper is excluded per build). The batch library's files (ImuBatch*.c/.h,
#: the ctypes entry points of `training`) are excluded by `_is_batch_file`.
EXCLUDED = frozenset({"ImuCoefficientsData.h"})


def _is_batch_file(path: Path) -> bool:
    """True for the batch-library-only files (ImuBatch.c, ImuBatchElm.c, ...)."""
    return path.name.startswith("ImuBatch")

#: Flags added to fmpy's -Wall -Wextra -Wpedantic: the project's C standard, warnings as errors.
C_FLAGS = "-std=c99 -Werror"


def check_fmi_version(fmi_version: int) -> int:
    """fmi_version if it is 2 or 3; BuildError otherwise."""
    if fmi_version not in WRAPPERS:
        raise BuildError(f"FMI version {fmi_version!r} is not supported (choose 2 or 3)")
    return fmi_version


def fmu_source_files(source_dir: Path = SOURCE_DIR, fmi_version: int = 2) -> list[Path]:
    """The .c and .h files of `source_dir` that go into the FMI `fmi_version` FMU, sorted by name."""
    other = {name for version, name in WRAPPERS.items() if version != check_fmi_version(fmi_version)}
    files = [p for p in source_dir.iterdir() if p.suffix in (".c", ".h") and p.name not in EXCLUDED
             and p.name not in other and not _is_batch_file(p)]
    return sorted(files, key=lambda p: p.name)


def binary_path(unzipdir: Path, model_identifier: str, fmi_version: int) -> Path:
    """Where the platform binary of an extracted FMU lives (FMI 2: linux64, FMI 3: x86_64-linux)."""
    platform = fmpy.platform if check_fmi_version(fmi_version) == 2 else fmpy.platform_tuple
    return Path(unzipdir) / "binaries" / platform / (model_identifier + fmpy.sharedLibraryExtension)


def _run(command: list[str], what: str) -> str:
    """Run `command`; return its combined output or raise BuildError carrying it."""
    try:
        result = subprocess.run(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    except OSError as e:
        raise BuildError(f"{what}: cannot run {command[0]}: {e}") from e
    if result.returncode != 0:
        raise BuildError(f"{what} failed (exit status {result.returncode}):\n{result.stdout}")
    return result.stdout


def compile_binary(unzipdir: Path) -> Path:
    """Compile unzipdir/sources into unzipdir/binaries/<platform>/<modelIdentifier>.so.

    unzipdir is an extracted FMU with modelDescription.xml whose SourceFiles (FMI 2) or
    sources/buildDescription.xml (FMI 3) list the .c files.
    The build uses fmpy's CMake project with all warnings as errors, C99 and --no-undefined.
    Returns the path of the shared library; raises BuildError with the compiler output.
    """
    unzipdir = Path(unzipdir).resolve()
    cmake_source = Path(fmpy.__file__).parent / "c-code"
    with tempfile.TemporaryDirectory(prefix="imufusion-build-") as build:
        create_cmake_settings(unzipdir, build, all_warnings=True, cmake_options={
            "CMAKE_C_FLAGS:STRING": C_FLAGS,
            "CMAKE_SHARED_LINKER_FLAGS:STRING": "-Wl,--no-undefined",
            "CMAKE_C_STANDARD_LIBRARIES:STRING": "-lm",
        })
        _run(["cmake", "-S", str(cmake_source), "-B", build], "CMake configuration")
        _run(["cmake", "--build", build, "--target", "install", "--config", "Release", "--parallel", "2"],
             "compiling the FMU binary")
    description = fmpy.read_model_description(str(unzipdir))
    binary = binary_path(unzipdir, description.coSimulation.modelIdentifier, int(description.fmiVersion[0]))
    if not binary.is_file():
        raise BuildError(f"the build finished but {binary} is missing")
    return binary
