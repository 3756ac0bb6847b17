"""Our distribution's name and version (pyproject.toml [project] name and version).

The name is `imufusion-fmu`; `imufusion` is x-io Technologies' Fusion package, which this
project only benchmarks against (training/bench/bench.py), so nothing records our version under it.
"""
from __future__ import annotations

from importlib import metadata

from contract import __version__

#: pyproject.toml [project] name.
DISTRIBUTION = "imufusion-fmu"


def package_version() -> str:
    """Version of the installed distribution (importlib.metadata); the source tree's
    training.__version__ when it is not installed (tests pin both to pyproject.toml)."""
    try:
        return metadata.version(DISTRIBUTION)
    except metadata.PackageNotFoundError:
        return __version__
