"""Fixtures shared by the test modules: the FMUs they co-simulate (built once per session, each
read only) and the shared measured recordings (a test that needs an absent one skips, naming it)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from contract.layout import identity_coefficients
from fmu_cases import TRAINED_SETTINGS, trained_coefficients
from training.fmu_build import build_fmu

#: The FMI versions every FMU is built for.
FMI_VERSIONS = (2, 3)
#: The shared measured data (read only), beside the repository.
SHARED_DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


def _build(tmp_path_factory, kind: str, version: int) -> Path:
    """An FMI `version` FMU of `kind`: "identity" (identity coefficients, default settings) or
    "trained" (tests/fmu_cases.py's non-identity coefficients and non-default settings)."""
    out = tmp_path_factory.mktemp(f"{kind}-fmi{version}") / "ImuFusion.fmu"
    if kind == "identity":
        return build_fmu(np.array(identity_coefficients()), {}, out, fmi_version=version)
    return build_fmu(trained_coefficients(), TRAINED_SETTINGS, out, provenance="test coefficients",
                     fmi_version=version)


@pytest.fixture(scope="session")
def identity_fmu2(tmp_path_factory) -> Path:
    """An FMI 2.0 FMU with identity coefficients and default settings: the outputs are the sensors' own."""
    return _build(tmp_path_factory, "identity", 2)


@pytest.fixture(scope="session")
def identity_fmu3(tmp_path_factory) -> Path:
    """An FMI 3.0 FMU with identity coefficients and default settings."""
    return _build(tmp_path_factory, "identity", 3)


@pytest.fixture(scope="session")
def trained_fmu2(tmp_path_factory) -> Path:
    """An FMI 2.0 FMU built from non-identity coefficients and non-default settings."""
    return _build(tmp_path_factory, "trained", 2)


@pytest.fixture(scope="session")
def trained_fmu3(tmp_path_factory) -> Path:
    """An FMI 3.0 FMU built from non-identity coefficients and non-default settings."""
    return _build(tmp_path_factory, "trained", 3)


@pytest.fixture(params=FMI_VERSIONS, ids=[f"fmi{v}" for v in FMI_VERSIONS])
def fmi_version(request) -> int:
    """Each FMI version in turn (2, 3)."""
    return request.param


@pytest.fixture
def identity_fmu(fmi_version, request) -> Path:
    """The identity FMU of each FMI version (identity_fmu2, identity_fmu3)."""
    return request.getfixturevalue(f"identity_fmu{fmi_version}")


@pytest.fixture
def trained_fmu(fmi_version, request) -> Path:
    """The trained FMU of each FMI version (trained_fmu2, trained_fmu3)."""
    return request.getfixturevalue(f"trained_fmu{fmi_version}")


def _shared_file(relative: str) -> Path:
    """SHARED_DATA / relative, or skip the calling test naming where it was looked for."""
    path = SHARED_DATA / relative
    if not path.is_file():
        pytest.skip(f"shared recording not found at {path}")
    return path


@pytest.fixture(scope="session")
def xio_log() -> Path:
    """The x-io handheld log (CSV, gzip), a measured recording without reference attitude."""
    return _shared_file("xio_handheld/xio_handheld.csv.gz")


@pytest.fixture(scope="session")
def broad_trial():
    """file name -> path of that BROAD trial (CSV, gzip, with reference attitude), or a skip."""
    return lambda name: _shared_file(f"broad/{name}")
