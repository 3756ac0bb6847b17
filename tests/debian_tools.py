"""The Debian tools some tests need (compilers, nm, valgrind): their path, or a skip that names
the package (CI installs them, see .ci/run)."""
from __future__ import annotations

import shutil

import pytest


def debian_tool(name: str, package: str | None = None) -> str:
    """Path of the tool `name`, or skip the calling test with the apt-get command that installs
    it (from the Debian package `package`, default the tool's own name)."""
    path = shutil.which(name)
    if path is None:
        pytest.skip(f"{name} is not installed (apt-get install {package or name}); CI installs it")
    return path
