"""Beyond the calibrated range on the thermal-plateau protocol (issue 33 item 4): clamped vs continued.

scenarios/thermal_plateaus.toml (the mems_grade sensor, static, 10 Hz): `imufmu train`'s defaults on the
first four plateaus (t < 6000 s: soaks at -10, 7, 19, 32 °C with their +10 °C power-on warm-ups, so the
calibrated range is -10 … 42 °C), then the batch runtime (= the FMU, tests/test_methods.py) on the
45 and 58 °C power-ons (the 900 s powered part of each held-out plateau: 45-55 and 58-68 °C), outside
the range. Printed per power-on: the RMS of the 10 s means of the gyro bias (output - reference) of
the raw sensor, of the runtime with the temperature clamped to the range (thermal_continuation = 0),
with the polynomials continued along their edge tangent (thermal_continuation = 1, the default) and
with the polynomial extrapolated without limit (no recorded range, as before layout version 4), each
with its reduction of the raw bias; and the noise floor: the RMS of the 10 s means of the continued
output on the calibration's own last powered plateau (32 °C), inside the range.

Usage: OMP_NUM_THREADS=1 .venv/bin/python benchmarks/thermal_continuation.py [--seed N] [--window S]
"""
from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from contract.layout import settings_array  # noqa: E402
from training.artefact import coefficients_array, settings_dict  # noqa: E402
from training.runtime import run_batch  # noqa: E402
from training.simulator import load_scenario, simulate  # noqa: E402
from training.train import train  # noqa: E402

SCENARIO = ROOT / "scenarios" / "thermal_plateaus.toml"
#: The protocol's blocks: a 600 s soak then 900 s powered, 1500 s per plateau; training = t < 6000 s.
BLOCK_S, SOAK_S, TRAIN_END_S = 1500.0, 600.0, 6000.0
#: Start [s] of the held-out plateaus (45 and 58 °C) and of the last training plateau (32 °C).
HELD_OUT = {"45 °C power-on": 6000.0, "58 °C power-on": 7500.0}
FLOOR_PLATEAU = 4500.0


def window_rms(t: np.ndarray, bias: np.ndarray, start: float, window_s: float) -> float:
    """RMS [°/s] over axes of the window_s means of bias (N, 3) [rad/s] on the powered part of the
    plateau starting at `start` [s]."""
    sel = (t >= start + SOAK_S) & (t < start + BLOCK_S)
    edges = np.floor((t[sel] - t[sel][0]) / window_s).astype(int)
    means = np.array([bias[sel][edges == k].mean(axis=0) for k in np.unique(edges)])
    return float(np.degrees(np.sqrt(np.mean(means ** 2))))


def runtime_bias(artefact, data) -> np.ndarray:
    """Gyro output minus reference (N, 3) [rad/s] of the batch runtime at the artefact's settings."""
    out = run_batch(coefficients_array(artefact), np.asarray(settings_array(settings_dict(artefact))),
                    data.t, data.inputs())
    return out[:, 0:3] - data.ref_gyr


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0, help="training seed (the scenario's noise seed is its own)")
    parser.add_argument("--window", type=float, default=10.0, help="averaging window [s]")
    args = parser.parse_args()
    data = simulate(load_scenario(SCENARIO))
    artefact = train([data.slice(data.t < TRAIN_END_S)], seed=args.seed, progress=False)
    lo, hi = artefact.thermal["gyr"].t_range
    print(f"calibrated range {lo:.1f} … {hi:.1f} °C; gyro degree {artefact.thermal['gyr'].degree}; "
          f"PSO-BP {'on' if artefact.settings.get('enable_psobp') else 'off'}")
    forms = {"clamped": replace(artefact, settings={**artefact.settings, "thermal_continuation": 0.0}),
             "continued": artefact,
             "extrapolated": replace(artefact, thermal={k: replace(m, t_range=None) for k, m in artefact.thermal.items()})}
    biases = {name: runtime_bias(a, data) for name, a in forms.items()}
    floor = window_rms(data.t, biases["continued"], FLOOR_PLATEAU, args.window)
    print(f"\nnoise floor (32 °C power-on, inside the range, continued): {floor:.4f} °/s "
          f"({args.window:g} s means)\n")
    print(f"| power-on | raw [°/s] | clamped [°/s] (reduction) | continued, default [°/s] (reduction) "
          f"| extrapolated [°/s] (reduction) | continued − clamped [°/s] |")
    print("|---|---|---|---|---|---|")
    for label, start in HELD_OUT.items():
        raw = window_rms(data.t, data.gyr - data.ref_gyr, start, args.window)
        rms = {name: window_rms(data.t, b, start, args.window) for name, b in biases.items()}
        cells = [f"{rms[n]:.4f} ({1.0 - rms[n] / raw:.1%})" for n in forms]
        print(f"| {label} | {raw:.4f} | " + " | ".join(cells) + f" | {rms['continued'] - rms['clamped']:+.4f} |")


if __name__ == "__main__":
    main()
