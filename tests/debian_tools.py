"""The Debian tools some tests need (compilers, nm, valgrind): their path, or a skip that names
the package (CI installs them, see .ci/run)."""
from __future__ import annotations

import shutil

import pytest


def debian_tool(name: str) -> str:
    """Path of the tool `name`, or skip the calling test with the apt-get command that installs it."""
    path = shutil.which(name)
    if path is None:
        pytest.skip(f"{name} is not installed (apt-get install {name}); CI installs it")
    return path
