"""Checks of values against their declared type and range (contract/layout.py SETTING_RANGES).

One place decides whether a setting value is acceptable: `imufmu run --param`, the model artefact
loader and the FMU's modelDescription.xml all use contract.layout.SETTING_RANGES, and
tests/test_value_checks.py pins the C runtime's ImuPipelineSettingsCheck to the same table.
Messages name the setting, the value (plain numbers) and the declared range in the setting's unit.
"""
from __future__ import annotations

import math

from contract.layout import SETTING_RANGES
from contract.ranges import SettingRange

#: Message spelling of the FMI unit names of contract.layout.SETTING_RANGES (the others as they are).
_UNIT_TEXT = {"uT": "µT", "m/s2": "m/s²", "rad/s/sqrt(Hz)": "rad/s/√Hz"}
#: Units a value is commonly given in by mistake, per FMI unit: (name, factor to that unit).
MISTAKEN_UNITS = {"rad": (("deg", math.pi / 180.0),), "rad/s": (("deg/s", math.pi / 180.0),),
                  "uT": (("nT", 1e-3), ("G", 100.0))}


def _unit_suffix(name: str, ascii_only: bool = False) -> str:
    """' µT' etc.: the unit of setting `name` as written after a number ('' when dimensionless);
    ascii_only: its FMI spelling (' uT'), for the C runtime's messages."""
    unit = SETTING_RANGES[name].unit
    return f" {unit if ascii_only else _UNIT_TEXT.get(unit, unit)}" if unit else ""


def number_text(x: float) -> str:
    """A number as plain short text: whole numbers in full, others to 7 significant digits."""
    x = float(x)
    return str(int(x)) if x.is_integer() and abs(x) < 1e16 else f"{x:.7g}"


def range_text(name: str, ascii_only: bool = False) -> str:
    """The declared range of setting `name`, e.g. '[-3.141593, 3.141593] rad' or '2..512';
    ascii_only: units in their FMI spelling (the C runtime's messages)."""
    r = SETTING_RANGES[name]
    if r.type == "Boolean":
        return "0 or 1"
    if r.type == "Integer":
        return f"a whole number in {int(r.min)}..{int(r.max)}{' other than 0' if r.nonzero else ''}"
    return (f"{'(' if r.min_open else '['}{number_text(r.min)}, {number_text(r.max)}"
            f"{')' if r.max_open else ']'}{_unit_suffix(name, ascii_only)}")


def _within(value: float, r: SettingRange) -> bool:
    """True if value lies in the declared range (open bounds excluded)."""
    above = value > r.min if r.min_open else value >= r.min
    below = value < r.max if r.max_open else value <= r.max
    return above and below and not (r.nonzero and value == 0.0)


def setting_problem(name: str, value) -> str | None:
    """Why `value` is not acceptable for setting `name` (one line), or None; an unknown name is a problem.

    A JSON/Python bool is accepted for a Boolean setting only."""
    if name not in SETTING_RANGES:
        return f"unknown setting '{name}' (known: {', '.join(SETTING_RANGES)})"
    r = SETTING_RANGES[name]
    if isinstance(value, bool):
        return None if r.type == "Boolean" else f"{name} is {value}, expected {range_text(name)}"
    if not isinstance(value, (int, float)) or isinstance(value, complex):
        return f"{name} is {value!r}, expected a number: {range_text(name)}"
    value = float(value)
    if math.isnan(value):
        return f"{name} is NaN, expected {range_text(name)}"
    if r.type in ("Boolean", "Integer") and math.isfinite(value) and value != math.floor(value):
        return f"{name} is {number_text(value)} (not a whole number), expected {range_text(name)}"
    if not _within(value, r):
        return (f"{name} is {number_text(value)}{_unit_suffix(name)}, expected {range_text(name)}"
                f"{_unit_hint(name, value)}")
    return None


def _unit_hint(name: str, value: float) -> str:
    """'; if that is 60 deg, give 1.047198 rad' when the refused value would be in range in a unit
    often mistaken for the setting's (MISTAKEN_UNITS), else ''."""
    for other, factor in MISTAKEN_UNITS.get(SETTING_RANGES[name].unit, ()):
        if _within(value * factor, SETTING_RANGES[name]):
            return f"; if that is {number_text(value)} {other}, give {number_text(value * factor)}{_unit_suffix(name)}"
    return ""


def check_setting(name: str, value) -> float:
    """The value as the runtime's float; ValueError (one line naming the setting) if not acceptable."""
    problem = setting_problem(name, value)
    if problem:
        raise ValueError(problem)
    return float(value)


def unit_warning(name: str, value: float) -> str | None:
    """A warning when an acceptable value looks like the wrong unit (an angle in degrees given as
    rad): what it was taken as, in degrees, and what the degrees would be in rad. None otherwise."""
    typical = SETTING_RANGES[name].typical
    if typical is None or abs(value) <= typical:
        return None
    return (f"{name} = {number_text(value)}{_unit_suffix(name)} is taken as {math.degrees(value):.1f} deg, "
            f"beyond the usual ±{math.degrees(typical):.0f} deg; if you meant {number_text(value)} deg, "
            f"give {number_text(math.radians(value))} rad")
