"""ctypes bridge to the C runtime (sources/Imu*.c) compiled as a small shared library.

The library is the same code that goes into the FMU, so `run_batch` gives the FMU's outputs for
a whole recording in one call. It is compiled on first use into a cache folder (env
`IMUFUSION_CACHE`, default `~/.cache/imufusion`) under a name keyed by a hash of the sources,
the compiler and the flags, and rebuilt only when one of them changes. Without a C compiler on PATH the
prebuilt library (fmu.prebuilt, `imufmu prebuild`) built from the same sources is used.
"""
from __future__ import annotations

import ctypes
import hashlib
import os
import shlex
import subprocess
import tempfile
from functools import lru_cache
from pathlib import Path

import numpy as np

from contract import layout
from contract.errors import BuildError
from fmu.prebuilt import missing_tools, prebuilt_file

SOURCES_DIR = Path(__file__).resolve().parent.parent / "sources"
#: The batch library's own entry points (never in an FMU).
BATCH_DIR = SOURCES_DIR / "batch"
#: Compiler flags of the runtime library (strict: every warning is an error), at the optimisation of the
#: FMU's own build (fmpy's CMake, Release: -O3), so that the batch library costs what the FMU costs.
CFLAGS = ("-std=c99", "-O3", "-fPIC", "-shared", "-Wall", "-Wextra", "-Wpedantic", "-Werror")
LIBS = ("-lm",)
#: Meaning of the negative return codes of ImuBatchRun (sources/ImuRuntime.h, ImuRuntimeResult).
ERROR_CODES = {
    -1: "an array pointer is NULL",
    -2: f"wrong number of coefficients (expected {layout.N_COEFFICIENTS})",
    -3: f"coefficient layout version is not {layout.LAYOUT_VERSION}",
    -4: "invalid temperature-model block (enabled not 0/1, degree not an integer in "
        f"0..{layout.MAX_DEGREE}, ts <= 0 or a non-finite entry)",
    -5: f"wrong number of settings (expected {len(layout.SETTINGS)})",
    -6: "a setting is out of range",
}


def runtime_sources() -> list[Path]:
    """The C files of the runtime library: the FMU's runtime (sources/Imu*.c, not the FMI layer) and
    the batch entry points (sources/batch/*.c)."""
    return sorted(SOURCES_DIR.glob("Imu*.c")) + sorted(BATCH_DIR.glob("*.c"))


def compiler_command() -> list[str]:
    """Compiler command: env CC (may hold arguments, e.g. 'ccache gcc') or 'cc'."""
    return shlex.split(os.environ.get("CC", "cc")) or ["cc"]


def _cache_dir() -> Path:
    """Folder of the compiled libraries (env IMUFUSION_CACHE or ~/.cache/imufusion)."""
    return Path(os.environ.get("IMUFUSION_CACHE", Path.home() / ".cache" / "imufusion"))


def _build_key(sources: list[Path], compiler: list[str]) -> str:
    """Hash of the sources, every header in sources/, the compiler command and the flags."""
    h = hashlib.sha256()
    for part in (*compiler, *CFLAGS, *LIBS):
        h.update(part.encode() + b"\0")
    for path in sorted({*sources, *SOURCES_DIR.glob("*.h"), *BATCH_DIR.glob("*.h")}):
        h.update(path.relative_to(SOURCES_DIR).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()[:20]


def build_runtime() -> Path:
    """Compile the runtime library if the cache has no up-to-date copy; return its path. Without the
    compiler on PATH: the prebuilt library of these sources (fmu.prebuilt.prebuilt_file).

    Raises BuildError with the compiler output when compilation fails. Safe to call from
    parallel processes: each compiles into its own temporary file and renames it atomically.
    """
    sources, compiler = runtime_sources(), compiler_command()
    cache = _cache_dir()
    target = cache / f"libimufusion-{_build_key(sources, compiler)}.so"
    if target.exists():
        return target
    if missing_tools(compiler[0]):
        return prebuilt_file("runtime", f"the C compiler '{compiler[0]}' is not on PATH (env CC names another)")
    cache.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=target.stem + ".", suffix=".tmp", dir=cache)
    os.close(fd)
    cmd = [*compiler, *CFLAGS, "-I", str(SOURCES_DIR), "-I", str(BATCH_DIR), *map(str, sources), "-o", tmp, *LIBS]
    try:
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True)
        except OSError as exc:
            raise BuildError(f"cannot run the C compiler '{compiler[0]}': {exc}") from exc
        if proc.returncode != 0:
            raise BuildError(f"compiling the C runtime failed ({shlex.join(cmd)}):\n{proc.stdout}{proc.stderr}")
        os.replace(tmp, target)
    finally:  # also when stopped (Ctrl-C) while compiling: no half-written file left in the cache
        if os.path.exists(tmp):
            os.unlink(tmp)
    return target


_DP, _SZ, _IP = ctypes.POINTER(ctypes.c_double), ctypes.c_size_t, ctypes.POINTER(ctypes.c_int)
_TEXT = ctypes.POINTER(ctypes.c_char_p)
#: Every entry point of the runtime library (sources/batch/*.c) with its (argument types, result
#: type): the one place Python declares them.
SIGNATURES = {
    "ImuBatchRun": ([_DP, _SZ, _DP, _SZ, _SZ, _DP, _DP, _DP], ctypes.c_int),
    "ImuBatchRunIssues": ([_DP, _SZ, _DP, _SZ, _SZ, _DP, _DP, _DP, _IP], ctypes.c_int),
    "ImuBatchEulerAllAdditions": ([], ctypes.c_int),
    "ImuBatchCheckSettings": ([_DP, _SZ, _TEXT], ctypes.c_int),
    "ImuBatchLayout": ([_IP] * 5, None),
    "ImuBatchTermSignals": ([_SZ, _DP, _DP, _DP, _DP, _DP], None),
    "ImuBatchElmPredict": ([_DP, _SZ, _SZ, _DP, _DP], ctypes.c_int),
    "ImuBatchPsoBpCorrect": ([_DP, _SZ, _SZ, _DP, _DP, _DP, _DP], ctypes.c_int),
    "ImuBatchPsoBpPredict": ([_DP, _SZ, _SZ, _DP, _DP, _DP], ctypes.c_int),
    "ImuBatchPsoBpEvaluate": ([_DP, _SZ, _SZ, _DP, _DP, _DP], ctypes.c_int),
    "ImuBatchMagPfInternal": ([_SZ, _TEXT, _TEXT, _DP, _DP], ctypes.c_int),
    "ImuBatchMagPfRun": ([_DP, _SZ, _DP, _SZ, _SZ, _DP, _DP], ctypes.c_int),
    "ImuBatchMagPfCheckSettings": ([_DP, _SZ, _DP, _SZ, _TEXT], ctypes.c_int),
    "ImuBatchRngDraw": ([ctypes.c_double, ctypes.c_double, ctypes.c_int, _SZ, _DP], ctypes.c_int),
    "ImuBatchSizes": ([ctypes.POINTER(ctypes.c_size_t)] * 3, None),
}


@lru_cache(maxsize=None)
def _load(path: str) -> ctypes.CDLL:
    """Open a compiled runtime library and declare the signatures of its entry points (SIGNATURES)."""
    lib = ctypes.CDLL(path)
    for name, (argtypes, restype) in SIGNATURES.items():
        getattr(lib, name).argtypes = argtypes
        getattr(lib, name).restype = restype
    return lib


def _stamp(sources: list[Path], compiler: list[str]) -> tuple:
    """What the build key depends on, read cheaply: the compiler command, the flags and the path, size and
    modification time of every file the key hashes (an edited file changes its time)."""
    files = sorted({*sources, *SOURCES_DIR.glob("*.h"), *BATCH_DIR.glob("*.h")})
    return (tuple(compiler), CFLAGS, LIBS, tuple((str(p), (st := p.stat()).st_mtime_ns, st.st_size) for p in files))


#: The libraries this process has opened, by the stamp of their sources: hashing the sources costs 1 ms a
#: call, 10 % of a 24 000-sample run_batch (imufmu bench speed timed it with every call).
_LOADED: dict[tuple, ctypes.CDLL] = {}


def load_runtime() -> ctypes.CDLL:
    """The runtime library (compiled if needed), with ctypes signatures declared; opened once per process
    while its sources stay as they are."""
    stamp = _stamp(runtime_sources(), compiler_command())
    if stamp not in _LOADED:
        _LOADED[stamp] = _load(str(build_runtime()))
    return _LOADED[stamp]


def runtime_layout() -> dict:
    """Array layout of the compiled runtime: version, n_coefficients, n_settings, n_inputs, n_outputs."""
    values = [ctypes.c_int() for _ in range(5)]
    load_runtime().ImuBatchLayout(*(ctypes.byref(v) for v in values))
    keys = ("version", "n_coefficients", "n_settings", "n_inputs", "n_outputs")
    return {k: v.value for k, v in zip(keys, values)}


def _as_array(name: str, value, shape: tuple) -> np.ndarray:
    """Contiguous float64 copy/view of value; ValueError if its shape differs (-1 = any length)."""
    a = np.ascontiguousarray(value, dtype=np.float64)
    if a.ndim != len(shape) or any(s not in (-1, n) for s, n in zip(shape, a.shape)):
        raise ValueError(f"{name} must have shape {shape} (-1 = any), got {a.shape}")
    return a


def pointer(a: np.ndarray):
    """ctypes double pointer to the data of a contiguous float64 array."""
    return a.ctypes.data_as(_DP)


def _error(lib: ctypes.CDLL, code: int, settings: np.ndarray) -> ValueError:
    """ValueError describing a negative ImuBatchRun code (naming the bad setting if any)."""
    text = ERROR_CODES.get(code, "unknown error")
    if code == -6:
        message = ctypes.c_char_p()
        lib.ImuBatchCheckSettings(pointer(settings), settings.size, ctypes.byref(message))
        text = message.value.decode() if message.value else text
    return ValueError(f"C runtime rejected the input (code {code}): {text}")


def euler_all_additions() -> int:
    """Every bit of the Euler fusion's project additions (sources/ImuAttitude.h ImuEulerAddition): the
    additions the FMU and run_batch's default use."""
    return int(load_runtime().ImuBatchEulerAllAdditions())


def _run_arrays(coefficients, settings, t, inputs):
    """The checked contiguous float64 arrays of a run (coefficients, settings, t, inputs) and its
    empty (N, len(OUTPUTS)) output array."""
    tt = _as_array("t", t, (-1,))
    return (_as_array("coefficients", coefficients, (-1,)), _as_array("settings", settings, (-1,)), tt,
            _as_array("inputs", inputs, (tt.shape[0], len(layout.INPUTS))),
            np.empty((tt.shape[0], len(layout.OUTPUTS)), dtype=np.float64))


def run_batch(coefficients, settings, t, inputs) -> np.ndarray:
    """Run the C pipeline over a recording.

    coefficients: (N_COEFFICIENTS,) flat coefficient array (contract.layout); settings: flat settings
    array (contract.layout.settings_array()); t: (N,) times [s]; inputs: (N, len(INPUTS)) raw
    gyr [rad/s], acc [m/s²], mag [µT], temp [°C] and the auxiliary inputs (ImuData.inputs). Returns (N, len(OUTPUTS)) outputs in the order of
    contract.layout.OUTPUTS, finite except the corrected triad of an absent sensor (NaN; docs/fmu.md,
    "Absent sensors"). Only the differences of t are used: sample k is integrated over t[k] − t[k−1],
    the step size the FMU gets from fmu.cosim.run_fmu. Raises ValueError on bad shapes or when the
    runtime rejects the coefficients or settings.
    """
    lib = load_runtime()
    c, s, tt, x, out = _run_arrays(coefficients, settings, t, inputs)
    code = lib.ImuBatchRun(pointer(c), c.size, pointer(s), s.size, tt.shape[0], pointer(tt), pointer(x), pointer(out))
    if code != 0:
        raise _error(lib, code, s)
    return out


def run_batch_issues(coefficients, settings, t, inputs) -> tuple[np.ndarray, np.ndarray]:
    """run_batch (every Euler addition, as the FMU) and the guard's ImuGuardIssue bits of every
    sample (sources/ImuGuard.h: what the FMU reports as warnings): ((N, len(OUTPUTS)), (N,) int)."""
    lib = load_runtime()
    c, s, tt, x, out = _run_arrays(coefficients, settings, t, inputs)
    issues = np.zeros(tt.shape[0], dtype=np.intc)
    code = lib.ImuBatchRunIssues(pointer(c), c.size, pointer(s), s.size, tt.shape[0], pointer(tt), pointer(x),
                                 pointer(out), issues.ctypes.data_as(_IP))
    if code != 0:
        raise _error(lib, code, s)
    return out, issues


def term_signals(t, components, temperature, aux=None) -> np.ndarray:
    """Correction-term signals of a series as the C pipeline forms them (sources/ImuTerms.h).

    t: (N,) s; components: (N, 9) compensated gyr [rad/s], acc [m/s²], mag [µT]; temperature:
    (N,) °C; aux: (N, len(contract.layout.AUX_INPUTS)) auxiliary inputs (default zeros). Returns
    (N, len(contract.layout.TERM_SIGNALS)); NaN where a signal is not computable.
    """
    lib = load_runtime()
    tt = _as_array("t", t, (-1,))
    n = tt.shape[0]
    x = _as_array("components", components, (n, 9))
    temp = _as_array("temperature", temperature, (n,))
    u = _as_array("aux", np.zeros((n, len(layout.AUX_INPUTS))) if aux is None else aux, (n, len(layout.AUX_INPUTS)))
    out = np.empty((n, len(layout.TERM_SIGNALS)), dtype=np.float64)
    lib.ImuBatchTermSignals(n, pointer(tt), pointer(x), pointer(temp), pointer(u), pointer(out))
    return out


def runtime_sizes() -> dict[str, int]:
    """sizeof [bytes] of ImuAttitude, ImuPipeline and ModelInstance, from the compiled runtime library."""
    sizes = [ctypes.c_size_t() for _ in range(3)]
    load_runtime().ImuBatchSizes(*(ctypes.byref(s) for s in sizes))
    return dict(zip(("attitude", "pipeline", "model_instance"), (s.value for s in sizes)))


def magpf_internal_rows() -> tuple[tuple[str, str, float, float], ...]:
    """(name, unit, default, value with pf_additions = 0) of the particle filter's internal settings, in the
    order of the second array of ImuBatchMagPfRun (sources/ImuMagPf.c ImuMagPfInternal, their one definition)."""
    lib, rows = load_runtime(), []
    name, unit, value, source = ctypes.c_char_p(), ctypes.c_char_p(), ctypes.c_double(), ctypes.c_double()
    while lib.ImuBatchMagPfInternal(len(rows), *(ctypes.byref(x) for x in (name, unit, value, source))) == 0:
        rows.append((name.value.decode(), unit.value.decode(), value.value, source.value))
    return tuple(rows)


def magpf_internal_table() -> tuple[tuple[str, str, float], ...]:
    """(name, unit, default) of the particle filter's internal settings (magpf_internal_rows)."""
    return tuple(row[:3] for row in magpf_internal_rows())


def magpf_settings_problem(settings: np.ndarray, internal: np.ndarray) -> str | None:
    """None if the C particle filter accepts the FMU settings array and its internal array, else its
    message naming the setting (ImuBatchMagPfCheckSettings)."""
    s, i = _as_array("settings", settings, (-1,)), _as_array("internal", internal, (-1,))
    message = ctypes.c_char_p()
    code = load_runtime().ImuBatchMagPfCheckSettings(pointer(s), s.size, pointer(i), i.size, ctypes.byref(message))
    return None if code == 0 else (message.value or b"invalid settings").decode()
