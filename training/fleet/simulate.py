"""`imufmu simulate-fleet FLEET.toml --devices N --out DIR --seed S`: N simulated units of one type.

Unit k draws its sensor errors from the population the unit type declares
(training.simulator.population) and is recorded in every calibration and test scenario of the fleet
file. Everything random of unit k comes from numpy's SeedSequence(S, spawn_key=(k,)), so unit k is
the same whatever N is, and the same seed gives the same bytes. Layout:

    DIR/fleet_simulation.json         the fleet: file, seed, units, declared spreads
    DIR/unit_0000/unit.json           the unit's drawn sensor table (its true errors) and seeds
    DIR/unit_0000/calibration/*.csv.gz + .json   calibration recordings (imu-csv/1, with truth)
    DIR/unit_0000/test/*.csv.gz + .json          held-out test recordings (imu-csv/1, with truth)
"""
from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
from tqdm import tqdm

from contract.errors import ScenarioError
from training.data.io import write_imu_csv
from training.fleet.spec import FleetSpec, load_fleet
from training.data.outputs import forget_previous_run
from training.simulator.population import draw_unit, spreads
from training.simulator.scenario import sensor_from_raw
from training.simulator.simulate import simulate

#: Most units one command simulates (each is a folder of a few MB).
MAX_DEVICES = 100_000
#: Sub-folders of a unit folder.
CALIBRATION_DIR, TEST_DIR = "calibration", "test"


def unit_name(k: int) -> str:
    """Folder name of unit k."""
    return f"unit_{k:04d}"


def unit_seeds(seed: int, k: int, recordings: int) -> tuple[int, list[int]]:
    """(seed of unit k's sensor draw, seed of each of its recordings), from SeedSequence(seed,
    spawn_key=(k,)): independent of how many units the fleet has."""
    states = np.random.SeedSequence(seed, spawn_key=(k,)).generate_state(1 + recordings, dtype=np.uint32)
    return int(states[0]), [int(s) for s in states[1:]]


def simulate_unit(spec: FleetSpec, k: int, seed: int, out_dir: Path,
                  scale_parameters: dict[str, float] | None = None) -> Path:
    """Simulate unit k of the fleet into out_dir/unit_XXXX and return that folder.
    scale_parameters {"<triad>.<key>": factor} multiplies drawn parameters (a faulty unit)."""
    scenarios = spec.calibration + spec.test
    draw_seed, recording_seeds = unit_seeds(seed, k, len(scenarios))
    raw = draw_unit(spec.sensor_raw, spec.sensor_path, np.random.default_rng(draw_seed))
    for name, factor in (scale_parameters or {}).items():
        triad, key = name.split(".", 1)
        raw[triad][key] = (np.asarray(raw[triad][key], dtype=float) * factor).tolist()
    raw["name"] = f"{spec.name}_{unit_name(k)}"
    sensor = sensor_from_raw(raw, spec.sensor_path)
    folder = Path(out_dir) / unit_name(k)
    for scenario, rec_seed in zip(scenarios, recording_seeds):
        sub = CALIBRATION_DIR if scenario in spec.calibration else TEST_DIR
        data = simulate(replace(scenario, sensor=sensor), rec_seed)
        (folder / sub).mkdir(parents=True, exist_ok=True)
        write_imu_csv(data, folder / sub / f"{data.name}.csv.gz")
    (folder / "unit.json").write_text(json.dumps(
        {"unit": unit_name(k), "fleet": spec.name, "fleet_seed": seed, "sensor_seed": draw_seed,
         "recording_seeds": dict(zip([s.name for s in scenarios], recording_seeds)),
         "scaled_parameters": scale_parameters or {}, "sensor": raw}, indent=1) + "\n")
    return folder


def simulate_fleet(fleet_path: str | Path, devices: int, out_dir: str | Path, seed: int = 0,
                   progress: bool = True) -> Path:
    """Simulate `devices` units of the fleet file into out_dir; returns out_dir/fleet_simulation.json."""
    if not 1 <= devices <= MAX_DEVICES:
        raise ScenarioError(f"{fleet_path}: --devices must be 1..{MAX_DEVICES}, got {devices}")
    spec = load_fleet(fleet_path)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    forget_previous_run(out_dir, ("fleet_simulation.json",), "fleet_simulation.json",
                        [unit_name(k) for k in range(devices)])
    for k in tqdm(range(devices), desc="units", unit="unit", disable=not progress):
        simulate_unit(spec, k, seed, out_dir)
    summary = out_dir / "fleet_simulation.json"
    summary.write_text(json.dumps(
        {"fleet": spec.name, "file": str(spec.path), "sensor": str(spec.sensor_path), "seed": seed,
         "devices": devices, "units": [unit_name(k) for k in range(devices)],
         "calibration": [s.name for s in spec.calibration], "test": [s.name for s in spec.test],
         "spreads": {name: sigma.tolist() for name, sigma in spreads(spec.sensor_raw, spec.sensor_path).items()}},
        indent=1) + "\n")
    return summary
