"""Declared types and ranges of the imu-csv/1 sidecar fields (ARCHITECTURE.md, 'Canonical dataset').

training/data/io.py calls `check_sidecar` on every sidecar it reads. The earth-field values become the
FMU settings field_norm, field_dip and declination, so their ranges are those settings' ranges
(contract/layout.py SETTING_RANGES) in the sidecar's units: one source for both.
"""
from __future__ import annotations

import math
from datetime import datetime
from pathlib import Path

from contract.errors import DataError
from contract.layout import SETTING_RANGES
from contract.mounting import mounting_problem
from contract.schema import number_text
from training.data.earth import GRAVITY_RANGE_MPS2, SITE_ALTITUDE_M

#: Sample rate [Hz]: at least one sample a day (a thermal soak log), at most 100 kHz (the loader's
#: MIN_MEDIAN_STEP_S of 10 µs, training/data/io.py; pinned by tests/test_value_checks.py).
RATE_MIN_HZ = 1.0 / 86400.0
RATE_MAX_HZ = 1.0e5
#: The reference kinds of imu-csv/1 (README.md, 'Data format'): an attitude reference ref_q from motion
#: capture ('optical'), a robot's forward kinematics ('robot') or a GNSS-aided INS ('gnss-ins', whose
#: frame is geographic: true north); a simulator's exact truth; a still log; none.
REFERENCES = ("optical", "robot", "gnss-ins", "simulated", "static", "none")
#: site entry -> accepted range (latitude and longitude in deg; altitude in m or km).
SITE_RANGES = {"latitude_deg": (-90.0, 90.0), "longitude_deg": (-180.0, 360.0),
               "altitude_m": SITE_ALTITUDE_M, "altitude_km": tuple(v / 1000.0 for v in SITE_ALTITUDE_M)}
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


def _gravity_problem(g) -> str | None:
    """Why 'gravity_mps2' is not a local gravity in m/s² (GRAVITY_RANGE_MPS2), or None (absent or null:
    unknown, then the site or standard gravity is used)."""
    lo, hi = GRAVITY_RANGE_MPS2
    if g is None or (_is_number(g) and lo <= g <= hi):
        return None
    return (f"sidecar 'gravity_mps2' is {g!r}, expected the local gravity in m/s² within [{lo:g}, {hi:g}] "
            "(not cm/s², g or ft/s²)")


def _site_problem(site) -> str | None:
    """Why 'site' is not {latitude_deg, longitude_deg, altitude_m or altitude_km, date} within SITE_RANGES,
    or None (absent entries and null values are unknown, not wrong)."""
    if site is None:
        return None
    if not isinstance(site, dict):
        return (f"sidecar 'site' is {type(site).__name__}, expected an object {{latitude_deg, longitude_deg, "
                "altitude_m, date}")
    for key, (lo, hi) in SITE_RANGES.items():
        value = site.get(key)
        if value is not None and not (_is_number(value) and lo <= value <= hi):
            return f"sidecar 'site.{key}' is {value!r}, expected a number in [{lo:g}, {hi:g}]"
    if site.get("altitude_m") is not None and site.get("altitude_km") is not None:
        return "sidecar 'site' gives both altitude_m and altitude_km; give one"
    date = site.get("date")
    if date is not None:
        try:
            datetime.fromisoformat(str(date))
        except ValueError:
            return f"sidecar 'site.date' is {date!r}, expected an ISO date such as 2024-05-17"
    return None


def _mounting_problem(codes) -> str | None:
    """Why 'mounting' is not the codes [mount_x, mount_y, mount_z] of a mounting (contract.mounting), or
    None (absent or null: not declared; train then decides from the data, training.mounting)."""
    if codes is None:
        return None
    if not isinstance(codes, list) or len(codes) != 3 or not all(_is_number(c) for c in codes):
        return (f"sidecar 'mounting' is {codes!r}, expected [mount_x, mount_y, mount_z], three signed sensor axes "
                "such as [1, -2, -3]")
    problem = mounting_problem(codes)
    return None if problem is None else f"sidecar 'mounting' {codes}: {problem}"


def check_sidecar(side: Path, meta: dict) -> None:
    """DataError naming the sidecar file and the first field of the wrong type or out of range."""
    reference = meta.get("reference")
    if reference is not None and reference not in REFERENCES:
        raise DataError(side, f"sidecar 'reference' is {reference!r}, expected one of {', '.join(REFERENCES)}")
    for key in TEXT_FIELDS:
        if not isinstance(meta.get(key, ""), (str, type(None))):
            raise DataError(side, f"sidecar '{key}' is {type(meta[key]).__name__}, expected text")
    problem = (_rate_problem(meta.get("rate_hz")) or _earth_field_problem(meta.get("earth_field"))
               or _gravity_problem(meta.get("gravity_mps2")) or _site_problem(meta.get("site"))
               or _mounting_problem(meta.get("mounting")))
    if problem:
        raise DataError(side, problem)
