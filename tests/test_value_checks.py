"""Nonsense refused (issue 15 item 8): every value is checked against a declared type and range.

One source, contract/layout.py SETTING_RANGES: the CLI's --param, the model.json loader, the
modelDescription.xml min/max and the C runtime's ImuPipelineSettingsCheck (pinned here bound by
bound); the artefact's temperature models and terms against the physical bounds of
training/models/model_checks.py; the sidecar fields against training/data/sidecar.py.
"""
from __future__ import annotations

import ctypes
import itertools
import json
import math
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from cli_errors import fails
from contract.errors import DataError, ModelError
from contract.generate import ranges_markdown
from contract.layout import SETTING_RANGES, SETTINGS, settings_array
from contract.mounting import MOUNT_SETTINGS, mounting_problem
from contract.ranges import FIELD_NORM_MAX_UT, FIELD_NORM_MIN_UT, RAO_BLACKWELL_POSITIVE
from contract.schema import setting_problem
from fmu.model_description import model_description_xml
from training.artefact import ModelArtefact, load_artefact
from training.cli import _param, main
from training.data import io, sidecar
from training.models import model_checks
from training.models.thermal import ThermalModel
from training.runtime import load_runtime

SOURCES = Path(__file__).resolve().parent.parent / "sources"

# ----------------------------------------------------------------------------- the table


def test_every_setting_has_a_range_that_holds_its_default():
    assert list(SETTING_RANGES) == [name for name, _ in SETTINGS]
    assert {name: setting_problem(name, value) for name, value in SETTINGS} == {n: None for n, _ in SETTINGS}


def test_docs_show_the_table():
    assert ranges_markdown() in (SOURCES.parent / "docs" / "fmu.md").read_text()


# ----------------------------------------------------------------------------- C limits = table = modelDescription


def _c_accepts(overrides: dict[str, float]) -> tuple[bool, str]:
    """ImuPipelineSettingsCheck (through the batch library) on the defaults with `overrides`."""
    lib = load_runtime()
    s = np.array(settings_array(overrides), dtype=np.float64)
    message = ctypes.c_char_p()
    code = lib.ImuBatchCheckSettings(s.ctypes.data_as(ctypes.POINTER(ctypes.c_double)), s.size,
                                     ctypes.byref(message))
    return code == 0, (message.value or b"").decode()


def _bound_cases(name: str, low: float, high: float) -> list[tuple[float, bool]]:
    """(value, accepted) at each bound and one double beyond it; an open bound is refused itself."""
    r = SETTING_RANGES[name]
    return [(low, not r.min_open), (high, not r.max_open),
            (math.nextafter(low, -math.inf), False), (math.nextafter(high, math.inf), False)]


def _context(name: str, value: float = math.nan) -> dict[str, float]:
    """Other settings a bound depends on: the Rao-Blackwellised filter needs positive spreads; a
    mounting code needs the other two codes that make a rotation with it (if any)."""
    if name in MOUNT_SETTINGS:
        k = MOUNT_SETTINGS.index(name)
        for codes in itertools.product((-3, -2, -1, 1, 2, 3), repeat=3):
            if codes[k] == value and mounting_problem(codes) is None:
                return {n: float(c) for n, c in zip(MOUNT_SETTINGS, codes) if n != name}
    return {"pf_rao_blackwell": 0.0} if name in RAO_BLACKWELL_POSITIVE else {}


def _declared_ranges(xml: str) -> dict[str, tuple[float, float]]:
    """name -> (min, max) of every variable with min/max attributes in a modelDescription.xml."""
    ranges = {}
    for element in ET.fromstring(xml).iter():
        typed = element if "min" in element.attrib else next((c for c in element if "min" in c.attrib), None)
        if typed is not None and "name" in element.attrib:
            ranges[element.attrib["name"]] = (float(typed.attrib["min"]), float(typed.attrib["max"]))
    return ranges


@pytest.mark.parametrize("fmi_version", [2, 3])
def test_model_description_min_max_are_the_c_limits(fmi_version):
    declared = _declared_ranges(model_description_xml({}, "guid", "test", [], fmi_version))
    numeric = {n for n, r in SETTING_RANGES.items() if r.type != "Boolean"}
    assert set(declared) == numeric
    wrong = {}
    for name, (low, high) in declared.items():
        assert (low, high) == (SETTING_RANGES[name].min, SETTING_RANGES[name].max)
        for value, accepted in _bound_cases(name, low, high):
            ok, message = _c_accepts({**_context(name, value), name: value})
            if ok != accepted or (not ok and name not in message):
                wrong[f"{name}={value!r}"] = message or "accepted"
    assert wrong == {}


def test_c_refuses_booleans_other_than_0_1_and_integers_not_whole():
    for name, r in SETTING_RANGES.items():
        if r.type == "Boolean":
            assert [_c_accepts({name: v})[0] for v in (0.0, 1.0, 0.5, 2.0, math.nan)] == [True] * 2 + [False] * 3
        elif r.type == "Integer":
            assert not _c_accepts({**_context(name), name: r.min + 0.5})[0], name


def test_rao_blackwell_filter_refuses_zero_hard_iron_spreads_in_c():
    for name in RAO_BLACKWELL_POSITIVE:
        assert SETTING_RANGES[name].min == 0.0
        assert not _c_accepts({"pf_rao_blackwell": 1.0, name: 0.0})[0]


def _define(header: str, name: str) -> float:
    """Value of `#define name value` in sources/header."""
    text = (SOURCES / header).read_text()
    return float(re.search(rf"#define {name}\s+\(?([-\d.e]+)\)?", text).group(1))


def test_physical_bounds_are_the_runtime_and_loader_limits():
    assert (model_checks.TEMP_MIN_C, model_checks.TEMP_MAX_C) == (_define("ImuGuard.h", "IMU_GUARD_TEMP_MIN"),
                                                                  _define("ImuGuard.h", "IMU_GUARD_TEMP_MAX"))
    assert model_checks.FULL_SCALE["gyr"] == _define("ImuGuard.h", "IMU_GUARD_GYR_LIMIT")
    assert model_checks.FULL_SCALE["acc"] == _define("ImuGuard.h", "IMU_GUARD_ACC_LIMIT")
    assert model_checks.MAG_SATURATION_FACTOR == _define("ImuGuard.h", "IMU_GUARD_MAG_SATURATION")
    assert (FIELD_NORM_MIN_UT, FIELD_NORM_MAX_UT) == (io.MAG_MEDIAN_NORM_MIN_UT, io.MAG_MEDIAN_NORM_MAX_UT)
    assert sidecar.RATE_MAX_HZ * io.MIN_MEDIAN_STEP_S == pytest.approx(1.0, rel=1e-12)


# ----------------------------------------------------------------------------- --param


@pytest.mark.parametrize("param, needle", [
    ("pf_particles=4294967298", "2..512"),          # became 2 particles (int32 wrap)
    ("pf_particles=2.9", "not a whole number"),     # became 2
    ("enable_pf=0.5", "0 or 1"),                    # switched the filter on
    ("enable_pf=nan", "NaN"),
    ("enable_thermal=2", "0 or 1"),
    ("declination=1e300", "[-3.141593, 3.141593] rad"),
    ("field_norm=44700", "if that is 44700 nT, give 44.7 µT"),   # nT given as µT
    ("field_dip=60", "if that is 60 deg, give 1.047198 rad"),      # degrees given as rad
    ("attitude_mode=0.5", "not a whole number"),
    ("no_such_setting=1", "unknown setting"),
])
def test_param_refuses_nonsense_with_one_line_naming_it(capsys, param, needle):
    with pytest.raises(SystemExit) as exit_:
        main(["run", "missing.fmu", "missing.csv", "--out", "out.csv", "--param", param])
    err = capsys.readouterr().err.strip().splitlines()
    assert exit_.value.code == 2
    assert param in err[-1] and needle in err[-1], err


def test_param_in_range_is_taken_as_the_runtime_float(capsys):
    assert _param("pf_particles=64") == ("pf_particles", 64.0)
    assert _param("enable_pf=1") == ("enable_pf", 1.0)
    assert _param("declination=0.05") == ("declination", 0.05)
    assert capsys.readouterr().err == ""


def test_declination_that_looks_like_degrees_is_taken_with_a_warning_in_degrees(capsys):
    assert _param("declination=2.5") == ("declination", 2.5)
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "declination" in err and "143.2 deg" in err and "0.04363323 rad" in err


# ----------------------------------------------------------------------------- model.json


def _artefact_doc(tmp_path: Path) -> dict:
    """The JSON document of a valid identity artefact."""
    artefact = ModelArtefact(seed=1, thermal={k: ThermalModel.identity() for k in ("gyr", "acc", "mag")},
                             settings={}, libraries={})
    return json.loads(artefact.save(tmp_path / "model.json").read_text())


def _term(coefficient: float) -> dict:
    return {"name": "t", "target": "gyr_x", "a": "temp", "b": None, "coefficient": coefficient,
            "lo": 0.0, "hi": 50.0}


BAD_ARTEFACTS = {
    "enabled 'no'": (lambda d: d["thermal"]["gyr"].update(enabled="no"), "'thermal.gyr.enabled' is 'no'"),
    "enabled 2": (lambda d: d["thermal"]["acc"].update(enabled=2), "'thermal.acc.enabled' is 2"),
    "A = 0": (lambda d: d["thermal"]["acc"].update(A=[[0.0] * 3] * 3), "'thermal.acc.A' has singular values 0..0"),
    "A = -I": (lambda d: d["thermal"]["mag"].update(A=[[-1.0, 0, 0], [0, -1.0, 0], [0, 0, -1.0]]),
               "'thermal.mag.A' has a negative determinant"),
    "A ill-conditioned": (lambda d: d["thermal"]["gyr"].update(A=[[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1e-9]]),
                          "'thermal.gyr.A' has singular values"),
    "A in g": (lambda d: d["thermal"]["acc"].update(A=[[9.80665, 0, 0], [0, 9.80665, 0], [0, 0, 9.80665]]),
               "'thermal.acc.A' has singular values 9.807..9.807"),
    "ts 1e-300": (lambda d: d["thermal"]["gyr"].update(ts=1e-300), "'thermal.gyr.ts' is 1e-300 °C"),
    "t0 1e6": (lambda d: d["thermal"]["gyr"].update(t0=1e6), "'thermal.gyr.t0' is 1e+06 °C"),
    "bias 1e300": (lambda d: d["thermal"]["acc"].update(degree=0, g=[[], [], []], b=[[1e300], [0.0], [0.0]]),
                   "'thermal.acc.b' reaches a bias of 1e+300 m/s²"),
    "term coefficient 1e300": (lambda d: d.update(terms=[_term(1e300)]), "terms[0] (t) corrects gyr_x by up to 5e+301"),
    "declination 1e300": (lambda d: d["settings"].update(declination=1e300), "settings: declination is 1e+300 rad"),
    "enable_pf 0.5": (lambda d: d["settings"].update(enable_pf=0.5), "settings: enable_pf is 0.5"),
    "pf_particles 2.9": (lambda d: d["settings"].update(pf_particles=2.9), "settings: pf_particles is 2.9"),
}


@pytest.mark.parametrize("case", BAD_ARTEFACTS)
def test_artefact_refuses_nonsense_naming_the_file_and_the_value(tmp_path, case):
    doc = _artefact_doc(tmp_path)
    change, needle = BAD_ARTEFACTS[case]
    change(doc)
    path = tmp_path / "model.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(ModelError) as error:
        load_artefact(path)
    message = str(error.value)
    assert message.startswith(str(path)) and needle in message and "\n" not in message, message


def test_artefact_accepts_flags_and_terms_within_bounds(tmp_path):
    doc = _artefact_doc(tmp_path)
    doc["thermal"]["gyr"]["enabled"] = 0
    doc["settings"].update(enable_pf=True, pf_particles=64)
    doc["terms"] = [_term(0.01)]
    (tmp_path / "model.json").write_text(json.dumps(doc))
    artefact = load_artefact(tmp_path / "model.json")
    assert not artefact.thermal["gyr"].enabled and artefact.settings["enable_pf"] == 1.0


def test_build_fmu_refuses_a_model_with_nonsense_in_one_line(tmp_path, capsys):
    doc = _artefact_doc(tmp_path)
    doc["settings"]["declination"] = 1e300
    (tmp_path / "model.json").write_text(json.dumps(doc))
    fails(capsys, ["build-fmu", "--model", str(tmp_path / "model.json"), "--out", str(tmp_path / "x.fmu")],
          "model.json", "declination is 1e+300 rad")
    assert not (tmp_path / "x.fmu").exists()


# ----------------------------------------------------------------------------- sidecar


def _recording(tmp_path: Path, meta_change) -> Path:
    """A tiny valid recording whose sidecar is changed by meta_change(meta)."""
    path = tmp_path / "rec.csv"
    rows = ["t,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z,mag_x,mag_y,mag_z,temp"]
    rows += [f"{k / 100:.2f},0,0,0,0,0,-9.81,20,0,40,25" for k in range(20)]
    path.write_text("\n".join(rows) + "\n")
    meta = {"format": "imu-csv/1", "rate_hz": 100.0, "reference": "none",
            "earth_field": {"norm_ut": 44.7, "dip_deg": 63.4, "declination_deg": 2.0}}
    meta_change(meta)
    (tmp_path / "rec.json").write_text(json.dumps(meta))
    return path


BAD_SIDECARS = {
    "rate_hz '100 Hz'": (lambda m: m.update(rate_hz="100 Hz"), "'rate_hz' is '100 Hz'"),
    "rate_hz 1e9": (lambda m: m.update(rate_hz=1e9), "'rate_hz' is 1000000000.0"),
    "norm_ut in nT": (lambda m: m["earth_field"].update(norm_ut=44700.0), "'earth_field.norm_ut' is 44700.0"),
    "dip_deg 1e300": (lambda m: m["earth_field"].update(dip_deg=1e300), "'earth_field.dip_deg' is 1e+300"),
    "declination_deg 400": (lambda m: m["earth_field"].update(declination_deg=400), "'earth_field.declination_deg' is 400"),
    "reference 'gps'": (lambda m: m.update(reference="gps"), "'reference' is 'gps'"),
    "sensor a number": (lambda m: m.update(sensor=5), "'sensor' is int, expected text"),
}


@pytest.mark.parametrize("case", BAD_SIDECARS)
def test_sidecar_refuses_wrong_types_and_ranges_naming_the_sidecar(tmp_path, case):
    change, needle = BAD_SIDECARS[case]
    path = _recording(tmp_path, change)
    with pytest.raises(DataError) as error:
        io.read_imu_csv(path)
    message = str(error.value)
    assert message.startswith(str(tmp_path / "rec.json")) and needle in message, message


def test_sidecar_within_ranges_is_read(tmp_path):
    data = io.read_imu_csv(_recording(tmp_path, lambda m: m["earth_field"].update(norm_ut=None)))
    assert data.meta["rate_hz"] == 100.0
