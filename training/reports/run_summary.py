"""What `imufmu run` tells the user about the outputs it wrote, beyond the FMU's own warnings:
outputs that are NaN because their sensor is absent, and samples outside the calibrated range."""
from __future__ import annotations

import numpy as np

from contract.layout import OUTPUTS

#: Output triads and the sensor whose absence makes them NaN (docs/fmu.md, "Absent sensors").
SENSOR_OUTPUTS = {"gyroscope": ("rate_x", "rate_y", "rate_z"),
                  "accelerometer": ("accel_x", "accel_y", "accel_z"),
                  "magnetometer": ("field_x", "field_y", "field_z")}


def _column(out: np.ndarray, name: str) -> np.ndarray:
    return out[:, OUTPUTS.index(name)]


def absent_notes(out: np.ndarray) -> list[str]:
    """One line per sensor whose corrected outputs are NaN in some samples (absent until then)."""
    notes = []
    for sensor, names in SENSOR_OUTPUTS.items():
        missing = int(np.sum(np.all(np.isnan(out[:, [OUTPUTS.index(n) for n in names]]), axis=1)))
        if missing:
            notes.append(f"{names[0]}..{names[-1][-1]} are NaN in {missing} of {len(out)} samples: the recording has "
                         f"no valid {sensor} input there (absent sensor, docs/fmu.md 'Absent sensors')")
    return notes


def range_note(out: np.ndarray) -> str | None:
    """A line when calibration_valid was 0 in some samples (inputs outside the calibrated range)."""
    outside = int(np.sum(_column(out, "calibration_valid") == 0.0))
    if not outside:
        return None
    return (f"calibration_valid = 0 in {outside} of {len(out)} samples ({100.0 * outside / len(out):.2g} %): "
            "model inputs outside the range they were calibrated on, evaluated clamped (docs/fmu.md 'Calibrated range')")


def run_notes(out: np.ndarray) -> list[str]:
    """Every note about the outputs of one run."""
    note = range_note(out)
    return absent_notes(out) + ([note] if note else [])
