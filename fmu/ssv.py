"""Calibration files: SSP "System Structure Parameter Values" (SSV) files that hold FMU parameter values.

Format: SSV 1.0 from the SSP 1.0 standard (Modelica Association, https://ssp-standard.org/). The root
is an `ssv:ParameterSet` with `version="1.0"`. It holds one `ssv:Parameter` per value, typed `ssv:Real`
(with an optional `unit`), `ssv:Integer` or `ssv:Boolean`, followed by `ssv:Units`. That element
declares every unit the parameters name, as an `ssc:Unit` whose `ssc:BaseUnit` gives the SI exponents
and a factor and offset (value in SI = factor * value + offset, as in FMI 2.0 section 2.2.2). Files
are checked against the standard's XSD, vendored in fmu/schema/ssp/.

Why 1.0 and not SSP 2.0 (2024-12-20): 2.0 keeps the same namespaces and adds `Float64` and array
parameters (`Dimension` elements, space-separated values). But `fmpy.ssp.ssd.read_ssv`, which reads a
parameter set for FMPy, checks files against the 1.0 schema. It rejects `version="2.0"` and array
values.

Arrays: SSV 1.0 only has scalar parameters. An array parameter `name` of n floats is therefore
written as the Real parameters `name[1]` ... `name[n]`, the FMI structured name of each element
(1-based, as in an FMI 2 modelDescription). `read_ssv` reassembles them into a list.
"""
from __future__ import annotations

import math
import numbers
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from fmpy.ssp.ssd import read_ssv as fmpy_read_ssv
from lxml import etree

from contract.errors import DataError, one_line

#: SSV 1.0 namespaces (SSP 1.0, chapters "Common Content" and "System Structure Parameter Values").
SSV_NAMESPACE = "http://ssp-standard.org/SSP1/SystemStructureParameterValues"
SSC_NAMESPACE = "http://ssp-standard.org/SSP1/SystemStructureCommon"
#: The `version` attribute of the ParameterSet written here.
SSV_VERSION = "1.0"
#: The standard's schema of an SSV file (it imports SystemStructureCommon.xsd beside it).
SCHEMA = Path(__file__).resolve().parent / "schema" / "ssp" / "SystemStructureParameterValues.xsd"

#: The attributes of ssc:BaseUnit in schema order: the exponents of the SI base units (and of rad),
#: then factor and offset.
BASE_UNIT_EXPONENTS = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")
BASE_UNIT_ATTRIBUTES = (*BASE_UNIT_EXPONENTS, "factor", "offset")

#: The units of the FMU's parameters. Each maps to its ssc:BaseUnit attributes; absent ones are 0
#: (factor 1). "rad/s/sqrt(Hz)" is missing on purpose: its s exponent (-1/2) is not an integer, so
#: SSP cannot declare it. Write such a parameter without a unit and the FMU's own unit applies.
UNITS: dict[str, dict[str, float]] = {
    "1": {},
    "A": {"A": 1},
    "degC": {"K": 1, "offset": 273.15},
    "m": {"m": 1},
    "m/s2": {"m": 1, "s": -2},
    "rad": {"rad": 1},
    "rad/s": {"rad": 1, "s": -1},
    "s": {"s": 1},
    "1/s": {"s": -1},
    "T": {"kg": 1, "s": -2, "A": -1},
    "uT": {"kg": 1, "s": -2, "A": -1, "factor": 1e-6},
    "V": {"kg": 1, "m": 2, "s": -3, "A": -1},
    "W": {"kg": 1, "m": 2, "s": -3},
}

#: Range of ssv:Integer (xs:int, 32-bit signed).
_INT32 = (-2**31, 2**31 - 1)
#: An FMI structured name of an array element: base name and 1-based index.
_ELEMENT_NAME = re.compile(r"^(?P<base>.+)\[(?P<index>[1-9][0-9]*)\]$")


@dataclass(frozen=True)
class SsvParameter:
    """One parameter value. `value` is a float (ssv:Real), an int (ssv:Integer, 32-bit), a bool
    (ssv:Boolean) or a one-dimensional sequence of floats. A sequence is stored as a tuple and
    written as the Real parameters `name[1]` ... `name[n]`. `unit` names a unit of write_ssv's table
    and applies to Real values only."""

    name: str
    value: float | int | bool | Sequence[float]
    unit: str | None = None
    description: str | None = None

    def __post_init__(self):
        object.__setattr__(self, "value", _checked_value(self.name, self.value))
        if self.unit is not None and not isinstance(self.value, (float, tuple)):
            raise ValueError(f"parameter '{self.name}': a unit applies to Real values only, "
                             f"not to {type(self.value).__name__} {self.value!r}")

    def scalars(self) -> list[tuple[str, float | int | bool]]:
        """(SSV parameter name, value) of each scalar this parameter is written as."""
        if isinstance(self.value, tuple):
            return [(f"{self.name}[{k}]", v) for k, v in enumerate(self.value, start=1)]
        return [(self.name, self.value)]


def _checked_value(name: str, value) -> float | int | bool | tuple[float, ...]:
    """`value` as a bool, int, float or tuple of floats, or a ValueError naming the parameter."""
    if isinstance(value, bool):
        return value
    if isinstance(value, numbers.Integral):
        if not _INT32[0] <= int(value) <= _INT32[1]:
            raise ValueError(f"parameter '{name}': integer {value} is outside the 32-bit range of ssv:Integer")
        return int(value)
    if isinstance(value, numbers.Real):
        return _finite(name, value)
    if isinstance(value, Iterable) and not isinstance(value, (str, bytes)):
        elements = list(value)
        if not elements:
            raise ValueError(f"parameter '{name}': an array needs at least one element")
        bad = [e for e in elements if isinstance(e, bool) or not isinstance(e, numbers.Real)]
        if bad:
            raise ValueError(f"parameter '{name}': array elements must be real numbers, got {bad[0]!r}")
        return tuple(_finite(name, e) for e in elements)
    raise ValueError(f"parameter '{name}': unsupported value {value!r} "
                     "(a float, an int, a bool or a sequence of floats)")


def _finite(name: str, value: numbers.Real) -> float:
    """`value` as a float, or a ValueError naming the parameter if it is infinite or NaN."""
    number = float(value)
    if not math.isfinite(number):
        raise ValueError(f"parameter '{name}': value {number!r} is not finite")
    return number


def _value_text(value: float | int | bool) -> str:
    """The XML text of a scalar: repr of a float (shortest text that reads back to the same double,
    valid as xs:double), decimal of an int, true/false of a bool."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    return repr(value)


def _unit_table(units: Mapping[str, Mapping] | None) -> dict[str, dict]:
    """UNITS with `units` added (or replacing entries of the same name), each entry checked."""
    table = {**UNITS, **(units or {})}
    for name, base in table.items():
        unknown = set(base) - set(BASE_UNIT_ATTRIBUTES)
        if unknown:
            raise ValueError(f"unit '{name}': unknown BaseUnit attribute(s) {', '.join(sorted(unknown))} "
                             f"(allowed: {', '.join(BASE_UNIT_ATTRIBUTES)})")
        for key in BASE_UNIT_EXPONENTS:
            if key in base and (isinstance(base[key], bool) or not isinstance(base[key], numbers.Integral)):
                raise ValueError(f"unit '{name}': exponent {key}={base[key]!r} is not an integer")
        for key in ("factor", "offset"):
            if key in base and (not isinstance(base[key], numbers.Real) or not math.isfinite(base[key])):
                raise ValueError(f"unit '{name}': {key}={base[key]!r} is not a finite number")
    return table


def _base_unit_attributes(base: Mapping[str, float]) -> dict[str, str]:
    """ssc:BaseUnit attributes in schema order, omitting the defaults (exponent 0, factor 1, offset 0)."""
    defaults = {"factor": 1.0, "offset": 0.0}
    attributes = {}
    for key in BASE_UNIT_ATTRIBUTES:
        value = base.get(key)
        if value is None or value == defaults.get(key, 0):
            continue
        attributes[key] = str(int(value)) if key in BASE_UNIT_EXPONENTS else repr(float(value))
    return attributes


def _ssv(tag: str) -> str:
    return f"{{{SSV_NAMESPACE}}}{tag}"


def _ssc(tag: str) -> str:
    return f"{{{SSC_NAMESPACE}}}{tag}"


def _parameter_element(parent, name: str, value, unit: str | None, description: str | None) -> None:
    """Append an ssv:Parameter holding one scalar to `parent`."""
    parameter = etree.SubElement(parent, _ssv("Parameter"), name=name)
    if description is not None:
        parameter.set("description", description)
    kind = "Boolean" if isinstance(value, bool) else "Integer" if isinstance(value, int) else "Real"
    typed = etree.SubElement(parameter, _ssv(kind), value=_value_text(value))
    if unit is not None:
        typed.set("unit", unit)


def ssv_document(parameters: Sequence[SsvParameter], name: str, description: str | None = None,
                 units: Mapping[str, Mapping] | None = None,
                 annotations: Mapping[str, etree._Element] | None = None) -> bytes:
    """The UTF-8 bytes of an SSV 1.0 file. Parameters appear in the given order (arrays expanded to
    `name[k]`). Only the units they use are declared, sorted by name. `annotations`: annotation type (reverse
    domain name, SSP 1.0 "Annotations") -> the one element it holds, in ssc:Annotations. The same arguments
    always give the same bytes. Raises ValueError for a unit missing from the table (UNITS plus `units`),
    naming the parameter, and for a name that occurs twice (the SSV standard requires unique names)."""
    table = _unit_table(units)
    root = etree.Element(_ssv("ParameterSet"), nsmap={"ssv": SSV_NAMESPACE, "ssc": SSC_NAMESPACE})
    root.set("version", SSV_VERSION)
    root.set("name", name)
    if description is not None:
        root.set("description", description)
    elements = etree.SubElement(root, _ssv("Parameters"))
    seen: set[str] = set()
    used: set[str] = set()
    for parameter in parameters:
        if parameter.unit is not None and parameter.unit not in table:
            raise ValueError(f"parameter '{parameter.name}': unknown unit '{parameter.unit}' "
                             f"(known: {', '.join(sorted(table))})")
        for scalar_name, value in parameter.scalars():
            if scalar_name in seen:
                raise ValueError(f"parameter '{scalar_name}' occurs twice")
            seen.add(scalar_name)
            _parameter_element(elements, scalar_name, value, parameter.unit, parameter.description)
        if parameter.unit is not None:
            used.add(parameter.unit)
    if used:
        declared = etree.SubElement(root, _ssv("Units"))
        for unit in sorted(used):
            element = etree.SubElement(declared, _ssc("Unit"), name=unit)
            etree.SubElement(element, _ssc("BaseUnit"), _base_unit_attributes(table[unit]))
    if annotations:
        holder = etree.SubElement(root, _ssv("Annotations"))
        for kind, content in annotations.items():
            etree.SubElement(holder, _ssc("Annotation"), type=kind).append(content)
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + etree.tostring(root, encoding="UTF-8", pretty_print=True)


def write_ssv(path, parameters: Sequence[SsvParameter], name: str, description: str | None = None,
              units: Mapping[str, Mapping] | None = None,
              annotations: Mapping[str, etree._Element] | None = None) -> Path:
    """Write the parameter set `name` to `path` as an SSV 1.0 file and return the path. See
    ssv_document for the content and the errors. The document is checked against the vendored XSD and
    our own checks before it is written, so a file is only written when it is valid."""
    path = Path(path)
    document = ssv_document(parameters, name, description, units, annotations)
    problems = _problems(etree.fromstring(document))
    if problems:
        raise ValueError(f"{path}: the parameter set is not a valid SSV file: {'; '.join(problems)}")
    path.write_bytes(document)
    return path


@lru_cache(maxsize=1)
def _schema() -> etree.XMLSchema:
    """The vendored SSV 1.0 schema (loaded once)."""
    return etree.XMLSchema(etree.parse(str(SCHEMA)))


def _parse(path: Path) -> etree._ElementTree:
    """The XML tree of `path`: entities are not expanded and nothing is fetched from the network.
    Raises DataError if the file is missing and etree.XMLSyntaxError if it is not well-formed."""
    if not path.is_file():
        raise DataError(path, "file not found" if not path.exists() else "is not a file")
    return etree.parse(str(path), etree.XMLParser(resolve_entities=False, no_network=True))


def validate_ssv(path) -> list[str]:
    """The problems of the SSV file at `path`; an empty list means the file is valid. Problems are
    (1) malformed XML, (2) violations of the SSP 1.0 XSD (fmu/schema/ssp/), and (3) rules the standard
    states in prose and the XSD does not check: unique parameter names, every unit referenced is
    declared in ssv:Units (and declared once), every Real value finite. Raises DataError if the file
    is missing."""
    path = Path(path)
    try:
        tree = _parse(path)
    except etree.XMLSyntaxError as error:
        return [f"not well-formed XML: {one_line(error)}"]
    return _problems(tree.getroot())


def _problems(root) -> list[str]:
    """Schema violations, then the rules of validate_ssv's (3), of the SSV document `root`."""
    schema = _schema()
    problems = [] if schema.validate(root) else [f"line {e.line}: {one_line(e.message)}" for e in schema.error_log]
    return problems + _rule_problems(root)


def _repeated(names: list[str], what: str) -> list[str]:
    """One problem per name that occurs again after its first occurrence."""
    seen: set[str] = set()
    problems = []
    for name in names:
        if name in seen:
            problems.append(f"{what} '{name}' occurs twice")
        seen.add(name)
    return problems


def _rule_problems(root) -> list[str]:
    """The problems of validate_ssv's (3)."""
    ns = {"ssv": SSV_NAMESPACE, "ssc": SSC_NAMESPACE}
    units = [unit.get("name") for unit in root.iterfind("ssv:Units/ssc:Unit", ns)]
    parameters = list(root.iterfind("ssv:Parameters/ssv:Parameter", ns))
    problems = _repeated(units, "unit") + _repeated([p.get("name") for p in parameters], "parameter")
    for parameter in parameters:
        real = parameter.find("ssv:Real", ns)
        if real is None:
            continue
        name, unit = parameter.get("name"), real.get("unit")
        if unit is not None and unit not in units:
            problems.append(f"parameter '{name}': unit '{unit}' is not declared in ssv:Units")
        problems += _finite_problems(name, real.get("value"))
    return problems


def _finite_problems(name: str, text: str | None) -> list[str]:
    """A problem if `text` is an infinite or NaN xs:double. Text that is not a number at all is
    already reported by the schema."""
    try:
        number = float(text)
    except (TypeError, ValueError):
        return []
    return [] if math.isfinite(number) else [f"parameter '{name}': value {text!r} is not finite"]


def read_ssv(path) -> dict[str, float | int | bool | list[float]]:
    """Parameter name -> value of the SSV file at `path`, read with `fmpy.ssp.ssd.read_ssv`, so values
    are exactly what FMPy applies. FMPy returns each value as text; it is converted by type: Real to
    float (bit-exact), Integer to int, Boolean to bool. The Real parameters `name[1]` ... `name[n]`
    (indices 1..n, all present, and no scalar called `name`) become `name` -> list of n floats, placed
    where `name[1]` was. Raises DataError, naming the file and the problem, if the file is missing,
    is malformed or invalid (see validate_ssv), or has a parameter of another SSV type (String,
    Enumeration, Binary)."""
    path = Path(path)
    problems = validate_ssv(path)
    if problems:
        more = f" (and {len(problems) - 1} more problem(s))" if len(problems) > 1 else ""
        raise DataError(path, f"not a valid SSV file: {problems[0]}{more}")
    values: dict[str, float | int | bool] = {}
    for parameter in fmpy_read_ssv(str(path)).parameters:
        values[parameter.name] = _typed(path, parameter.name, parameter.type, parameter.value)
    return _gather_arrays(values)


def read_annotation(path, kind: str) -> etree._Element | None:
    """The element the annotation of type `kind` holds in the SSV file at `path` (its first), or None.
    Raises DataError if the file is missing or not well-formed."""
    path = Path(path)
    try:
        root = _parse(path).getroot()
    except etree.XMLSyntaxError as error:
        raise DataError(path, f"not well-formed XML: {one_line(error)}") from None
    for annotation in root.iterfind("ssv:Annotations/ssc:Annotation", {"ssv": SSV_NAMESPACE, "ssc": SSC_NAMESPACE}):
        if annotation.get("type") == kind and len(annotation):
            return annotation[0]
    return None


def _typed(path: Path, name: str, kind: str | None, text: str) -> float | int | bool:
    """The Python value of a parameter FMPy read as (`kind`, `text`)."""
    if kind == "Real":
        return float(text)
    if kind == "Integer":
        return int(text)
    if kind == "Boolean":
        return text.strip() in ("true", "1")
    raise DataError(path, f"parameter '{name}' is of type {kind}; calibrations hold Real, Integer or Boolean values")


def _gather_arrays(values: dict[str, float | int | bool]) -> dict[str, float | int | bool | list[float]]:
    """`values` with each complete run of float elements `name[1]` ... `name[n]` replaced by `name` ->
    list. Elements that do not form such a run stay scalars under their own names."""
    indices: dict[str, dict[int, str]] = {}
    for key, value in values.items():
        match = _ELEMENT_NAME.match(key)
        if match and isinstance(value, float):
            indices.setdefault(match["base"], {})[int(match["index"])] = key
    arrays = {base: [found[k] for k in range(1, len(found) + 1)] for base, found in indices.items()
              if base not in values and set(found) == set(range(1, len(found) + 1))}
    first = {keys[0]: base for base, keys in arrays.items()}
    members = {key for keys in arrays.values() for key in keys}
    result: dict[str, float | int | bool | list[float]] = {}
    for key, value in values.items():
        if key in first:
            result[first[key]] = [values[k] for k in arrays[first[key]]]
        elif key not in members:
            result[key] = value
    return result
