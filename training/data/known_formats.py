"""Formats of other tools' example recordings, recognised by their header, with what their header
does not say (units, sample rate) and what the sidecar should say about them.

- x-io Technologies (Fusion's `Examples/Python/sensor_data.csv`, the x-io loggers' sensor CSV):
  `Time (s),Gyroscope X (deg/s),…,Accelerometer X (g),…[,Magnetometer X (uT),…]` — the header names
  every unit, so the format adds only its name and sensor text.
- imucal (mad-lab-fau/imucal `example_data/example_ferraris_session.csv`):
  `n_samples,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z` — a sample counter at 102.4 Hz, gyroscope in
  deg/s, accelerometer in m/s² (imucal's convention; its README and the session's sections file).
"""
from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class KnownFormat:
    """A recognised format: `header` is the exact start of its header; `units` {quantity: unit} for
    what the header does not name; `rate_hz` the rate of its sample counter [Hz] (None: it has a clock)."""

    name: str
    header: tuple[str, ...]
    sensor: str
    units: dict[str, str] = field(default_factory=dict)
    rate_hz: float | None = None


XIO = KnownFormat(
    name="x-io Technologies CSV",
    header=("Time (s)", "Gyroscope X (deg/s)", "Gyroscope Y (deg/s)", "Gyroscope Z (deg/s)",
            "Accelerometer X (g)", "Accelerometer Y (g)", "Accelerometer Z (g)"),
    sensor="x-io Technologies log (the IMU is not named in the file)")

IMUCAL = KnownFormat(
    name="imucal example session",
    header=("n_samples", "gyr_x", "gyr_y", "gyr_z", "acc_x", "acc_y", "acc_z"),
    sensor="imucal example IMU (the model is not named in the file)",
    units={"gyr": "deg/s", "acc": "m/s2"}, rate_hz=102.4)

KNOWN_FORMATS = (XIO, IMUCAL)


def known_format(names: list[str]) -> KnownFormat | None:
    """The known format whose header the column `names` start with, else None."""
    stripped = tuple(n.strip() for n in names)
    for fmt in KNOWN_FORMATS:
        if stripped[:len(fmt.header)] == fmt.header:
            return fmt
    return None
