"""Bias error outside the calibrated temperature range: extrapolated, clamped, continued (issues 15 and 33).

Trains on the two-soak calibration of tests/test_calibrated_range.py (scenarios/variants/
two_soaks.toml with its soaks at 15 and 35 °C, the mems_grade sensor, seed 0), then holds the
simulated sensor still in four poses at -20, 15, 35 and 70 °C and prints, per triad (gyr, acc),
the largest |rest bias| per axis of the raw sensor, of the runtime with the temperature polynomial
extrapolated (the model without its t_range, as before layout version 4), with the temperature
clamped to the calibrated range (thermal_continuation = 0, the default of layout version 4) and with
the polynomials continued along their edge tangent for at most one span (thermal_continuation = 1,
the default since issue 33).

Usage: OMP_NUM_THREADS=1 .venv/bin/python benchmarks/calibrated_range.py
"""
from __future__ import annotations

import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

from test_calibrated_range import OUTSIDE_C, SOAKS_C, two_soak_scenario  # noqa: E402
from test_thermal_degree import rest_bias, static_recording  # noqa: E402
from training.simulator import simulate  # noqa: E402
from training.train import train  # noqa: E402

UNITS = {"gyr": ("°/s", np.degrees(1.0)), "acc": ("m/s²", 1.0)}


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        scenario = two_soak_scenario(Path(tmp))
    artefact = train([simulate(scenario)], seed=0, progress=False)
    extrapolated = replace(artefact, thermal={k: replace(m, t_range=None) for k, m in artefact.thermal.items()})
    print(f"calibrated range: {artefact.thermal['gyr'].t_range} °C, degrees "
          f"{[artefact.thermal[k].degree for k in ('gyr', 'acc', 'mag')]}")
    clamping = replace(artefact, settings={**artefact.settings, "thermal_continuation": 0.0})
    print("| T [°C] | triad | raw | extrapolated | clamped | continued (default) |")
    print("|---|---|---|---|---|---|")
    for temp_c in (OUTSIDE_C[0], *SOAKS_C, OUTSIDE_C[1]):
        data = static_recording(scenario, temp_c, seed=int(temp_c) + 200)
        continued, clamped, before = (rest_bias(a, data) for a in (artefact, clamping, extrapolated))
        for triad, (unit, factor) in UNITS.items():
            cells = [", ".join(f"{v * factor:.3f}" for v in b) for b in
                     (continued[f"raw_{triad}"], before[triad], clamped[triad], continued[triad])]
            print(f"| {temp_c:g} | {triad} [{unit}] | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
