"""imucal's Ferraris session calibrated by imucal and by `imufmu train`, judged side by side.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_ferraris.py [--data ../shared/data/imucal_ferraris]

imucal calibrates from its published section list; `imufmu train` gets the raw recording only (no
sections, no reference, its defaults) — the way a user runs it. Both are judged on the same samples by
training.bench.textbook: the gravity-norm spread over the six faces and the rest-to-rest
gravity-direction error. Prints two tables (the figures, and each tool's scale factors).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from training.bench.textbook import (Calibrated, face_norm_spread_pct, imucal_calibrated, read_sections,  # noqa: E402
                                     rest_norm_spread_pct, rest_to_rest_error_deg, rests)
from training.data.io import read_imu_csv  # noqa: E402
from training.models.thermal import apply_thermal  # noqa: E402
from training.selfcal.accel import gain_summary  # noqa: E402
from training.train import train  # noqa: E402

DATA = ROOT.parent / "shared" / "data" / "imucal_ferraris"
#: The acceptance bound of issue 28: each figure within 1.5x imucal's on the same session.
BOUND = 1.5


def ours(data) -> Calibrated:
    """`imufmu train` at its defaults on the raw recording, applied to it."""
    artefact = train([data], seed=0, progress=False)
    gyr, acc = artefact.thermal["gyr"], artefact.thermal["acc"]
    return Calibrated("ImuFusion `imufmu train` (raw recording, defaults)", apply_thermal(acc, data.acc, data.temp),
                      apply_thermal(gyr, data.gyr, data.temp), np.array(gain_summary(acc.A)["scale_factors"]),
                      np.array(gain_summary(gyr.A)["scale_factors"]))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", type=Path, default=DATA, help="folder with ferraris_session.csv.gz, .json, _sections.json")
    args = p.parse_args()
    data = read_imu_csv(args.data / "ferraris_session.csv.gz")
    sections = read_sections(args.data / "ferraris_session_sections.json")
    windows = rests(data)
    raw = Calibrated("raw", data.acc, data.gyr, np.ones(3), np.ones(3))
    tools = [raw, imucal_calibrated(data, sections, float(data.meta["rate_hz"])), ours(data)]
    figures = {c.name: (rest_norm_spread_pct(c.acc, windows), face_norm_spread_pct(c.acc, sections),
                        *rest_to_rest_error_deg(data, c, windows)) for c in tools}
    ref = figures[tools[1].name]
    print(f"| calibration | gravity-norm spread over the {len(windows)} rests [%] | gravity-norm spread over imucal's "
          "6 face sections [%] | rest-to-rest gravity-direction error RMS [°] | rest pairs "
          f"| ÷ imucal: rests / sections / direction (bound ≤ {BOUND:g}) |")
    print("|---|---|---|---|---|---|")
    for c in tools:
        rest, faces, error, pairs = figures[c.name]
        ratio = f"{rest / ref[0]:.2f} / {faces / ref[1]:.2f} / {error / ref[2]:.2f}" if c is not tools[1] else "1 / 1 / 1"
        print(f"| {c.name} | {rest:.4f} | {faces:.4f} | {error:.3f} | {pairs} | {ratio} |")
    print()
    print("| calibration | accelerometer scale factors x, y, z | gyro scale factors x, y, z |")
    print("|---|---|---|")
    for c in tools[1:]:
        print(f"| {c.name} | {', '.join(f'{v:.5f}' for v in c.acc_scale)} | {', '.join(f'{v:.5f}' for v in c.gyr_scale)} |")


if __name__ == "__main__":
    main()
