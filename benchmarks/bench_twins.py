"""The textbook protocols' simulated twins, trained without their truth, against the simulator's truth.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_twins.py [--seeds 0 1 2] [--twins ferraris multipose]

For each twin (scenarios/<name>.toml) and seed: the protocol `train` recognised, the largest scale-factor
error of the accelerometer and the gyro [%], the largest accelerometer and gyro non-orthogonality error
[°], and the parameters held at nominal (training.bench.textbook.trained_twin; the bounds are issue 28's:
0.05 %, 0.05°, 0.1 %).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from training.bench.textbook import trained_twin  # noqa: E402

TWINS = ("ferraris", "multipose")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    p.add_argument("--twins", nargs="+", default=list(TWINS))
    args = p.parse_args()
    print("| twin | seed | protocol recognised | acc scale err max [%] | acc non-orth. err max [°] "
          "| gyr scale err max [%] | gyr non-orth. err max [°] | held at nominal |")
    print("|---|---|---|---|---|---|---|---|")
    for name in args.twins:
        for seed in args.seeds:
            r = trained_twin(ROOT / "scenarios" / f"{name}.toml", seed)
            held = [f"{t} {h}" for t in ("acc", "gyr") for h in r.artefact.fit_stats[t].get("held", [])]
            worst = {k: {t: float(np.max(np.abs(v[t]))) for t in v} for k, v in
                     (("scale", r.scale_error_pct), ("nonorth", r.nonorthogonality_error_deg))}
            print(f"| {name} | {seed} | {r.artefact.fit_stats['protocol']['name'].split(':')[0]} "
                  f"| {worst['scale']['acc']:.4f} | {worst['nonorth']['acc']:.4f} | {worst['scale']['gyr']:.4f} "
                  f"| {worst['nonorth']['gyr']:.4f} | {', '.join(held) or 'none'} |")


if __name__ == "__main__":
    main()
