"""Small scenario files the tests write: a still start, then one turn about a body axis, then more
segments if given — with the shared mems_grade sensor (scenarios/sensors/mems_grade.toml)."""
from __future__ import annotations

from pathlib import Path

from training.main_job import SCENARIO_DIR

MEMS_GRADE = SCENARIO_DIR / "sensors" / "mems_grade.toml"


def turn_scenario(path: Path, *, axis: str, rate_dps: float, angle_deg: float, hold_s: float, rest_s: float,
                  pitch_deg: float = 0.0, seed: int = 5, declination_deg: float = 3.0, extra: str = "") -> Path:
    """Write to `path` (and return it) a 100 Hz scenario at 25 °C: hold_s [s] still from a pose pitched by
    pitch_deg [°], a turn of angle_deg [°] about body `axis` at rate_dps [°/s] (0.5 s ramps), rest_s [s]
    still, then the TOML segments of `extra`."""
    path.write_text(f'''sensor = "{MEMS_GRADE.as_posix()}"
[scenario]
name = "{path.stem}"
rate_hz = 100.0
seed = {seed}
[earth_field]
norm_ut = 50.0
dip_deg = 60.0
declination_deg = {declination_deg}
[start]
attitude_deg = [0.0, {pitch_deg}, 0.0]
temp_c = 25.0
[[segment]]
type = "hold"
duration_s = {hold_s}
[[segment]]
type = "rotations"
axes = ["{axis}"]
rates_dps = [{rate_dps}]
angle_deg = {angle_deg}
ramp_s = 0.5
rest_s = {rest_s}
''' + extra)
    return path
