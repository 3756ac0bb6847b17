"""No code from outside the archive: an FMU whose modelIdentifier is not a plain C name is refused
by `imufmu run`, `imufmu validate` and the Python API before anything is loaded (issue 16, item 2).

The hostile FMU names, by traversal, a shared library built here with gcc whose constructor writes
a marker file; the marker must not exist afterwards.
"""
from __future__ import annotations

import subprocess
import tempfile
import zipfile
from pathlib import Path

import fmpy
import numpy as np
import pytest

from debian_tools import debian_tool

from cli_errors import fails
from contract.layout import INPUTS
from fmu.archive import FmuArchiveError, extracted_binary, read_description
from fmu.compiler import binary_path
from fmu.cosim import initialised_fmu, run_fmu
from fmu.model_description import MODEL_NAME, model_description_xml

GUID = "{00000000-0000-0000-0000-000000000016}"
EVIL_C = """#include <stdio.h>
__attribute__((constructor)) static void mark(void) {
    FILE *f = fopen(MARKER, "w");
    if (f != NULL) { fputs("loaded", f); fclose(f); }
}
"""
#: From <extraction folder>/binaries/linux64 three '..' reach the temporary folder holding it.
UP_TO_TEMP = "../../../"


def _fmu(path: Path, identifier: str) -> Path:
    """An FMI 2 FMU whose modelDescription.xml names `identifier`, holding a (dummy) ImuFusion binary."""
    xml = model_description_xml({}, GUID, "identifier test").replace(
        f'modelIdentifier="{MODEL_NAME}"', f'modelIdentifier="{identifier}"')
    assert f'modelIdentifier="{identifier}"' in xml
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("modelDescription.xml", xml)
        zf.writestr(binary_path(Path(), MODEL_NAME, 2).as_posix(), b"not a library")
    return path


@pytest.fixture
def evil(tmp_path, monkeypatch):
    """(FMU naming the library by traversal, marker file, library): extraction folders go under
    tmp_path/temp, so the traversal from there reaches tmp_path/evil.so."""
    gcc = debian_tool("gcc")
    marker = tmp_path / "marker.txt"
    source = tmp_path / "evil.c"
    source.write_text(EVIL_C)
    library = tmp_path / f"evil{fmpy.sharedLibraryExtension}"
    subprocess.run([gcc, "-shared", "-fPIC", f'-DMARKER="{marker}"', str(source), "-o", str(library)], check=True)
    temp = tmp_path / "temp"
    temp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(temp))
    return _fmu(tmp_path / "evil.fmu", f"{UP_TO_TEMP}../evil"), marker, library


def _recording(tmp_path: Path) -> Path:
    """A 0.5 s level recording at rest (imu-csv/1)."""
    rows = [",".join(str(v) for v in (0.01 * k, 0.0, 0.0, 0.0, 0.0, 0.0, -9.81, 20.0, 0.0, 40.0, 25.0))
            for k in range(50)]
    path = tmp_path / "rest.csv"
    path.write_text("\n".join(["t," + ",".join(INPUTS[:10])] + rows) + "\n")
    return path


def test_run_refuses_the_traversal_identifier_and_loads_nothing(evil, tmp_path, capsys):
    fmu, marker, _ = evil
    fails(capsys, ["run", str(fmu), str(_recording(tmp_path)), "--out", str(tmp_path / "o.csv")],
          "evil.fmu", "modelIdentifier", "not a plain C name")
    assert not marker.exists()


def test_validate_refuses_the_traversal_identifier_and_loads_nothing(evil, capsys):
    fmu, marker, _ = evil
    fails(capsys, ["validate", str(fmu)], "evil.fmu", "modelIdentifier", "not a plain C name")
    assert not marker.exists()


@pytest.mark.parametrize("api", ["run_fmu", "initialised_fmu"])
def test_cosimulation_api_refuses_it_too(evil, api):
    """initialised_fmu extracts the archive and then loads the binary: the old code loaded evil.so there."""
    fmu, marker, _ = evil
    with pytest.raises(FmuArchiveError, match="modelIdentifier"):
        if api == "run_fmu":
            run_fmu(fmu, np.arange(3) * 0.01, np.zeros((3, len(INPUTS))))
        else:
            with initialised_fmu(fmu):
                pass
    assert not marker.exists()


@pytest.mark.parametrize("identifier", [
    "", "/tmp/x/evil", "sub/ImuFusion", "..\\evil", "Imu.Fusion", "Imu Fusion", "C:evil", "9lives"])
def test_identifiers_that_are_not_c_names_are_refused(tmp_path, identifier):
    fmu = _fmu(tmp_path / "bad.fmu", identifier)
    with pytest.raises(FmuArchiveError, match=r"bad\.fmu: modelIdentifier .* is not a plain C name"):
        read_description(fmu)


def test_a_binary_that_resolves_outside_the_folder_is_not_loaded(tmp_path):
    """A plain identifier whose extracted binary is a symbolic link to a file outside the folder."""
    outside = tmp_path / "outside.so"
    outside.write_bytes(b"x")
    unzipdir = tmp_path / "unzipped"
    binary = binary_path(unzipdir, MODEL_NAME, 2)
    binary.parent.mkdir(parents=True)
    binary.symlink_to(outside)
    (unzipdir / "modelDescription.xml").write_text(model_description_xml({}, GUID, "symlink test"))
    description = fmpy.read_model_description(str(unzipdir))
    with pytest.raises(FmuArchiveError, match="no binary .* inside the extracted FMU"):
        extracted_binary(tmp_path / "x.fmu", unzipdir, description)
    binary.unlink()
    binary.write_bytes(b"x")
    assert extracted_binary(tmp_path / "x.fmu", unzipdir, description) == binary.resolve()
