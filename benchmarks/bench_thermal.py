"""Benchmark of the gyro temperature models (training/bench/compare_thermal.py): the tables of
docs/thermal_models.md.

Recordings (one report folder each under OUT):
  plateaus   scenarios/thermal_plateaus.toml (shared sensor), simulated; train on the first
             four plateaus (train_fraction 2/3), validate on the last two
  rate       scenarios/variants/thermal_plateaus_rate.toml (10x temperature-rate bias), same split
  pan        /work/shared/data/pan_thermal/pan_etu_cold_chamber.csv.gz, train on the first 60 %

Usage: python benchmarks/bench_thermal.py {plateaus,rate,pan} --out OUT [--runs N] [--seed N]
       [--bp-epochs N] [--pan-dir DIR]
Each recording is a separate invocation so they can run in parallel on separate cores.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import torch

from training.bench.compare_thermal import compare_thermal
from training.data.io import write_imu_csv
from training.simulator import load_scenario, simulate

ROOT = Path(__file__).resolve().parent.parent
SCENARIOS = {"plateaus": ROOT / "scenarios" / "thermal_plateaus.toml",
             "rate": ROOT / "scenarios" / "variants" / "thermal_plateaus_rate.toml"}
#: Training part of the simulated protocol: six equally long plateau blocks, train on four.
PLATEAU_TRAIN_FRACTION = 2.0 / 3.0
#: Training part of the measured PAN log (issue 4: the first 60 % by time).
PAN_TRAIN_FRACTION = 0.6
PAN_DIR = Path("/work/shared/data/pan_thermal")


def main() -> None:
    """Simulate (or locate) the recording, run the comparison, print the Markdown table."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("recording", choices=["plateaus", "rate", "pan"])
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--runs", type=int, default=50)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--bp-epochs", type=int, default=3000)
    p.add_argument("--pan-dir", type=Path, default=PAN_DIR)
    a = p.parse_args()
    torch.set_num_threads(1)
    out = a.out / a.recording
    out.mkdir(parents=True, exist_ok=True)
    if a.recording == "pan":
        path, fraction = a.pan_dir / "pan_etu_cold_chamber.csv.gz", PAN_TRAIN_FRACTION
    else:
        scenario = load_scenario(SCENARIOS[a.recording])
        path = write_imu_csv(simulate(scenario), out / f"{scenario.name}.csv.gz")
        fraction = PLATEAU_TRAIN_FRACTION
    compare_thermal([path], out, runs=a.runs, seed=a.seed, train_fraction=fraction,
                    bp_epochs=a.bp_epochs, progress=False)
    print((out / "compare_thermal.md").read_text())


if __name__ == "__main__":
    main()
