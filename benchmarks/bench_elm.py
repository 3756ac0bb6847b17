"""Benchmark of the compass ELM (training/models/elm.py): prints the tables of docs/elm.md.

1. Simulated compass (scenarios/variants/compass_elm.toml: all yaws, pitch and roll within ±60°, hard and
   soft iron plus a cubic cross-axis distortion): heading error RMS on the held-out 10 % for the
   linear (ellipsoid) calibration alone, a plain ELM (stage one only) of the back-tuned size, the
   plain incremental ELM grown to the same loss, the ELM with back-tuning, and the heading form.
   Heading = tilt-compensated compass of the corrected field with the TRUE roll and pitch, so
   the figure isolates the compass. Repeated with the shared mems_grade sensor (weaker cubic).
2. Training loss against hidden nodes, plain incremental ELM vs back-tuned growth.
3. Training schedules: the seed's ("source": odd iterations stage one, even iterations plain
   gradient descent on all rows) against the product's ("adam"), same seeds, same data, same
   budget, at the bench's budget and at the chain's (training.train.ELM_FITTER), where each of
   the product's additions (elm.ADDITIONS) is also added to the source alone; per seed the
   scenario is simulated with that seed and every schedule trains on the same rows. Mean and
   worst held-out figures over the seeds. Then the plain gradient-descent step-size sweep.
4. Measured BROAD trials (undisturbed 01-18): leave-one-trial-out heading RMSE without / with
   the ELM trained on the other trials, and behind the validation gate.

Usage: python benchmarks/bench_elm.py [--skip-broad] [--broad-dir DIR] [--seed N] [--seeds N]
       python benchmarks/bench_elm.py --small    (table 3 only: 2 seeds, every 8th sample, small
                                                  budget; what tests/test_elm.py runs)
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
from training.train import ELM_FITTER

ROOT = Path(__file__).resolve().parent.parent
SCENARIO = ROOT / "scenarios" / "variants" / "compass_elm.toml"
SHARED_SENSOR_SCENARIO = ROOT / "scenarios" / "calibration.toml"   # carries sensors/mems_grade.toml
PREP = elm.CompassPrep()
#: Loss E where the growth stops: the noise floor of the prepared field (median-filtered
#: noise ≈ 0.04 µT on a ~110 µT range -> (2·0.04/110)² ≈ 5e-7, plus quantisation) times ~4.
TARGET_LOSS = 2e-6
FITTER = elm.ElmFitter(max_hidden=40, target_loss=TARGET_LOSS)
#: The ablation: the source, the source plus one of the product's additions, the product.
ABLATION = ("source", *(f"source+{a}" for a in elm.ADDITIONS), "adam")
#: Budgets of the schedule table: name -> (fitter, the schedules trained with it).
BUDGETS = {"bench (E 2e-6, ≤ 40 nodes, 150 steps)": (FITTER, ("source", "adam")),
           "chain (training.train.ELM_FITTER)": (elm.ElmFitter(**ELM_FITTER), ABLATION)}
#: The --small run: a budget that trains in about a second on every 8th sample.
SMALL_BUDGETS = {"small (≤ 12 nodes, 20 steps)":
                 (dataclasses.replace(FITTER, max_hidden=12, tune_steps=20), ABLATION)}
SMALL_STRIDE = 8
#: The --small forms of the other tables: a small fitter, two step sizes, three BROAD trials thinned.
SMALL_FITTER = dataclasses.replace(FITTER, max_hidden=12, tune_steps=20)
SMALL_SWEEP = (0.0, 0.01)
SMALL_BROAD_TRIALS, SMALL_BROAD_STRIDE = 3, 200
#: Step sizes of the plain gradient-descent sweep ("source" schedule, chain budget, all seeds);
#: 0 leaves stage two without effect (the plain incremental ELM of the same growth).
GD_SWEEP = (0.0, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0)


def field_rms(a: np.ndarray, b: np.ndarray) -> float:
    """RMS of a − b over all entries [µT]."""
    return float(np.sqrt(np.mean((a - b) ** 2)))


def compass_table(name: str, scenario, seed: int, fitter: elm.ElmFitter = FITTER) -> tuple[elm.ElmModel, elm.ElmModel]:
    """Print the heading table of one simulated compass; returns (plain grown, back-tuned)."""
    data = simulate(scenario, seed)
    start = time.perf_counter()
    linear = fit_ellipsoid(elm.median_filter(data.mag, PREP.median_window), data.field_norm_ut)
    linear_s = time.perf_counter() - start
    s = elm.prepare_compass(data, linear, PREP, seed)
    x, t, xt, tt, et = s.field[s.train], s.reference[s.train], s.field[s.test], s.reference[s.test], s.euler[s.test]
    tuned = fitter.fit(x, t, seed)
    grown = dataclasses.replace(fitter, back_tuning=False).fit(x, t, seed)
    plain = dataclasses.replace(fitter, back_tuning=False, fixed_hidden=tuned.hidden).fit(x, t, seed)
    hx, ht = elm.heading_form_data(s, s.train)
    heading = dataclasses.replace(fitter, max_hidden=min(20, fitter.max_hidden)).fit(hx, ht, seed)
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


def prepared_compass(scenario, seed: int, prep: elm.CompassPrep) -> elm.CompassSet:
    """The scenario simulated with `seed`, its ellipsoid fit (no reference used) and prepared rows."""
    data = simulate(scenario, seed)
    linear = fit_ellipsoid(elm.median_filter(data.mag, prep.median_window), data.field_norm_ut)
    return elm.prepare_compass(data, linear, prep, seed)


def held_out(model: elm.ElmModel | None, s: elm.CompassSet) -> tuple[float, float]:
    """(field error RMS µT, heading RMS °) on the held-out rows; model None = linear stage alone."""
    x, t, e = s.field[s.test], s.reference[s.test], s.euler[s.test]
    y = x if model is None else elm.elm_apply(model, x)
    return field_rms(y, t), elm.heading_rms_deg(y, e)


def schedule_table(scenario, seeds: int, stride: int, budgets: dict) -> None:
    """The schedules on the same seeds, data and budget: mean and worst over the seeds of the
    held-out heading RMS and field error, hidden nodes and training time (table 3); a diverged
    fit counts as an infinite error and in the last column."""
    prep = dataclasses.replace(PREP, stride=stride)
    results = {}   # (budget, schedule or None) -> list of (field µT, heading °, nodes, time s)
    for seed in range(seeds):
        s = prepared_compass(scenario, seed, prep)
        results.setdefault(("–", None), []).append((*held_out(None, s), 0, 0.0))
        for budget, (fitter, schedules) in budgets.items():
            for schedule in schedules:
                try:
                    m = dataclasses.replace(fitter, schedule=schedule).fit(
                        s.field[s.train], s.reference[s.train], seed)
                    row = (*held_out(m, s), m.hidden, m.train_time_s)
                except ValueError:          # gradient descent diverged: counted, not hidden
                    row = (np.inf, np.inf, 0, np.nan)
                results.setdefault((budget, schedule), []).append(row)
    print(f"\n## Training schedules: {seeds} seeds (0..{seeds - 1}), every {stride}. sample, "
          f"held-out 10 %, mean / worst over the seeds\n")
    print("| budget | schedule | hidden nodes mean / max | field error RMS [µT] mean / worst | "
          "heading RMS [°] mean / worst | train time [s] mean | diverged |")
    print("|---|---|---|---|---|---|---|")
    for (budget, schedule), rows in results.items():
        f, h, n, t = (np.array(c, dtype=float) for c in zip(*rows))
        ok = np.isfinite(t)
        label, nodes, train = (("linear (ellipsoid) alone", "–", "–") if schedule is None else
                               (schedule, f"{n[ok].mean():.1f} / {n.max():.0f}" if ok.any() else "–",
                                f"{t[ok].mean():.1f}" if ok.any() else "–"))
        print(f"| {budget} | {label} | {nodes} | {f.mean():.3f} / {f.max():.3f} | "
              f"{h.mean():.3f} / {h.max():.3f} | {train} | {int((~ok).sum())} |")


def gd_sweep_table(scenario, seeds: int, fitter: elm.ElmFitter, sweep=GD_SWEEP, prep: elm.CompassPrep = PREP) -> None:
    """Held-out heading RMS of the "source" schedule at each plain gradient-descent step size
    (`sweep`), mean / worst over the seeds; how many fits diverged."""
    sets = [prepared_compass(scenario, seed, prep) for seed in range(seeds)]
    print(f"\n## Plain gradient-descent step size, 'source' schedule, chain budget, {seeds} seeds\n")
    print("| gd_learning_rate | hidden nodes mean | heading RMS [°] mean / worst | diverged |")
    print("|---|---|---|---|")
    for lr in sweep:
        nodes, heading = [], []
        for seed, s in enumerate(sets):
            try:
                m = dataclasses.replace(fitter, schedule="source", gd_learning_rate=lr).fit(
                    s.field[s.train], s.reference[s.train], seed)
            except ValueError:
                continue
            nodes.append(m.hidden)
            heading.append(held_out(m, s)[1])
        cells = (f"{np.mean(nodes):.1f} | {np.mean(heading):.3f} / {np.max(heading):.3f}" if heading
                 else "– | –")
        print(f"| {lr} | {cells} | {seeds - len(heading)} |")


def broad_table(folder: Path, seed: int, trials: int | None = None, stride: int = 20) -> None:
    """Leave-one-trial-out heading RMSE on the undisturbed BROAD trials (the first `trials` of
    them; None: all), every `stride`-th sample."""
    paths = sorted(folder.glob("*_undisturbed_*.csv.gz"))[:trials]
    fitter = dataclasses.replace(FITTER, max_hidden=10, target_loss=1e-6)
    start = time.perf_counter()
    results = elm.broad_heading_with_elm(paths, fitter, elm.CompassPrep(stride=stride), seed)
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
    parser.add_argument("--seeds", type=int, default=8, help="seeds of the schedule table")
    parser.add_argument("--small", action="store_true",
                        help="every table on a small input: small fitters, 2 seeds for the schedules, 1 for the "
                             "step sizes, 3 BROAD trials every 200th sample")
    args = parser.parse_args()
    torch.set_num_threads(1)
    scenario = load_scenario(SCENARIO)
    if args.small:
        grown, tuned = compass_table("compass_elm, small fitter", scenario, args.seed, SMALL_FITTER)
        loss_table(grown, tuned)
        schedule_table(scenario, 2, SMALL_STRIDE, SMALL_BUDGETS)
        gd_sweep_table(scenario, 1, SMALL_FITTER, SMALL_SWEEP, dataclasses.replace(PREP, stride=SMALL_STRIDE))
        if not args.skip_broad and args.broad_dir.is_dir():
            broad_table(args.broad_dir, args.seed, SMALL_BROAD_TRIALS, SMALL_BROAD_STRIDE)
        return
    grown, tuned = compass_table("compass_elm (sensors/compass_nonlinear.toml)", scenario, args.seed)
    loss_table(grown, tuned)
    shared = dataclasses.replace(scenario, sensor=load_scenario(SHARED_SENSOR_SCENARIO).sensor)
    compass_table("compass_elm with the shared mems_grade sensor", shared, args.seed)
    schedule_table(scenario, args.seeds, PREP.stride, BUDGETS)
    gd_sweep_table(scenario, args.seeds, BUDGETS["chain (training.train.ELM_FITTER)"][0])
    if not args.skip_broad:
        broad_table(args.broad_dir, args.seed)


if __name__ == "__main__":
    main()
