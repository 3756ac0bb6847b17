"""fmu.archive: a malformed or hostile FMU archive is refused in one line before anything is loaded,
and extraction stops at the size caps. (The CLI side of every case is in tests/test_cli_fuzz.py.)"""
from __future__ import annotations

import zipfile

import pytest

from fmu import archive
from fmu.archive import FmuArchiveError, check_archive, extract_archive
from fmu.cosim import _Log


def _zip(path, members: dict):
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, content in members.items():
            zf.writestr(name, content)
    return path


@pytest.mark.parametrize("name, words", [("/etc/evil", "absolute path"), ("../evil", "contains '..'"),
                                         ("a/../../evil", "contains '..'"), ("C:/evil", "absolute path"),
                                         ("a\\evil", "backslash")])
def test_member_names_outside_the_folder_are_refused(tmp_path, name, words):
    path = _zip(tmp_path / "x.fmu", {"modelDescription.xml": "<x/>", name: "x"})
    with pytest.raises(FmuArchiveError) as info:
        extract_archive(path, tmp_path / "out")
    assert words in str(info.value) and str(path) in str(info.value)
    assert not (tmp_path / "evil").exists() and not (tmp_path / "out").exists()


def test_a_zip_of_an_fmu_is_named(tmp_path):
    inner = _zip(tmp_path / "inner.fmu", {"modelDescription.xml": "<x/>"})
    outer = _zip(tmp_path / "outer.fmu", {"ImuFusion.fmu": inner.read_bytes()})
    with pytest.raises(FmuArchiveError, match="it holds 'ImuFusion.fmu'"):
        check_archive(outer)


def test_declared_size_over_the_cap_is_refused_before_extraction(tmp_path, monkeypatch):
    monkeypatch.setattr(archive, "MAX_MEMBER_BYTES", 1000)
    path = _zip(tmp_path / "x.fmu", {"modelDescription.xml": "<x/>", "big.bin": b"0" * 1001})
    with pytest.raises(FmuArchiveError, match="declares 1001 bytes"):
        extract_archive(path, tmp_path / "out")
    assert not (tmp_path / "out" / "big.bin").exists()


def test_actual_size_over_the_cap_stops_the_copy(tmp_path, monkeypatch):
    """The streaming copy counts what it inflates, whatever the headers declared."""
    path = _zip(tmp_path / "x.fmu", {"big.bin": b"0" * 5000})
    monkeypatch.setattr(archive, "MAX_MEMBER_BYTES", 1000)
    with zipfile.ZipFile(path) as zf, pytest.raises(FmuArchiveError, match="inflates beyond"):
        archive._copy_member(zf, zf.getinfo("big.bin"), tmp_path / "big.bin", path)
    assert (tmp_path / "big.bin").stat().st_size <= 1000


def test_fmu_errors_are_one_line_with_the_last_log_messages():
    log = _Log()
    for k in range(5):
        log.log3(None, 3, b"logStatusError", f"problem {k}\nsecond line".encode())
    error = log.error("fmi2DoStep failed\nwith status 3")
    text = str(error)
    assert "\n" not in text and "problem 4" in text and "problem 1" not in text and "(2 earlier messages)" in text
    assert len(error.log) == 5
