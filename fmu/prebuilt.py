"""Prebuilt artefacts (issue 32): the runtime library `imufmu train` evaluates with and the generic FMU of
each FMI version, compiled once so that calibrating a unit (`imufmu train`) and running it
(`imufmu run GENERIC.fmu DATA --calibration unit/calibration.ssv`) need no C compiler.

`imufmu prebuild` writes them on a machine with a compiler into the checkout's `fmu/prebuilt/` or into
`--out`; copied to a machine without one (the same commit), the folder is found there at `fmu/prebuilt/` or
where env `IMUFUSION_PREBUILT` points. They are taken only when no compiler is found, and only when they were
built from these very sources on this platform (the manifest's key and platform): a stale or foreign set is
refused with a one-line error, never used.
"""
from __future__ import annotations

import hashlib
import json
import os
import shutil
import sysconfig
from pathlib import Path

from contract.errors import BuildError

#: The C sources (FMU and batch library): the key hashes every file below it.
SOURCES_DIR = Path(__file__).resolve().parent.parent / "sources"
#: The manifest of a prebuilt folder: {"key", "platform", "files": {kind: file name}}.
MANIFEST = "prebuilt.json"
#: What a prebuilt folder holds: the runtime library and the generic FMU per FMI version.
KINDS = ("runtime", "fmi2", "fmi3")
#: The checkout's own prebuilt folder (not versioned: .gitignore).
PACKAGE_DIR = Path(__file__).resolve().parent / "prebuilt"


def sources_key() -> str:
    """Hash of every file under sources/ (relative path and bytes): what the prebuilt artefacts were built from."""
    h = hashlib.sha256()
    for path in sorted(p for p in SOURCES_DIR.rglob("*") if p.is_file() and p.suffix in (".c", ".h")):
        h.update(path.relative_to(SOURCES_DIR).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()[:20]


def platform() -> str:
    """This interpreter's platform tag (e.g. linux-x86_64): a prebuilt binary runs only there."""
    return sysconfig.get_platform()


def prebuilt_dir() -> Path:
    """The prebuilt folder: env IMUFUSION_PREBUILT, else fmu/prebuilt/ beside this module."""
    return Path(os.environ.get("IMUFUSION_PREBUILT") or PACKAGE_DIR)


def missing_tools(*tools: str) -> list[str]:
    """The commands among `tools` that are not on PATH (an absolute path counts when it exists)."""
    return [tool for tool in tools if shutil.which(tool) is None]


def write_manifest(folder: Path, files: dict[str, str]) -> Path:
    """Write folder/MANIFEST for the files (kind -> file name in folder) built from the current sources."""
    path = Path(folder) / MANIFEST
    path.write_text(json.dumps({"key": sources_key(), "platform": platform(), "files": files}, indent=2) + "\n")
    return path


def prebuilt_file(kind: str, reason: str) -> Path:
    """The prebuilt artefact `kind` (KINDS) to use because `reason` (no compiler, …); BuildError in one line
    naming the folder and what is wrong when there is none, it was built from other sources or for another
    platform, or its file is missing."""
    folder = prebuilt_dir()
    remedy = ("install a C compiler, or run `imufmu prebuild` on a machine with one (same sources) and set "
              "IMUFUSION_PREBUILT to its folder")
    try:
        manifest = json.loads((folder / MANIFEST).read_text())
        key, built_for, name = manifest["key"], manifest["platform"], manifest["files"][kind]
    except FileNotFoundError:
        raise BuildError(f"{reason}, and {folder} holds no prebuilt artefacts ({MANIFEST}): {remedy}") from None
    except (ValueError, KeyError, TypeError) as e:
        raise BuildError(f"{reason}, and {folder / MANIFEST} is not a prebuilt manifest with a '{kind}' entry "
                         f"({e}): {remedy}") from None
    if key != sources_key():
        raise BuildError(f"{reason}, and the prebuilt artefacts in {folder} were built from other sources "
                         f"(key {key}, these sources {sources_key()}): {remedy}")
    if built_for != platform():
        raise BuildError(f"{reason}, and the prebuilt artefacts in {folder} are for {built_for}, "
                         f"not {platform()}: {remedy}")
    path = folder / name
    if not path.is_file():
        raise BuildError(f"{reason}, and {path} (listed in {folder / MANIFEST}) is missing: {remedy}")
    return path
