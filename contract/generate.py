"""Everything written from the variable table (contract/variables.py), in marked regions of files
that are otherwise written by hand:

- sources/ImuLayout.h: the enums of the runtime's input, output and settings arrays, and the
  declared range of every setting (the C runtime's one range check, ImuPipelineSettingsCheck);
- sources/config.h: the value references, which parameters are Boolean or Integer, VR_COUNT and
  the slot of every value reference in those arrays (model.c's variable lookup); the value references
  of the coefficient parameters, whose blocks go to sources/ImuLayout.h (contract/coefficient_parameters.py);
- sources/sensor/config.h: the same for the virtual sensor's table (contract/sensor_variables.py);
- README.md: the variable table; docs/virtual_sensor.md: the sensor's; docs/fmu.md: the parameters' types, ranges and defaults, and the
  coefficient parameters.

A region runs from a line holding `generated:begin NAME` to one holding `generated:end NAME`
(C comments or HTML comments). `python -m contract.generate` rewrites every region and names the
files it changed; tests/test_generated.py fails when a region is stale.
"""
from __future__ import annotations

import re
import sys
from collections.abc import Callable
from pathlib import Path

from contract import coefficient_parameters as cp
from contract.schema import range_text
from contract.sensor_variables import SENSOR_VARIABLES
from contract.variables import VARIABLES, Variable

ROOT = Path(__file__).resolve().parent.parent

#: C enum constant prefix and the C type name of each array, by causality.
_C_ARRAYS = {"input": ("ImuIn", "ImuInput", "IMU_INPUT_COUNT"),
             "output": ("ImuOut", "ImuOutput", "IMU_OUTPUT_COUNT"),
             "parameter": ("ImuSet", "ImuSetting", "IMU_SETTING_COUNT")}
#: The same for the virtual sensor's arrays (sources/sensor/config.h, contract/sensor_variables.py).
SENSOR_ARRAYS = {"input": ("SensorIn", "SensorInput", "SENSOR_INPUT_COUNT"),
                 "output": ("SensorOut", "SensorOutput", "SENSOR_OUTPUT_COUNT"),
                 "parameter": ("SensorSet", "SensorSetting", "SENSOR_SETTING_COUNT")}
#: model.c's one-letter tag of the array each causality lives in.
_SLOT_TAG = {"input": "i", "output": "o", "parameter": "s"}


def c_name(v: Variable, arrays: dict = _C_ARRAYS) -> str:
    """The C enum constant of v's array slot: the prefix and the name in CamelCase (gyr_x -> ImuInGyrX)."""
    return arrays[v.causality][0] + "".join(part.capitalize() for part in v.name.split("_"))


def _unit_comment(v: Variable) -> str:
    """'/* unit */' of a variable (1 when dimensionless; Integer and Boolean parameters: their type)."""
    unit = v.unit or ("0 or 1" if v.type == "Boolean" else ("whole number" if v.type == "Integer" else "1"))
    return f"/* {unit} */"


def _of(causality: str, table: tuple[Variable, ...] = VARIABLES) -> list[Variable]:
    return [v for v in table if v.causality == causality]


def c_array_enum(causality: str, table: tuple[Variable, ...] = VARIABLES, arrays: dict = _C_ARRAYS) -> str:
    """The typedef enum of one array (value-reference order within the causality); `arrays` names the enum
    prefix, type and count of each causality (the virtual sensor's differ: SENSOR_ARRAYS)."""
    prefix, type_name, count = arrays[causality]
    width = max(len(c_name(v, arrays)) for v in _of(causality, table)) + 1
    lines = ["typedef enum {"]
    lines += [f"    {c_name(v, arrays) + ',':<{width}} {_unit_comment(v)}" for v in _of(causality, table)]
    lines += [f"    {count}", f"}} {type_name};"]
    return "\n".join(lines)


def c_value_references(table: tuple[Variable, ...] = VARIABLES, arrays: dict = _C_ARRAYS, slots: str = "IMU_VR_SLOTS",
                       vrs: tuple[str, str] = ("IMU_INPUT_VRS", "IMU_OUTPUT_VRS")) -> str:
    """config.h: the ValueReference enum, VR_COUNT, VR_IS_BOOLEAN / VR_IS_INTEGER, the slot table `slots` and the
    value references of the inputs and outputs in array order (`vrs`)."""
    lines = ["/** Value references of every model variable. */", "typedef enum {"]
    lines += [f"    vr_{v.name} = {v.value_reference}{',' if k + 1 < len(table) else ''}"
              for k, v in enumerate(table)]
    lines += ["} ValueReference;", "", f"#define VR_COUNT {len(table)}", ""]
    for macro, type_name in (("VR_IS_BOOLEAN", "Boolean"), ("VR_IS_INTEGER", "Integer")):
        names = " || ".join(f"(vr) == vr_{v.name}" for v in table if v.causality == "parameter"
                            and v.type == type_name) or "0"
        lines += [f"/** Parameters of type {type_name} (FMI 3: {'Boolean' if type_name == 'Boolean' else 'Int32'})"
                  f"{'' if type_name == 'Boolean' else ', stored as whole numbers in the settings array'}. */",
                  f"#define {macro}(vr) ({names})"]
    lines += ["", "/** Where each value reference lives: {'i' inputs / 'o' outputs / 's' settings, array index}. */",
              f"#define {slots} {{ \\"]
    lines += [f"    {{'{_SLOT_TAG[v.causality]}', {c_name(v, arrays)}}}{',' if k + 1 < len(table) else ''} \\"
              for k, v in enumerate(table)]
    lines += ["}"]
    for causality, macro in zip(("input", "output"), vrs):
        names = ", ".join(f"vr_{v.name}" for v in _of(causality, table))
        lines += [f"/** The value references of the {causality}s, in {arrays[causality][1]} order. */",
                  f"#define {macro} {{{names}}}"]
    return "\n".join(lines)


def c_coefficient_vrs() -> str:
    """config.h: the value references of the coefficient parameters (contract/coefficient_parameters.py)."""
    return "\n".join([
        "/** FMI 2: value reference of the scalar parameter of coefficient 0; coefficient i has VR_COEFFICIENTS + i. */",
        f"#define VR_COEFFICIENTS {cp.FMI2_COEFFICIENT_VR}u",
        "/** FMI 3: value reference of the array parameter of block 0; block b has VR_COEFFICIENT_BLOCKS + b. */",
        f"#define VR_COEFFICIENT_BLOCKS {cp.FMI3_BLOCK_VR}u"])


def c_coefficient_blocks() -> str:
    """ImuLayout.h: {first index, length, parameter name, problem} of every coefficient block, in array order:
    how the FMU maps its coefficient parameters and how the runtime names a block that does not fit."""
    lines = [f"#define IMU_COEFFICIENT_BLOCK_COUNT {len(cp.BLOCKS)}",
             "/** {first index, length, parameter name, the runtime's message when the block is invalid} of every",
             " *  coefficient block, in array order (ImuCoefficientBlock). */",
             "#define IMU_COEFFICIENT_BLOCKS { \\"]
    lines += [f'    {{{b.offset}, {b.size}, "{b.parameter}", "{cp.problem_text(b)}"}}{"," if k + 1 < len(cp.BLOCKS) else ""} \\'
              for k, b in enumerate(cp.BLOCKS)]
    lines += ["}"]
    return "\n".join(lines)


#: ImuSettingRange flags (sources/ImuLayout.h).
_RANGE_FLAGS = {"min_open": 1, "max_open": 2, "whole": 4, "nonzero": 8}


def range_problem_text(v: Variable) -> str:
    """The C runtime's message for a value of parameter v outside its declared range."""
    prefix = "finite and within " if v.type == "Real" else ""
    return f"{v.name} must be {prefix}{range_text(v.name, ascii_only=True)}"


def c_setting_ranges() -> str:
    """IMU_SETTING_RANGES: {min, max, flags, message} of every setting (ImuSetting order), the
    declared ranges of the table as exact doubles."""
    lines = ["/** Declared range of every setting, in ImuSetting order (ImuSettingRange). */",
             "#define IMU_SETTING_RANGES { \\"]
    params = _of("parameter")
    for k, v in enumerate(params):
        r = v.range
        flags = ((_RANGE_FLAGS["min_open"] if r.min_open else 0) | (_RANGE_FLAGS["max_open"] if r.max_open else 0)
                 | (_RANGE_FLAGS["whole"] if r.type != "Real" else 0) | (_RANGE_FLAGS["nonzero"] if r.nonzero else 0))
        lines.append(f"    {{{float(r.min)!r}, {float(r.max)!r}, {flags}, \"{range_problem_text(v)}\"}}"
                     f"{',' if k + 1 < len(params) else ''} \\")
    lines.append("}")
    return "\n".join(lines)


def sensor_setting_ranges() -> str:
    """SENSOR_SETTING_RANGES: {min, max, whole number, message} of every sensor parameter (SensorSetting order)."""
    params = _of("parameter", SENSOR_VARIABLES)
    lines = ["/** Declared range of every parameter, in SensorSetting order (SensorSettingRange). */",
             "#define SENSOR_SETTING_RANGES { \\"]
    for k, v in enumerate(params):
        r = v.range
        unit = f" {r.unit}" if r.unit else ""
        lines.append(f'    {{{float(r.min)!r}, {float(r.max)!r}, {int(r.type != "Real")}, '
                     f'"{v.name} must be {"finite and " if r.type == "Real" else ""}within [{r.min:.10g}, {r.max:.10g}]{unit}"}}'
                     f"{',' if k + 1 < len(params) else ''} \\")
    lines.append("}")
    return "\n".join(lines)


def markdown_table(table: tuple[Variable, ...] = VARIABLES) -> str:
    """A variable table as Markdown (README.md: ImuFusion's; docs/virtual_sensor.md: the sensor's)."""
    lines = ["| variable | causality | unit | description |", "|---|---|---|---|"]
    for v in table:
        unit = v.unit or "1"
        if v.display_unit:
            unit += f" (shown in {v.display_unit})"
        lines.append(f"| `{v.name}` | {v.causality} | {unit} | {v.description} |")
    return "\n".join(lines)


def ranges_markdown() -> str:
    """The parameters' declared types, ranges and defaults as Markdown (docs/fmu.md).
    ( ) marks a bound that is itself refused."""
    lines = ["| parameter | type | range | default |", "|---|---|---|---|"]
    for v in _of("parameter"):
        lines.append(f"| `{v.name}` | {v.type} | {range_text(v.name)} | {v.default:g} |")
    return "\n".join(lines)


def coefficient_parameters_markdown() -> str:
    """The coefficient parameters (contract/coefficient_parameters.py) as Markdown (docs/fmu.md)."""
    lines = ["| block | FMI 3: Float64 array (value reference) | FMI 2: Real per coefficient (value references) | values |",
             "|---|---|---|---|"]
    for k, b in enumerate(cp.BLOCKS):
        first = cp.FMI2_COEFFICIENT_VR + b.offset
        lines.append(f"| {b.description} | `{b.parameter}` ({cp.FMI3_BLOCK_VR + k}) | `{cp.scalar_name(b, 0)}` … "
                     f"`{cp.scalar_name(b, b.size - 1)}` ({first}–{first + b.size - 1}) | {b.size} |")
    return "\n".join(lines)


#: File (relative to the repository) -> {region name: its text}.
REGIONS: dict[str, dict[str, Callable[[], str]]] = {
    "sources/ImuLayout.h": {"inputs": lambda: c_array_enum("input"), "outputs": lambda: c_array_enum("output"),
                            "settings": lambda: c_array_enum("parameter"), "setting-ranges": c_setting_ranges,
                            "coefficient-blocks": c_coefficient_blocks},
    "sources/config.h": {"value-references": c_value_references, "coefficient-parameters": c_coefficient_vrs},
    "sources/sensor/config.h": {
        "arrays": lambda: "\n\n".join(c_array_enum(c, SENSOR_VARIABLES, SENSOR_ARRAYS) for c in ("input", "output", "parameter")),
        "value-references": lambda: c_value_references(SENSOR_VARIABLES, SENSOR_ARRAYS, "SENSOR_VR_SLOTS",
                                                       ("SENSOR_INPUT_VRS", "SENSOR_OUTPUT_VRS")),
        "setting-ranges": sensor_setting_ranges},
    "README.md": {"variables": markdown_table},
    "docs/virtual_sensor.md": {"sensor-variables": lambda: markdown_table(SENSOR_VARIABLES)},
    "docs/fmu.md": {"parameter-ranges": ranges_markdown, "coefficient-parameters": coefficient_parameters_markdown},
}


def _region_pattern(name: str) -> re.Pattern:
    """A marked region: the begin line, the text, the end line."""
    return re.compile(rf"(^[^\n]*generated:begin {re.escape(name)}\b[^\n]*\n)(.*?)(^[^\n]*generated:end {re.escape(name)}\b)",
                      re.S | re.M)


def rendered(path: str, text: str) -> str:
    """`text` (the file at `path`) with every region of REGIONS[path] regenerated; ValueError when a
    region's markers are missing."""
    for name, make in REGIONS[path].items():
        pattern = _region_pattern(name)
        if not pattern.search(text):
            raise ValueError(f"{path}: no 'generated:begin {name}' ... 'generated:end {name}' region")
        text = pattern.sub(lambda m: m.group(1) + make() + "\n" + m.group(3), text, count=1)
    return text


def stale(root: Path = ROOT) -> list[str]:
    """The files whose regions differ from what the table generates."""
    return [path for path in REGIONS if rendered(path, (root / path).read_text()) != (root / path).read_text()]


def main() -> int:
    """Rewrite every stale file; print what changed."""
    changed = stale()
    for path in changed:
        target = ROOT / path
        target.write_text(rendered(path, target.read_text()))
        print(f"rewrote {path}")
    if not changed:
        print("every generated region is current")
    return 0


if __name__ == "__main__":
    sys.exit(main())
