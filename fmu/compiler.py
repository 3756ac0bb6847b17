"""Compile the FMU's binaries from its sources/: this platform's with fmpy's CMake project, the
Windows x86-64 one with Debian's mingw-w64 cross compiler."""
from __future__ import annotations

import shutil
import subprocess
import tempfile
from pathlib import Path

import fmpy
from fmpy.build import create_cmake_settings

from contract.errors import BuildError

#: The repository's C sources: exactly what goes into the FMU's sources/ folder (minus EXCLUDED).
SOURCE_DIR = Path(__file__).resolve().parent.parent / "sources"

#: FMI versions the sources build, with the wrapper file of each.
WRAPPERS = {2: "fmi2Functions.c", 3: "fmi3Functions.c"}

#: Repository sources that are in no FMU: a generated coefficient header left in the tree (the
#: other version's wrapper is excluded per build). The batch library's own files live in
#: sources/batch/, which no FMU takes.
EXCLUDED = frozenset({"ImuCoefficientsData.h"})

#: Flags added to fmpy's -Wall -Wextra -Wpedantic: the project's C standard, warnings as errors.
C_FLAGS = "-std=c99 -Werror"

#: fmpy's CMake project (CMakeLists.txt) and the FMI 2/3 headers the wrappers include.
FMPY_C_CODE = Path(fmpy.__file__).parent / "c-code"

#: The Windows x86-64 binary: its platform folder by FMI version, the cross compiler and the
#: Debian package that installs it.
WIN64_PLATFORMS = {2: "win64", 3: "x86_64-windows"}
WIN64_COMPILER = "x86_64-w64-mingw32-gcc"
WIN64_PACKAGE = "gcc-mingw-w64-x86-64"
#: The cross compiler's flags: those of the CMake build (fmpy's all-warnings set, C_FLAGS, CMake's
#: Release optimisation) and a DLL that links libgcc statically, so that it needs nothing but
#: Windows system DLLs; -s drops the debug sections of mingw's static runtime objects (0.38 MB ->
#: 0.15 MB).
WIN64_FLAGS = ("-Wall", "-Wextra", "-Wpedantic", *C_FLAGS.split(), "-O3", "-DNDEBUG",
               "-shared", "-static-libgcc", "-s", "-Wl,--no-undefined")


def check_fmi_version(fmi_version: int) -> int:
    """fmi_version if it is 2 or 3; BuildError otherwise."""
    if fmi_version not in WRAPPERS:
        raise BuildError(f"FMI version {fmi_version!r} is not supported (choose 2 or 3)")
    return fmi_version


def fmu_source_files(source_dir: Path = SOURCE_DIR, fmi_version: int = 2) -> list[Path]:
    """The .c and .h files of `source_dir` that go into the FMI `fmi_version` FMU, sorted by name."""
    other = {name for version, name in WRAPPERS.items() if version != check_fmi_version(fmi_version)}
    files = [p for p in source_dir.iterdir() if p.suffix in (".c", ".h") and p.name not in EXCLUDED
             and p.name not in other]
    return sorted(files, key=lambda p: p.name)


def binary_path(unzipdir: Path, model_identifier: str, fmi_version: int) -> Path:
    """Where the platform binary of an extracted FMU lives (FMI 2: linux64, FMI 3: x86_64-linux)."""
    platform = fmpy.platform if check_fmi_version(fmi_version) == 2 else fmpy.platform_tuple
    return Path(unzipdir) / "binaries" / platform / (model_identifier + fmpy.sharedLibraryExtension)


def win64_binary_path(unzipdir: Path, model_identifier: str, fmi_version: int) -> Path:
    """Where the Windows x86-64 binary of an extracted FMU lives (FMI 2: win64, FMI 3: x86_64-windows)."""
    return Path(unzipdir) / "binaries" / WIN64_PLATFORMS[check_fmi_version(fmi_version)] / (model_identifier + ".dll")


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
    with tempfile.TemporaryDirectory(prefix="imufusion-build-") as build:
        create_cmake_settings(unzipdir, build, all_warnings=True, cmake_options={
            "CMAKE_C_FLAGS:STRING": C_FLAGS,
            "CMAKE_SHARED_LINKER_FLAGS:STRING": "-Wl,--no-undefined",
            "CMAKE_C_STANDARD_LIBRARIES:STRING": "-lm",
        })
        _run(["cmake", "-S", str(FMPY_C_CODE), "-B", build], "CMake configuration")
        _run(["cmake", "--build", build, "--target", "install", "--config", "Release", "--parallel", "2"],
             "compiling the FMU binary")
    description = fmpy.read_model_description(str(unzipdir))
    binary = binary_path(unzipdir, description.coSimulation.modelIdentifier, int(description.fmiVersion[0]))
    if not binary.is_file():
        raise BuildError(f"the build finished but {binary} is missing")
    return binary


def win64_compiler() -> str | None:
    """Path of the mingw-w64 cross compiler (WIN64_COMPILER), or None when it is not installed."""
    return shutil.which(WIN64_COMPILER)


def compile_win64_binary(unzipdir: Path, compiler: str) -> Path:
    """Cross-compile unzipdir/sources into unzipdir/binaries/<win64|x86_64-windows>/<modelIdentifier>.dll.

    One `compiler` (mingw-w64 gcc) command line with WIN64_FLAGS over the source files and
    preprocessor definitions the model description's build configuration lists (what fmpy's CMake
    project compiles), the sources folder and fmpy's FMI headers on the include path. The FMI
    headers declare the fmi2*/fmi3* functions __declspec(dllexport), so the DLL exports exactly
    those. Returns the DLL's path; raises BuildError with the compiler output.
    """
    unzipdir = Path(unzipdir).resolve()
    description = fmpy.read_model_description(str(unzipdir))
    source_set = description.buildConfigurations[0].sourceFileSets[0]
    binary = win64_binary_path(unzipdir, description.coSimulation.modelIdentifier, int(description.fmiVersion[0]))
    binary.parent.mkdir(parents=True, exist_ok=True)
    _run([compiler, *WIN64_FLAGS, f"-I{unzipdir / 'sources'}", f"-I{FMPY_C_CODE}",
          *(f"-D{d.name}={d.value}" for d in source_set.preprocessorDefinitions),
          *(str(unzipdir / "sources" / name) for name in source_set.sourceFiles), "-o", str(binary)],
         "cross-compiling the win64 binary")
    return binary
