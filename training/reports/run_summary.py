"""What `imufmu run` tells the user about the outputs it wrote, beyond the FMU's own warnings: the frame
they are in (issue 35: printed first and recorded in the outputs' sidecar JSON), outputs that are NaN
because their sensor is absent, and samples outside the calibrated range."""
from __future__ import annotations

import numpy as np

from contract.layout import OUTPUTS
from contract.mounting import frame_text

#: The outputs by frame (the variable table's descriptions say the same per variable).
BODY_AXES_OUTPUTS = ("rate_*", "accel_*", "field_*", "hard_iron_*", "soft_iron_*")
BODY_ATTITUDE_OUTPUTS = ("roll", "pitch", "yaw", "heading", "q_*")
SENSOR_ATTITUDE_OUTPUTS = ("q_sensor_*",)
#: Format tag of the sidecar JSON beside `imufmu run`'s outputs CSV.
RUN_SIDECAR_FORMAT = "imufmu-run-outputs/1"

#: Output triads and the sensor whose absence makes them NaN (docs/fmu.md, "Absent sensors").
SENSOR_OUTPUTS = {"gyroscope": ("rate_x", "rate_y", "rate_z"),
                  "accelerometer": ("accel_x", "accel_y", "accel_z"),
                  "magnetometer": ("field_x", "field_y", "field_z")}


def frame_lines(codes) -> list[str]:
    """The frame of the outputs of an FMU run with the mounting `codes` (mount_x, mount_y, mount_z), two lines."""
    return [f"frame: {frame_text(codes)}; navigation frame magnetic NED (heading: true north)",
            f"  {', '.join(BODY_AXES_OUTPUTS)} in the body axes; {', '.join(BODY_ATTITUDE_OUTPUTS)}: body -> magnetic "
            f"NED; {', '.join(SENSOR_ATTITUDE_OUTPUTS)}: sensor axes -> magnetic NED (compare a sensor-axes "
            "reference with these)"]


def frame_record(codes, fmu: str, data: str) -> dict:
    """The sidecar JSON of an outputs CSV: what it was run from and which frame each output is in."""
    return {"format": RUN_SIDECAR_FORMAT, "fmu": fmu, "data": data,
            "mounting": [int(c) for c in codes], "frame": frame_text(codes), "navigation": "magnetic NED",
            "quaternions": "Hamilton [w, x, y, z], rotating the named axes into NED (v_nav = q v q*)",
            "body_axes": list(BODY_AXES_OUTPUTS), "body_attitude": list(BODY_ATTITUDE_OUTPUTS),
            "sensor_attitude": list(SENSOR_ATTITUDE_OUTPUTS)}


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
