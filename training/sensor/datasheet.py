"""Noise parameters of the virtual-sensor FMU from a simulator sensor definition (scenarios/sensors/*.toml): the
white noise density, bias random walk, LSB and range the simulator gives that unit, in the sensor FMU's units.

For a model trained before its noise was characterised (model.json without a "noise" block) or to compare the
closed loop with the simulator's own recordings of the unit (docs/virtual_sensor.md, "Closed loop"): the
figures then are exactly those the evaluation recordings were simulated with.
"""
from __future__ import annotations

import math
import tomllib
from pathlib import Path

from contract.errors import ImuFusionError
from contract.sensor_variables import AXES, noise_parameter_name

#: Per triad: the definition's key suffix of each figure and the factor to the sensor FMU's unit
#: (°/s -> rad/s for the gyro; m/s² and µT as they are).
_KEYS = {"gyr": ("dps", math.pi / 180.0), "acc": ("ms2", 1.0), "mag": ("ut", 1.0)}


def datasheet_noise(path: str | Path) -> dict[str, float]:
    """Sensor FMU parameters (name -> value) from the sensor definition at `path`: per triad and axis the noise
    density (noise_density_<u>_per_sqrt_hz) and bias random walk (bias_walk_<u>_per_sqrt_s), the LSB (lsb_<u>)
    and full scale (range_<u>); a figure the definition omits is 0 (none), as the simulator takes it.
    ImuFusionError naming the file when it cannot be read."""
    try:
        doc = tomllib.loads(Path(path).read_text())
    except (OSError, tomllib.TOMLDecodeError) as e:
        raise ImuFusionError(f"{path}: cannot read the sensor definition ({e})") from None
    out: dict[str, float] = {}
    for triad, (unit, scale) in _KEYS.items():
        table = doc.get(triad, {})
        figures = {"noise_density": table.get(f"noise_density_{unit}_per_sqrt_hz", 0.0),
                   "random_walk": table.get(f"bias_walk_{unit}_per_sqrt_s", 0.0)}
        for figure, value in figures.items():
            for a in range(len(AXES)):
                out[noise_parameter_name(triad, figure, a)] = float(value) * scale
        out[f"{triad}_lsb"] = float(table.get(f"lsb_{unit}", 0.0)) * scale
        out[f"{triad}_full_scale"] = float(table.get(f"range_{unit}", 0.0)) * scale
    return out
