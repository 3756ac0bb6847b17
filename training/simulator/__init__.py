"""IMU simulator: scenario files (TOML) -> trajectories with exact truth -> sensor errors.

Public API: `load_scenario`, `simulate`, `simulate_to_dir`, and the types they return; the Earth's
fields it uses are in training.data.earth.
"""
from training.simulator.scenario import Scenario, load_scenario
from training.simulator.sensors import REFERENCE_TEMP_C, MagDistortion, SensorModel, TriadErrors
from training.simulator.simulate import simulate, simulate_to_dir

__all__ = ["MagDistortion", "REFERENCE_TEMP_C", "Scenario", "SensorModel", "TriadErrors",
           "load_scenario", "simulate", "simulate_to_dir"]
