"""Benchmark of the magnetometer particle filter (docs/magpf.md): prints Markdown tables.

    python benchmarks/bench_magpf.py [--seeds 20] [--no-broad] [--no-sim]

1. Simulated tumbling (wide zero prior, magpf.zero_prior) (60 s at 100 Hz, |h_0| = 60 µT, h_p = [30, 40, 20] µT, soft iron up to
   0.05, uniform + Student-t noise), zero prior: hard-iron error (largest axis) at the end and
   RMS of |h_c| − |h_0| over the last 10 s, for the filter, plain SIR (steps 5–6 off) and the
   batch ellipsoid fit; mean and worst over the seeds. The norm error is evaluated on the
   noise-free distorted field (the calibration's error) and on the measured field.
2. Hard-iron jump of 20 µT at 30 s: the same figures 30 s after the jump.
3. BROAD trials (Laidig et al., Data 6(7) 2021, CC-BY-4.0): spread 100·std/mean of |h_c| over
   eval_mask, raw and filtered, ‖h_0‖ from the sidecar.
4. Cost: µs per sample of the C filter and of training.runtime.run_batch on a BROAD recording.
"""
from __future__ import annotations

import argparse
import glob
import sys
import time
from pathlib import Path

import numpy as np

from training import layout, magpf, runtime
from training.ellipsoid import apply_ellipsoid, fit_ellipsoid
from training.io import read_imu_csv

BROAD = Path(__file__).resolve().parents[2] / "shared" / "data" / "broad"
TAIL_S = 10.0


def clean_distorted(d: magpf.TumblingData) -> np.ndarray:
    """Noise-free distorted field (N, 3) µT of a simulated record."""
    inv = np.linalg.inv(np.eye(3) + magpf.soft_matrix(d.soft_iron[0]))
    return d.truth @ inv.T + d.hard_iron


def figures(d, est_hp, compensate, end: int) -> tuple[float, float, float]:
    """(hard-iron max-axis error at `end` [µT], norm RMS % clean, norm RMS % measured) over the
    TAIL_S seconds before `end`."""
    tail = slice(end - int(TAIL_S * d.rate_hz), end)
    herr = float(np.abs(est_hp - d.hard_iron[end - 1]).max())
    out = []
    for field in (clean_distorted(d)[tail], d.mag[tail]):
        n = np.linalg.norm(compensate(field, tail), axis=1)
        out.append(100.0 * float(np.sqrt(np.mean((n - d.field_norm_ut) ** 2))) / d.field_norm_ut)
    return herr, out[0], out[1]


def run_filter(d, s, end):
    r = magpf.run_c(d.mag, s)
    est = np.column_stack([r.hard_iron, r.soft_iron])
    return figures(d, r.hard_iron[end - 1],
                   lambda f, tail: magpf.apply(est[tail], f), end)


def run_ellipsoid(d, end):
    fit = fit_ellipsoid(d.mag[:end], d.field_norm_ut)
    return figures(d, fit.offset, lambda f, tail: apply_ellipsoid(fit, f), end)


def table(title: str, rows: dict) -> None:
    print(f"\n### {title}\n")
    print("| method | hard-iron err mean / worst [µT] | norm RMS clean mean / worst [%] "
          "| norm RMS measured mean / worst [%] |")
    print("|---|---|---|---|")
    for name, values in rows.items():
        a = np.array(values)
        print(f"| {name} | {a[:, 0].mean():.3f} / {a[:, 0].max():.3f} | "
              f"{a[:, 1].mean():.3f} / {a[:, 1].max():.3f} | {a[:, 2].mean():.3f} / {a[:, 2].max():.3f} |")


def simulated(seeds: int) -> None:
    for title, kwargs, end_s in (("Tumbling, zero prior, end of 60 s", {}, 60.0),
                                 ("Hard-iron jump of 20 µT at 30 s, 30 s later", {
                                     "duration_s": 60.0, "jump_at_s": 30.0}, 60.0)):
        rows = {"particle filter": [], "plain SIR": [], "ellipsoid fit (batch)": []}
        for seed in range(seeds):
            d = magpf.simulate_tumbling(seed, **kwargs)
            end = int(end_s * d.rate_hz)
            wide = magpf.zero_prior(60.0)
            rows["particle filter"].append(run_filter(d, magpf.settings(60.0, seed=seed, **wide), end))
            rows["plain SIR"].append(run_filter(d, magpf.settings(60.0, seed=seed, enable_splitting=0,
                                                                  **wide), end))
            start = int(kwargs.get("jump_at_s", 0.0) * d.rate_hz)
            rows["ellipsoid fit (batch)"].append(run_ellipsoid(magpf.TumblingData(
                d.mag[start:], d.truth[start:], d.hard_iron[start:], d.soft_iron[start:],
                d.rate_hz, d.field_norm_ut), end - start))
        table(f"{title} ({seeds} seeds)", rows)


def broad() -> None:
    print("\n### BROAD: spread 100·std/mean of |h_c| over eval_mask [%], default settings "
          "(prior 0 ± 3 µT / 0.02: the data set is calibrated)\n")
    print("| trial | raw | particle filter | plain SIR | µs/sample PF |")
    print("|---|---|---|---|---|")
    files = sorted(glob.glob(str(BROAD / "*.csv.gz")))
    for path in files:
        name = Path(path).name.split("_")[0]
        if not (name <= "18" or name in ("32", "33", "35")):
            continue
        d = read_imu_csv(path)
        m = d.eval_mask.astype(bool)
        spread = lambda v: 100.0 * float(np.std(np.linalg.norm(v[m], axis=1)) /
                                         np.mean(np.linalg.norm(v[m], axis=1)))
        t0 = time.perf_counter()
        pf = magpf.run_c(d.mag, magpf.settings(d.field_norm_ut))
        cost = 1e6 * (time.perf_counter() - t0) / len(d)
        sir = magpf.run_c(d.mag, magpf.settings(d.field_norm_ut, enable_splitting=0))
        print(f"| {Path(path).name[:-7]} | {spread(d.mag):.2f} | {spread(pf.compensated):.2f} | "
              f"{spread(sir.compensated):.2f} | {cost:.0f} |", flush=True)


def cost() -> None:
    path = sorted(glob.glob(str(BROAD / "01_*.csv.gz")))[0]
    d = read_imu_csv(path)
    s = np.array(layout.settings_array({}))
    c = np.array(layout.identity_coefficients())
    t0 = time.perf_counter()
    runtime.run_batch(c, s, d.t - d.t[0], d.inputs())
    rest = 1e6 * (time.perf_counter() - t0) / len(d)
    print("\n### Cost on BROAD 01 (µs per sample)\n")
    print("| configuration | µs/sample |\n|---|---|")
    for label, over in (("filter, defaults (N=128, decimation 16)", {}),
                        ("filter, plain SIR (splitting off)", {"enable_splitting": 0}),
                        ("filter, move off", {"enable_move": 0}),
                        ("filter, N=256", {"particle_count": 256})):
        t0 = time.perf_counter()
        magpf.run_c(d.mag, magpf.settings(d.field_norm_ut, **over))
        print(f"| {label} | {1e6 * (time.perf_counter() - t0) / len(d):.1f} |")
    print(f"| rest of the runtime (run_batch) | {rest:.2f} |")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--seeds", type=int, default=20)
    p.add_argument("--no-broad", action="store_true")
    p.add_argument("--no-sim", action="store_true")
    a = p.parse_args(argv)
    if not a.no_sim:
        simulated(a.seeds)
    if not a.no_broad and BROAD.is_dir():
        broad()
        cost()
    return 0


if __name__ == "__main__":
    sys.exit(main())
