"""The two-soak acceptance figure of issue 15: trained at the defaults on two static soaks at 13
and 48 °C (scenarios/variants/two_soaks.toml, the mems_grade sensor, seed 0), the largest |rest
bias| per axis of the raw sensor and of the runtime at 5, 30 and 60 °C (below, between and above
the soaks; outside them the models run clamped to the calibrated range). The assertions live in
tests/test_thermal_degree.py; this prints the numbers.

Usage: OMP_NUM_THREADS=1 .venv/bin/python benchmarks/two_soaks.py
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

from test_thermal_degree import EVAL_TEMPS, SCENARIO, rest_bias, static_recording  # noqa: E402
from training.simulator import load_scenario, simulate  # noqa: E402
from training.train import train  # noqa: E402

UNITS = {"gyr": ("°/s", np.degrees(1.0)), "acc": ("m/s²", 1.0)}


def main() -> None:
    scenario = load_scenario(SCENARIO)
    artefact = train([simulate(scenario)], seed=0, progress=False)
    print("| T [°C] | triad | raw | corrected | corrected / raw (largest) |")
    print("|---|---|---|---|---|")
    for temp_c in EVAL_TEMPS:
        bias = rest_bias(artefact, static_recording(scenario, temp_c, seed=int(temp_c) + 100))
        for triad, (unit, factor) in UNITS.items():
            raw, corrected = bias[f"raw_{triad}"], bias[triad]
            cells = [", ".join(f"{v * factor:.4f}" for v in b) for b in (raw, corrected)]
            print(f"| {temp_c:g} | {triad} [{unit}] | {cells[0]} | {cells[1]} | {np.max(corrected / raw):.3f} |")


if __name__ == "__main__":
    main()
