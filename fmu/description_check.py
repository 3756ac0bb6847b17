"""Does an FMU's modelDescription.xml describe what its code implements?

An importer sets and reads variables only through the value references, types and start values
that modelDescription.xml declares; a description whose value references of gyr_x and gyr_y are
swapped passed fmpy's and fmutool's checks, since both only check that the description is
well-formed. Two checks close that gap:

`description_problems` (static) compares every variable of the description (name,
valueReference, causality, variability, type, unit, start, min, max) with what the FMU's code
says, from two sides: the variable table the build generated the description from
(contract/variables.py, from contract/layout.py) and the archive's own sources — the `ValueReference`
enum, `VR_IS_BOOLEAN` / `VR_IS_INTEGER` and `VR_TIME` of sources/config.h, and the parameter start
values compiled into the binary (`IMU_SETTING_DEFAULTS` of sources/ImuCoefficientsData.h, in
contract.layout.SETTINGS order); the coefficient parameters (contract/coefficient_parameters.py: FMI 3 one
array per block, FMI 2 one scalar per coefficient) against config.h's `VR_COEFFICIENTS` /
`VR_COEFFICIENT_BLOCKS` and, as start values, the coefficients compiled in (`IMU_COEFFICIENT_DATA`). config.h is hand-written and pinned to the table by
tests/test_fmu.py; model.c maps a value reference to an array index from its groups, which
compile-time checks tie to ImuLayout.h.

`behaviour_problems` (behavioural) asks the binary itself, because a binary-only FMU or edited
sources could still lie: it instantiates the FMU, reads every input and parameter at the
description's value reference with the description's type and compares the value with the
description's start, then holds each raw triad input (gyr_x .. mag_z) at its start value plus a
step and requires that the output the description names for its corrected value (rate_x follows
gyr_x, accel_x acc_x, field_x mag_x) moves more than the other two outputs of that triad. That
catches a swap of inputs, of triad outputs, and of parameters whose start values differ. It is
cheap (a baseline and 9 stepped runs of HOLD_STEPS = 102 steps from a saved FMU state: about
0.02 s) and robust: calibration matrices are near the identity (cross-axis terms of a few per
cent), every step stays far inside the input guard's limits (sources/ImuGuard.h), and holding the
input longer than the largest time-alignment lag makes the outcome independent of the lag
parameters. The orientation, quaternion, gain and particle-filter outputs have no such one-to-one
input; only the static check covers them.

The shipped reference result did not catch the swap either: fmu.cosim set inputs and read
outputs at our table's value references, not the description's. It now uses the description's
name -> value reference map, so the reference result fails for such a description too.
"""
from __future__ import annotations

import math
import re
import zipfile
from pathlib import Path

from fmpy.fmi1 import FMICallException
from fmpy.fmi3 import FMU3Slave

from fmu.archive import read_description
from fmu.cosim import Stepper, initialised_fmu
from fmu.header import HEADER_NAME, read_header_arrays
from fmu.model_description import FMI3_TYPES, TIME_VALUE_REFERENCE
from contract import coefficient_parameters as cp
from contract.variables import VARIABLES
from contract.errors import ImuFusionError, ModelError, one_line
from contract.layout import INPUTS, OUTPUTS, SETTINGS, TRIAD_ORDER
from contract.ranges import LAG_MAX_S
from contract.mounting import MOUNT_SETTINGS

#: The archive members whose contents the static check reads.
CONFIG_MEMBER = "sources/config.h"
HEADER_MEMBER = f"sources/{HEADER_NAME}"
#: Where each side of the comparison comes from, as the problem lines name it.
DESCRIPTION = "modelDescription.xml"
TABLE = "the variable table (contract/variables.py)"

#: The attributes compared, in the order problems are reported (fmpy's ScalarVariable names).
ATTRIBUTES = ("valueReference", "causality", "variability", "type", "unit", "start", "min", "max")

#: FMI 3's independent variable, declared by every FMI 3 description (not part of the table).
_TIME = {"valueReference": TIME_VALUE_REFERENCE, "causality": "independent", "variability": "continuous",
         "type": "Real", "unit": "s", "start": None, "min": None, "max": None}

#: Table type of each FMI 3 type element.
_TABLE_TYPES = {fmi3: table for table, fmi3 in FMI3_TYPES.items()}

#: Step added to a held raw input [rad/s, m/s², µT]: far above rounding, far inside the guard's
#: limits (100 rad/s, 2000 m/s², a field between 0.02 and 20 field norms).
INPUT_STEPS = {"gyr": 0.1, "acc": 1.0, "mag": 5.0}
#: Communication step [s] and steps each input is held: longer than the largest time-alignment
#: lag (contract.ranges.LAG_MAX_S), so every triad's aligned value is the held one.
HOLD_STEP_S = 0.01
HOLD_STEPS = math.ceil(LAG_MAX_S / HOLD_STEP_S) + 2
#: The raw triad inputs; OUTPUTS[k] is the corrected INPUTS[k] for each of them (contract.layout).
RAW_TRIADS = INPUTS[:3 * len(TRIAD_ORDER)]


def _value(text: str | None, type_name: str) -> float | int | bool | str | None:
    """A start/min/max attribute text as a number of the variable's type (the text itself when it
    is not one, so that it is reported as declared)."""
    if text is None:
        return None
    try:
        if type_name == "Boolean":
            return {"true": True, "1": True, "false": False, "0": False}[text]
        return int(text) if type_name == "Integer" else float(text)
    except (KeyError, ValueError):
        return text


def _typed(value: float | None, type_name: str) -> float | int | None:
    """A table bound as a number of the variable's type (None when undeclared)."""
    if value is None:
        return None
    return int(value) if type_name == "Integer" else float(value)


def _array_start(text: str | None) -> list[float] | str | None:
    """The start of an FMI 3 array variable as its list of values (the text itself when it is not one)."""
    if text is None:
        return None
    try:
        return [float(v) for v in text.split()]
    except ValueError:
        return text


def described_variables(description) -> dict[str, dict]:
    """name -> ATTRIBUTES of every variable of an fmpy ModelDescription (FMI 3 types in the
    table's spelling: Float64 -> Real, Int32 -> Integer; an array's start as a list)."""
    variables = {}
    for v in description.modelVariables:
        type_name = _TABLE_TYPES.get(v.type, v.type)
        bounds = {key: _value(getattr(v, key), type_name) for key in ("start", "min", "max")}
        if getattr(v, "dimensions", None):
            bounds["start"] = _array_start(v.start)
        variables[v.name] = {"valueReference": v.valueReference, "causality": v.causality,
                             "variability": v.variability, "type": type_name, "unit": v.unit, **bounds}
    return variables


def _coefficient_references(fmi_version: int, scalar_base: int, block_base: int) -> dict[str, int]:
    """Coefficient parameter name -> value reference (contract/coefficient_parameters.py) from the two bases."""
    if fmi_version == 3:
        return {b.parameter: block_base + k for k, b in enumerate(cp.BLOCKS)}
    return {cp.scalar_name(b, j): scalar_base + b.offset + j for b in cp.BLOCKS for j in range(b.size)}


def table_attributes(table, fmi_version: int) -> dict[str, dict]:
    """name -> expected ATTRIBUTES of every variable of a variable table (FMI 3 adds `time`); parameter start
    values are left out (the build overrides them). Used for ImuFusion's table and the virtual sensor's."""
    expected = {"time": dict(_TIME)} if fmi_version == 3 else {}
    for v in table:
        attributes = {"valueReference": v.value_reference, "causality": v.causality, "variability": v.variability,
                      "type": v.type, "unit": (v.unit or "1") if v.type == "Real" else None,
                      "min": _typed(v.min, v.type), "max": _typed(v.max, v.type)}
        if v.causality != "parameter":
            attributes["start"] = v.start
        expected[v.name] = attributes
    return expected


def table_variables(fmi_version: int) -> dict[str, dict]:
    """name -> expected ATTRIBUTES from the variable table (FMI 3 adds `time`). Parameter start
    values are left out: the build overrides them with the model's settings."""
    expected = table_attributes(VARIABLES, fmi_version)
    for name, vr in _coefficient_references(fmi_version, cp.FMI2_COEFFICIENT_VR, cp.FMI3_BLOCK_VR).items():
        expected[name] = {"valueReference": vr, "causality": "parameter", "variability": "fixed", "type": "Real",
                          "unit": None, "min": None, "max": None}
    return expected


def config_variables(text: str, fmi_version: int) -> dict[str, dict]:
    """name -> valueReference and type from the text of sources/config.h: the `vr_<name> = N`
    enum, VR_IS_BOOLEAN / VR_IS_INTEGER (every other variable is Real) and, for FMI 3, VR_TIME."""
    def named_in(macro: str) -> set[str]:
        body = re.search(rf"#define {macro}\(vr\) (.*)", text)
        return set(re.findall(r"vr_(\w+)", body.group(1))) if body else set()
    booleans, integers = named_in("VR_IS_BOOLEAN"), named_in("VR_IS_INTEGER")
    variables = {name: {"valueReference": int(vr),
                        "type": "Boolean" if name in booleans else "Integer" if name in integers else "Real"}
                 for name, vr in re.findall(r"\bvr_(\w+)\s*=\s*(\d+)", text)}
    time = re.search(r"#define VR_TIME (\d+)u?\b", text)
    if fmi_version == 3 and time:
        variables["time"] = {"valueReference": int(time.group(1)), "type": "Real"}
    bases = [re.search(rf"#define {macro} (\d+)u?\b", text) for macro in ("VR_COEFFICIENTS", "VR_COEFFICIENT_BLOCKS")]
    if all(bases):
        references = _coefficient_references(fmi_version, *(int(b.group(1)) for b in bases))
        variables.update({name: {"valueReference": vr, "type": "Real"} for name, vr in references.items()})
    return variables


def header_variables(text: str, fmi_version: int) -> dict[str, dict]:
    """name -> start of every parameter, from the IMU_SETTING_DEFAULTS array compiled into the
    binary (text of sources/ImuCoefficientsData.h; contract.layout.SETTINGS order), typed by the
    table (Integer and Boolean parameters are stored as whole numbers), and of every coefficient
    parameter, from the IMU_COEFFICIENT_DATA array."""
    coefficients, settings, _ = read_header_arrays(text)
    if len(settings) != len(SETTINGS):
        raise ModelError(f"{HEADER_NAME}: {len(settings)} parameter start values, expected {len(SETTINGS)}")
    types = {v.name: v.type for v in VARIABLES}
    starts = {}
    for (name, _), value in zip(SETTINGS, settings):
        start = bool(value) if types[name] == "Boolean" else int(value) if types[name] == "Integer" else float(value)
        starts[name] = {"start": start}
    try:
        starts.update({name: {"start": value} for name, value in cp.parameter_values(coefficients, fmi_version).items()})
    except ValueError as e:
        raise ModelError(f"{HEADER_NAME}: {e}") from e
    return starts


def _shown(value) -> str:
    """An attribute value as a problem line shows it."""
    if value is None:
        return "none"
    if isinstance(value, bool):
        return "true" if value else "false"
    return repr(value) if isinstance(value, float) else str(value)


def compare(described: dict[str, dict], sides: dict[str, dict[str, dict]]) -> list[str]:
    """One line per variable and attribute on which the description differs from any side
    (side label -> name -> attributes it knows), naming what the description and every side that
    knows the attribute say; one line per variable that is missing on either side."""
    problems = []
    for name in sorted(set().union(*sides.values()) - described.keys()):
        holders = " and ".join(label for label, side in sides.items() if name in side)
        problems.append(f"{name}: declared by {holders} but not in {DESCRIPTION}")
    for name, declared in described.items():
        if not any(name in side for side in sides.values()):
            problems.append(f"{name}: in {DESCRIPTION} but not in {' nor '.join(sides)}")
            continue
        for key in ATTRIBUTES:
            said = {label: side[name][key] for label, side in sides.items() if key in side.get(name, {})}
            if any(value != declared[key] or type(value) is not type(declared[key]) for value in said.values()):
                others = "; ".join(f"{label} says {_shown(value)}" for label, value in said.items())
                problems.append(f"{name}: {DESCRIPTION} says {key} {_shown(declared[key])}; {others}")
    return problems


def description_problems(path: str | Path) -> list[str]:
    """Every mismatch between the model description of the ImuFusion FMU at path (FMI 2 or 3)
    and the variable table and the archive's sources (module docstring), one line each naming
    the variable; an empty list when they all agree. A missing or unreadable source is a problem
    too (every ImuFusion FMU ships its sources)."""
    path = Path(path)
    try:
        description = read_description(path)
        with zipfile.ZipFile(path) as zf:
            missing = [m for m in (CONFIG_MEMBER, HEADER_MEMBER) if m not in zf.namelist()]
            if missing:
                return [f"{path}: the FMU has no {' and no '.join(missing)}: its model description cannot be "
                        "checked against its sources"]
            config = zf.read(CONFIG_MEMBER).decode()
            header = zf.read(HEADER_MEMBER).decode()
        fmi_version = 3 if description.fmiVersion.startswith("3") else 2
        settings = header_variables(header, fmi_version)
    except (ImuFusionError, UnicodeDecodeError, zipfile.BadZipFile) as e:
        return [f"{path}: cannot read the FMU's sources to check its model description ({one_line(str(e))})"]
    sides = {TABLE: table_variables(fmi_version), CONFIG_MEMBER: config_variables(config, fmi_version),
             HEADER_MEMBER: settings}
    return compare(described_variables(description), sides)


def _read(fmu, name: str, declared: dict):
    """The binary's value of variable `name` at the description's value reference, read with the
    description's type (an array as the list of its values); FMICallException when the binary refuses."""
    vr = [declared["valueReference"]]
    if isinstance(declared["start"], list):
        return list(fmu.getFloat64(vr, nValues=len(declared["start"])))
    if declared["type"] == "Boolean":
        return bool(fmu.getBoolean(vr)[0])
    if declared["type"] == "Integer":
        return int((fmu.getInt32 if isinstance(fmu, FMU3Slave) else fmu.getInteger)(vr)[0])
    return float((fmu.getFloat64 if isinstance(fmu, FMU3Slave) else fmu.getReal)(vr)[0])


def _start_problems(fmu, described: dict[str, dict]) -> list[str]:
    """Inputs and parameters whose value in the freshly initialised binary is not the start value
    the description declares (or that the binary refuses to give with the declared type)."""
    problems = []
    for name, declared in described.items():
        if declared["causality"] not in ("input", "parameter"):
            continue
        where = f"{name} (valueReference {declared['valueReference']}, {declared['type']})"
        try:
            value = _read(fmu, name, declared)
        except FMICallException as e:
            problems.append(f"{where}: the binary refuses to give it ({one_line(str(e))})")
            continue
        if value != declared["start"]:
            problems.append(f"{where}: {DESCRIPTION} says start {_shown(declared['start'])}; "
                            f"the binary holds {_shown(value)}")
    return problems


def _held_outputs(stepper: Stepper, sample: list[float]) -> list[float]:
    """The outputs (OUTPUTS order) after holding `sample` (INPUTS order) for HOLD_STEPS steps."""
    for k in range(HOLD_STEPS):
        stepper.set_inputs(sample)
        stepper.do_step(k * HOLD_STEP_S, HOLD_STEP_S)
    return list(stepper.get_outputs())


def _body_axis(sensor_axis: int, described: dict[str, dict]) -> int:
    """The body axis (0..2) that sensor axis `sensor_axis` (0..2) becomes under the mounting the
    description declares (start values of mount_x, mount_y, mount_z: body axis i is sensor axis
    |code_i| - 1); the sensor axis itself when the codes are not a mounting (the start check and
    the initialisation report that)."""
    codes = [abs(int(described.get(name, {}).get("start") or 0)) for name in MOUNT_SETTINGS]
    return codes.index(sensor_axis + 1) if sorted(codes) == [1, 2, 3] else sensor_axis


def _follow_problems(fmu, described: dict[str, dict]) -> list[str]:
    """Raw triad inputs whose step does not move, most among its triad's outputs, the output the
    description names for its corrected value (OUTPUTS[k] corrects RAW_TRIADS[k] in the body axis
    the declared mounting turns sensor axis k into)."""
    base = [described[name]["start"] for name in INPUTS]
    stepper = Stepper(fmu)
    start = fmu.getFMUState() if isinstance(fmu, FMU3Slave) else fmu.getFMUstate()
    restore = fmu.setFMUState if isinstance(fmu, FMU3Slave) else fmu.setFMUstate
    reference = _held_outputs(stepper, base)
    problems = []
    for k, name in enumerate(RAW_TRIADS):
        restore(start)
        sample = list(base)
        sample[k] += INPUT_STEPS[TRIAD_ORDER[k // 3]]
        moved = _held_outputs(stepper, sample)
        triad = range(3 * (k // 3), 3 * (k // 3) + 3)
        change = {OUTPUTS[j]: abs(moved[j] - reference[j]) for j in triad}
        follower = OUTPUTS[3 * (k // 3) + _body_axis(k % 3, described)]
        if any(change[follower] <= change[other] for other in change if other != follower):
            moves = ", ".join(f"{out} by {change[out]:.3g}" for out in change)
            problems.append(f"{name}: stepping it (valueReference {described[name]['valueReference']}) should move "
                            f"{follower} most; it moved {moves}")
    (fmu.freeFMUState if isinstance(fmu, FMU3Slave) else fmu.freeFMUstate)(start)
    return problems


def behaviour_problems(path: str | Path) -> list[str]:
    """Every way the binary of the FMU at path contradicts its model description (module
    docstring): a start value it does not hold, a triad input whose corrected output does not
    follow it. One line each, naming the variable; an empty list when the binary agrees."""
    path = Path(path)
    try:
        described = described_variables(read_description(path))
        missing = [name for name in INPUTS + OUTPUTS if name not in described]
        if missing:
            return [f"{path}: {DESCRIPTION} declares no {', '.join(missing)}"]
        with initialised_fmu(path) as fmu:
            return _start_problems(fmu, described) + _follow_problems(fmu, described)
    except (ImuFusionError, FMICallException) as e:
        return [f"{path}: running the FMU to check its model description failed: {one_line(str(e))}"]
