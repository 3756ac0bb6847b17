"""IMU simulator: scenario files (TOML) -> trajectories with exact truth -> sensor errors.

Public API: `load_scenario`, `simulate`, `simulate_to_dir`, and the types they return.
"""
from .earth import GRAVITY_NED, STANDARD_GRAVITY, EarthField
from .scenario import Scenario, load_scenario
from .sensors import REFERENCE_TEMP_C, MagDistortion, SensorModel, TriadErrors
from .simulate import simulate, simulate_to_dir

__all__ = ["EarthField", "GRAVITY_NED", "MagDistortion", "REFERENCE_TEMP_C", "STANDARD_GRAVITY",
           "Scenario", "SensorModel", "TriadErrors", "load_scenario", "simulate",
           "simulate_to_dir"]
