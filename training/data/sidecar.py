"""Declared types and ranges of the imu-csv/1 sidecar fields (ARCHITECTURE.md, 'Canonical dataset').

training/data/io.py calls `check_sidecar` on every sidecar it reads. The earth-field values become the
FMU settings field_norm, field_dip and declination, so their ranges are those settings' ranges
(contract/layout.py SETTING_RANGES) in the sidecar's units: one source for both.
"""
from __future__ import annotations

import math
from pathlib import Path

from contract.errors import DataError
from contract.layout import SETTING_RANGES
from contract.schema import number_text

#: Sample rate [Hz]: at least one sample a day (a thermal soak log), at most 100 kHz (the loader's
#: MIN_MEDIAN_STEP_S of 10 µs, training/data/io.py; pinned by tests/test_value_checks.py).
RATE_MIN_HZ = 1.0 / 86400.0
RATE_MAX_HZ = 1.0e5
#: The reference kinds of imu-csv/1.
REFERENCES = ("optical", "simulated", "static", "none")
#: Free-text fields: a string (or null) when present.
TEXT_FIELDS = ("sensor", "source", "license", "notes")
#: earth_field entry -> (FMU setting it becomes, factor from the sidecar's unit to the setting's).
EARTH_FIELD = {"norm_ut": ("field_norm", 1.0), "dip_deg": ("field_dip", math.pi / 180.0),
               "declination_deg": ("declination", math.pi / 180.0)}


def _is_number(value) -> bool:
    """True for a JSON number (not a bool); NaN and inf included (the range test refuses them)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _rate_problem(rate) -> str | None:
    """Why 'rate_hz' is not a sample rate in Hz, or None (absent is fine)."""
    if rate is None:
        return None
    if not _is_number(rate) or not RATE_MIN_HZ <= rate <= RATE_MAX_HZ:
        return (f"sidecar 'rate_hz' is {rate!r}, expected a number of Hz in "
                f"[{number_text(RATE_MIN_HZ)}, {number_text(RATE_MAX_HZ)}]")
    return None


def _earth_field_problem(field) -> str | None:
    """Why 'earth_field' is not {norm_ut [µT], dip_deg [°], declination_deg [°]} within the ranges
    of the settings they become, or None (absent entries and null values are unknown, not wrong)."""
    if field is None:
        return None
    if not isinstance(field, dict):
        return f"sidecar 'earth_field' is {type(field).__name__}, expected an object {{norm_ut, dip_deg, declination_deg}}"
    for key, (setting, factor) in EARTH_FIELD.items():
        value = field.get(key)
        if value is None:
            continue
        r = SETTING_RANGES[setting]
        if not _is_number(value) or not r.min <= value * factor <= r.max:
            unit = "µT" if factor == 1.0 else "deg"
            return (f"sidecar 'earth_field.{key}' is {value!r}, expected a number of {unit} in "
                    f"[{number_text(r.min / factor)}, {number_text(r.max / factor)}]")
    return None


def check_sidecar(side: Path, meta: dict) -> None:
    """DataError naming the sidecar file and the first field of the wrong type or out of range."""
    reference = meta.get("reference")
    if reference is not None and reference not in REFERENCES:
        raise DataError(side, f"sidecar 'reference' is {reference!r}, expected one of {', '.join(REFERENCES)}")
    for key in TEXT_FIELDS:
        if not isinstance(meta.get(key, ""), (str, type(None))):
            raise DataError(side, f"sidecar '{key}' is {type(meta[key]).__name__}, expected text")
    problem = _rate_problem(meta.get("rate_hz")) or _earth_field_problem(meta.get("earth_field"))
    if problem:
        raise DataError(side, problem)
