"""Benchmark of the compass ELM (training/models/elm.py): prints the tables of docs/elm.md.

1. Simulated compass (scenarios/variants/compass_elm.toml: all yaws, pitch and roll within ±60°, hard and
   soft iron plus a cubic cross-axis distortion): heading error RMS on the held-out 10 % for the
   linear (ellipsoid) calibration alone, a plain ELM (stage one only) of the back-tuned size, the
   plain incremental ELM grown to the same loss, the ELM with back-tuning, and the heading form.
   Heading = tilt-compensated compass of the corrected field with the TRUE roll and pitch, so
   the figure isolates the compass. Repeated with the shared mems_grade sensor (weaker cubic).
2. Training loss against hidden nodes, plain incremental ELM vs back-tuned growth.
3. Measured BROAD trials (undisturbed 01-18): leave-one-trial-out heading RMSE without / with
   the ELM trained on the other trials, and behind the validation gate.

Usage: python benchmarks/bench_elm.py [--skip-broad] [--broad-dir DIR] [--seed N]
"""
from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np
import torch

from training.models import elm
from training.models.ellipsoid import fit_ellipsoid
from training.simulator import load_scenario, simulate

ROOT = Path(__file__).resolve().parent.parent
SCENARIO = ROOT / "scenarios" / "variants" / "compass_elm.toml"
SHARED_SENSOR_SCENARIO = ROOT / "scenarios" / "calibration.toml"   # carries sensors/mems_grade.toml
PREP = elm.CompassPrep()
#: Loss E where the growth stops: the noise floor of the prepared field (median-filtered
#: noise ≈ 0.04 µT on a ~110 µT range -> (2·0.04/110)² ≈ 5e-7, plus quantisation) times ~4.
TARGET_LOSS = 2e-6
FITTER = elm.ElmFitter(max_hidden=40, target_loss=TARGET_LOSS)


def field_rms(a: np.ndarray, b: np.ndarray) -> float:
    """RMS of a − b over all entries [µT]."""
    return float(np.sqrt(np.mean((a - b) ** 2)))


def compass_table(name: str, scenario, seed: int) -> tuple[elm.ElmModel, elm.ElmModel]:
    """Print the heading table of one simulated compass; returns (plain grown, back-tuned)."""
    data = simulate(scenario, seed)
    start = time.perf_counter()
    linear = fit_ellipsoid(elm.median_filter(data.mag, PREP.median_window), data.field_norm_ut)
    linear_s = time.perf_counter() - start
    s = elm.prepare_compass(data, linear, PREP, seed)
    x, t, xt, tt, et = s.field[s.train], s.reference[s.train], s.field[s.test], s.reference[s.test], s.euler[s.test]
    tuned = FITTER.fit(x, t, seed)
    grown = dataclasses.replace(FITTER, back_tuning=False).fit(x, t, seed)
    plain = dataclasses.replace(FITTER, back_tuning=False, fixed_hidden=tuned.hidden).fit(x, t, seed)
    hx, ht = elm.heading_form_data(s, s.train)
    heading = dataclasses.replace(FITTER, max_hidden=20).fit(hx, ht, seed)
    print(f"\n## {name}: {len(data)} samples, {s.rejected} rejected by the invariance test "
          f"(invariant {s.invariant_ut:.2f} µT), train {len(s.train)}, test {len(s.test)}\n")
    print("| model | hidden nodes | train loss (norm. MSE) | field error RMS [µT] | heading RMS [°] | train time [s] |")
    print("|---|---|---|---|---|---|")
    print(f"| linear (ellipsoid) alone | – | – | {field_rms(xt, tt):.3f} | "
          f"{elm.heading_rms_deg(xt, et):.3f} | {linear_s:.1f} |")
    for label, m in (("plain ELM, same size (stage one only)", plain),
                     ("plain incremental ELM grown to E", grown),
                     ("ELM with back-tuning (grown to E)", tuned)):
        y = elm.elm_apply(m, xt)
        print(f"| {label} | {m.hidden} | {m.loss:.2e} | {field_rms(y, tt):.3f} | "
              f"{elm.heading_rms_deg(y, et):.3f} | {m.train_time_s:.1f} |")
    print(f"| heading form with back-tuning | {heading.hidden} | {heading.loss:.2e} | – | "
          f"{elm.heading_form_rms_deg(heading, s, s.test):.3f} | {heading.train_time_s:.1f} |")
    print(f"| truth field (floor of the metric) | – | – | 0 | {elm.heading_rms_deg(tt, et):.3f} | – |")
    return grown, tuned


def loss_table(grown: elm.ElmModel, tuned: elm.ElmModel) -> None:
    """Training loss against hidden nodes for both growth variants."""
    plain = {h.nodes: h.loss_stage_two for h in grown.history}
    back = {h.nodes: h.loss_stage_two for h in tuned.history}
    print(f"\n## Training loss (normalised MSE) against hidden nodes, E = {TARGET_LOSS:.0e}\n")
    print("| nodes | plain incremental ELM | with back-tuning |")
    print("|---|---|---|")
    for n in sorted(set(plain) | set(back)):
        if n <= 12 or n % 4 == 0 or n in (grown.hidden, tuned.hidden):
            cell = lambda d: f"{d[n]:.2e}" if n in d else "–"
            print(f"| {n} | {cell(plain)} | {cell(back)} |")


def broad_table(folder: Path, seed: int) -> None:
    """Leave-one-trial-out heading RMSE on the undisturbed BROAD trials."""
    paths = sorted(folder.glob("*_undisturbed_*.csv.gz"))
    fitter = dataclasses.replace(FITTER, max_hidden=10, target_loss=1e-6)
    start = time.perf_counter()
    results = elm.broad_heading_with_elm(paths, fitter, elm.CompassPrep(stride=20), seed)
    print(f"\n## BROAD undisturbed trials, leave-one-trial-out ({time.perf_counter() - start:.0f} s)\n")
    print("| trial | eval samples | without ELM [°] | ELM always on [°] | change [°] | gate | gated [°] | gated change [°] |")
    print("|---|---|---|---|---|---|---|---|")
    for r in results:
        print(f"| {r.trial} | {r.samples} | {r.without_deg:.3f} | {r.ungated_deg:.3f} | "
              f"{r.ungated_deg - r.without_deg:+.3f} | {'on' if r.enabled else 'off'} | "
              f"{r.gated_deg:.3f} | {r.gated_deg - r.without_deg:+.3f} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--skip-broad", action="store_true")
    parser.add_argument("--broad-dir", type=Path, default=ROOT.parent / "shared" / "data" / "broad")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    torch.set_num_threads(1)
    scenario = load_scenario(SCENARIO)
    grown, tuned = compass_table("compass_elm (sensors/compass_nonlinear.toml)", scenario, args.seed)
    loss_table(grown, tuned)
    shared = dataclasses.replace(scenario, sensor=load_scenario(SHARED_SENSOR_SCENARIO).sensor)
    compass_table("compass_elm with the shared mems_grade sensor", shared, args.seed)
    if not args.skip_broad:
        broad_table(args.broad_dir, args.seed)


if __name__ == "__main__":
    main()
