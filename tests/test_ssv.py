"""fmu.ssv: calibration files in the SSP "System Structure Parameter Values" (SSV 1.0) format. Tests
cover bit-exact round trips, validity against the standard's XSD, declared units, the problems
validate_ssv reports, reading by FMPy, deterministic bytes and the error for a malformed file."""
from __future__ import annotations

import struct

import pytest
from fmpy.ssp.ssd import read_ssv as fmpy_read_ssv
from lxml import etree

from contract.errors import DataError
from fmu.ssv import (SCHEMA, SSC_NAMESPACE, SSV_NAMESPACE, UNITS, SsvParameter, read_ssv, validate_ssv,
                     write_ssv)

NS = {"ssv": SSV_NAMESPACE, "ssc": SSC_NAMESPACE}
#: Doubles whose shortest text is awkward: inexact decimals, a subnormal, a negative zero and more
#: digits than a double holds.
AWKWARD = [0.1, 1 / 3, 1e-300, -0.0, 123456789.123456789, 5e-324, -2.5e16]


def _bits(value: float) -> bytes:
    return struct.pack("<d", value)


def _calibration() -> list[SsvParameter]:
    return [
        SsvParameter("gyro_bias", AWKWARD[:3], "rad/s", "gyroscope bias"),
        SsvParameter("hard_iron", [12.5, -0.0, 1e-300], "uT"),
        SsvParameter("acc_gain", 1 / 3, "1"),
        SsvParameter("temp_ref", 25.125, "degC"),
        SsvParameter("scale", 123456789.123456789),
        SsvParameter("pf_particles", -7),
        SsvParameter("enable_pf", True),
        SsvParameter("enable_elm", False),
    ] + [SsvParameter(f"awkward_{k}", v, "m/s2") for k, v in enumerate(AWKWARD)]


@pytest.fixture
def calibration_file(tmp_path):
    return write_ssv(tmp_path / "calibration.ssv", _calibration(), "calibration", "test calibration")


def _edited(path, edit) -> None:
    """Rewrite the XML file `path` after `edit(root)`."""
    tree = etree.parse(str(path))
    edit(tree.getroot())
    tree.write(str(path), xml_declaration=True, encoding="UTF-8")


def test_round_trip_is_bit_exact(calibration_file):
    values = read_ssv(calibration_file)
    assert list(values) == [p.name for p in _calibration()]
    for parameter in _calibration():
        got = values[parameter.name]
        if isinstance(parameter.value, tuple):
            assert isinstance(got, list) and [_bits(v) for v in got] == [_bits(v) for v in parameter.value]
        elif isinstance(parameter.value, float):
            assert type(got) is float and _bits(got) == _bits(parameter.value), parameter.name
        else:
            assert type(got) is type(parameter.value) and got == parameter.value, parameter.name


def test_written_file_is_valid_against_the_ssp_schema(calibration_file):
    assert validate_ssv(calibration_file) == []
    schema = etree.XMLSchema(etree.parse(str(SCHEMA)))
    root = etree.parse(str(calibration_file)).getroot()
    assert schema.validate(root), schema.error_log
    assert root.get("version") == "1.0" and root.get("name") == "calibration"


def test_every_unit_used_is_declared_with_its_si_base_unit(calibration_file):
    root = etree.parse(str(calibration_file)).getroot()
    used = {real.get("unit") for real in root.iterfind("ssv:Parameters/ssv:Parameter/ssv:Real", NS)} - {None}
    declared = {unit.get("name"): unit.find("ssc:BaseUnit", NS).attrib
                for unit in root.iterfind("ssv:Units/ssc:Unit", NS)}
    assert set(declared) == used == {"rad/s", "uT", "1", "degC", "m/s2"}
    assert dict(declared["uT"]) == {"kg": "1", "s": "-2", "A": "-1", "factor": "1e-06"}
    assert dict(declared["degC"]) == {"K": "1", "offset": "273.15"}
    assert dict(declared["rad/s"]) == {"s": "-1", "rad": "1"}
    assert dict(declared["1"]) == {}


def test_array_is_written_as_element_parameters(calibration_file):
    root = etree.parse(str(calibration_file)).getroot()
    names = [p.get("name") for p in root.iterfind("ssv:Parameters/ssv:Parameter", NS)]
    assert names[:3] == ["gyro_bias[1]", "gyro_bias[2]", "gyro_bias[3]"]


def test_fmpy_reads_the_file_with_its_own_validation(calibration_file):
    parameter_set = fmpy_read_ssv(str(calibration_file))  # validates against FMPy's SSP 1.0 schema
    read = {p.name: (p.type, p.value, p.unit) for p in parameter_set.parameters}
    assert read["gyro_bias[2]"][0] == "Real" and _bits(float(read["gyro_bias[2]"][1])) == _bits(1 / 3)
    assert read["gyro_bias[1]"][2] == "rad/s"
    assert _bits(float(read["awkward_3"][1])) == _bits(-0.0)
    assert read["pf_particles"][:2] == ("Integer", "-7")
    assert read["enable_pf"][:2] == ("Boolean", "true")
    assert len(read) == sum(len(p.scalars()) for p in _calibration())


def test_same_input_gives_the_same_bytes(tmp_path):
    first = write_ssv(tmp_path / "a.ssv", _calibration(), "calibration")
    second = write_ssv(tmp_path / "b.ssv", _calibration(), "calibration",
                       units=dict(reversed(list(UNITS.items()))))  # the table's order does not matter
    assert first.read_bytes() == second.read_bytes()


def test_undeclared_unit_is_reported(calibration_file):
    def drop_ut(root):
        unit = root.find("ssv:Units/ssc:Unit[@name='uT']", NS)
        unit.getparent().remove(unit)
    _edited(calibration_file, drop_ut)
    problems = validate_ssv(calibration_file)
    assert problems == [f"parameter 'hard_iron[{k}]': unit 'uT' is not declared in ssv:Units" for k in (1, 2, 3)]
    with pytest.raises(DataError, match="unit 'uT' is not declared"):
        read_ssv(calibration_file)


def test_duplicate_parameter_name_is_reported(calibration_file):
    def duplicate(root):
        parameters = root.find("ssv:Parameters", NS)
        parameters.append(etree.fromstring(etree.tostring(parameters[0])))
    _edited(calibration_file, duplicate)
    assert validate_ssv(calibration_file) == ["parameter 'gyro_bias[1]' occurs twice"]


def test_non_finite_and_schema_violations_are_reported(calibration_file):
    def corrupt(root):
        reals = root.findall("ssv:Parameters/ssv:Parameter/ssv:Real", NS)
        reals[0].set("value", "INF")      # a valid xs:double, but not a calibration value
        reals[1].set("value", "1,5")      # not an xs:double
    _edited(calibration_file, corrupt)
    problems = validate_ssv(calibration_file)
    assert len(problems) == 2
    assert "'1,5' is not a valid value of the atomic type 'xs:double'" in problems[0]
    assert problems[1] == "parameter 'gyro_bias[1]': value 'INF' is not finite"


def test_writer_refuses_what_it_cannot_write(tmp_path):
    with pytest.raises(ValueError, match="parameter 'noise': unknown unit 'rad/s/sqrt\\(Hz\\)'"):
        write_ssv(tmp_path / "x.ssv", [SsvParameter("noise", 0.1, "rad/s/sqrt(Hz)")], "x")
    with pytest.raises(ValueError, match="parameter 'b\\[1\\]' occurs twice"):
        write_ssv(tmp_path / "x.ssv", [SsvParameter("b", [1.0, 2.0]), SsvParameter("b[1]", 3.0)], "x")
    with pytest.raises(ValueError, match="parameter 'bias': value nan is not finite"):
        SsvParameter("bias", [0.0, float("nan")])
    with pytest.raises(ValueError, match="parameter 'n': integer 2147483648 is outside"):
        SsvParameter("n", 2**31)
    with pytest.raises(ValueError, match="parameter 'flag': a unit applies to Real values only"):
        SsvParameter("flag", True, "1")
    assert not (tmp_path / "x.ssv").exists()


def test_extra_units_are_declared(tmp_path):
    path = write_ssv(tmp_path / "g.ssv", [SsvParameter("g", 9.81, "g_n")], "x",
                     units={"g_n": {"m": 1, "s": -2, "factor": 9.80665}})
    unit = etree.parse(str(path)).getroot().find("ssv:Units/ssc:Unit[@name='g_n']/ssc:BaseUnit", NS)
    assert dict(unit.attrib) == {"m": "1", "s": "-2", "factor": "9.80665"}
    assert validate_ssv(path) == []


def test_malformed_file_gives_a_one_line_data_error_naming_it(tmp_path):
    path = tmp_path / "broken.ssv"
    path.write_text('<?xml version="1.0"?>\n<ssv:ParameterSet xmlns:ssv="x">\n<unclosed>\n')
    assert validate_ssv(path)[0].startswith("not well-formed XML: ")
    with pytest.raises(DataError) as raised:
        read_ssv(path)
    message = str(raised.value)
    assert message.startswith(f"{path}: not a valid SSV file: not well-formed XML") and "\n" not in message
    with pytest.raises(DataError, match="missing.ssv: file not found"):
        read_ssv(tmp_path / "missing.ssv")


def test_incomplete_element_run_stays_scalar(tmp_path):
    path = write_ssv(tmp_path / "s.ssv", [SsvParameter("m[2]", 1.5), SsvParameter("k[1]", 3)], "x")
    assert read_ssv(path) == {"m[2]": 1.5, "k[1]": 3}
