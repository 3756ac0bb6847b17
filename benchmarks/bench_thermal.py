"""Benchmark of the gyro temperature models (training/bench/compare_thermal.py): the tables of
docs/thermal_models.md.

Recordings (one report folder each under OUT):
  plateaus   scenarios/thermal_plateaus.toml (shared sensor), simulated; train on the first
             four plateaus (train_fraction 2/3), validate on the last two
  rate       scenarios/variants/thermal_plateaus_rate.toml (10x temperature-rate bias), same split
  pan        /work/shared/data/pan_thermal/pan_etu_cold_chamber.csv.gz, train on the first 60 %

Usage: python benchmarks/bench_thermal.py {plateaus,rate,pan} --out OUT [--runs N] [--seed N]
       [--bp-epochs N] [--tau-s S] [--pan-dir DIR] [--as-written]
Each recording is a separate invocation so they can run in parallel on separate cores.
The table's rows (training/bench/compare_thermal.MODELS): the polynomials, plain BP, PSO-BP in the
source's form (issue 4), the product's additions one at a time up to (a), (b) without the
shrinkage and (b). The source's form fits single samples with plain gradient descent over the
whole budget: about 60 s of CPU per run on the simulated recordings, most of a run's time.
--as-written prints the PSO-BP paper's comparison as written instead (compare_thermal.AS_WRITTEN_MODELS,
issue 33 item 5): the piecewise polynomial with one segment per temperature point, plain BP as the
source trains it and PSO-BP in the source's form, each beside the product's variant; the two
source-form networks cost about 30 s (BP) and 50 s (PSO-BP) of CPU per run on the simulated recordings. Its report
folder is OUT/<recording>_as_written.

       python benchmarks/bench_thermal.py verdict --out OUT [--recordings plateaus rate pan]
       [--seeds 0 1 2] [--bp-epochs N] [--tau-s S] [--pan-dir DIR]
The table of "Verdict for the chain": each whole recording as calibration data, the degree-2
bias polynomial fitted on all its static rows, then the rule that sets `enable_psobp`
(training.models.psobp.residual_psobp_wins: residual network fitted on the first 2/3, judged
on the held-out last third) for each seed; the figures and the switch are the rule's own.

       python benchmarks/bench_thermal.py gainbias --out OUT [--iterations N]
The gain/bias(T) model's fit as built (Rprop) against plain gradient descent (GainBiasFitter
optimizer 'sgd', the baseline kept for the source's adaptive-rate gradient descent) on the gyro
of the simulated calibration set (scenarios/calibration.toml, five soaks -10..50 °C with
rotations, the recording `train` calibrates from), judged on scenarios/eval_rotations.toml
(rotations and rests at -3, 12, 27, 42 °C, between the soaks); same degree and iteration budget.
"""
from __future__ import annotations

import argparse
import inspect
import time
from pathlib import Path

import numpy as np
import torch

from training.bench.compare_thermal import compare_thermal, fit_bias_polynomial
from training.data.io import read_imu_csv, write_imu_csv
from training.models.psobp import bias_targets, residual_psobp_wins
from training.models.thermal import GainBiasFitter, apply_thermal
from training.simulator import load_scenario, simulate

ROOT = Path(__file__).resolve().parent.parent
SCENARIOS = {"plateaus": ROOT / "scenarios" / "thermal_plateaus.toml",
             "rate": ROOT / "scenarios" / "variants" / "thermal_plateaus_rate.toml"}
#: Training part of the simulated protocol: six equally long plateau blocks, train on four.
PLATEAU_TRAIN_FRACTION = 2.0 / 3.0
#: Training part of the measured PAN log (issue 4: the first 60 % by time).
PAN_TRAIN_FRACTION = 0.6
PAN_DIR = Path("/work/shared/data/pan_thermal")
PAN_FILE = "pan_etu_cold_chamber.csv.gz"
#: Names of the recordings in the verdict table.
LABELS = {"plateaus": "shared sensor", "rate": "variant, 10× rate bias", "pan": "PAN log"}
#: Degree of the chain's bias polynomial B(T) in the verdict (the single polynomial of the comparison).
VERDICT_DEGREE = 2
#: Bias targets of the polynomial: rate low-pass τ [s], window [s], rest threshold [rad/s]
#: (the PSO-BP fitter's defaults, so both models see the same static windows).
TARGETS = {"tau_s": 10.0, "window_s": 10.0, "rest_rad_s": 1e-3}
DPS = np.pi / 180.0
#: The gain/bias fit's protocol: calibrated on the first recording, judged on the second.
GAIN_BIAS_SCENARIOS = (ROOT / "scenarios" / "calibration.toml", ROOT / "scenarios" / "eval_rotations.toml")
#: Iteration budget of the gain/bias fits: GainBiasFitter's default.
GAIN_BIAS_ITERATIONS = inspect.signature(GainBiasFitter).parameters["iterations"].default
#: The fits compared: (row label, GainBiasFitter arguments beyond the degree). Rprop is the product; plain
#: gradient descent at the fitter's default step and at the step the tests use for it (tests/test_thermal.py).
GAIN_BIAS_FITS = (("Rprop (as built)", {"optimizer": "rprop"}),
                  ("plain gradient descent, step 0.001", {"optimizer": "sgd", "lr": 1e-3}),
                  ("plain gradient descent, step 1", {"optimizer": "sgd", "lr": 1.0}))


def recording_path(name: str, out: Path, pan_dir: Path) -> Path:
    """The imu-csv/1 file of a recording: PAN from pan_dir, the simulated ones simulated into out."""
    if name == "pan":
        return pan_dir / PAN_FILE
    scenario = load_scenario(SCENARIOS[name])
    return write_imu_csv(simulate(scenario), out / f"{scenario.name}.csv.gz")


def polynomial_compensated(t, gyr, ref_gyr, temp) -> np.ndarray:
    """(N, 3) gyro [rad/s] after the degree-VERDICT_DEGREE bias polynomial fitted on every static
    10 s window of the recording (as the chain's B(T) with A = I, G = 1)."""
    tw, _, bw = bias_targets(t, gyr, ref_gyr, temp, TARGETS["tau_s"], TARGETS["window_s"], TARGETS["rest_rad_s"])
    return apply_thermal(fit_bias_polynomial(tw, bw, VERDICT_DEGREE), gyr, temp)


def verdict_rows(paths: dict[str, Path], seeds: list[int], bp_epochs: int,
                 tau_s: float = TARGETS["tau_s"]) -> list[dict]:
    """Per recording: held-out 10 s-mean RMS [°/s] of the polynomial alone, of the hybrid per
    seed, the rule's switch per seed and the held-out window count (residual_psobp_wins; tau_s [s]:
    the network's dT/dt low-pass)."""
    rows = []
    for name, path in paths.items():
        d = read_imu_csv(path)
        gyr = polynomial_compensated(d.t, d.gyr, d.ref_gyr, d.temp)
        decisions = [residual_psobp_wins(d.t, gyr, d.ref_gyr, d.temp, seed, tau_s=tau_s, epochs=bp_epochs)
                     for seed in seeds]
        rows.append({"recording": name, "windows": decisions[0].windows,
                     "polynomial_dps": decisions[0].rms_polynomial / DPS,
                     "hybrid_dps": [x.rms_hybrid / DPS for x in decisions],
                     "enable": [bool(x.enable) for x in decisions]})
    return rows


def _switch_text(enable: list[bool]) -> str:
    """'on (all seeds)', 'off (all seeds)' or the per-seed list."""
    if all(enable):
        return "on (all seeds)"
    if not any(enable):
        return "off (all seeds)"
    return " / ".join("on" if e else "off" for e in enable)


def verdict_table(rows: list[dict], seeds: list[int]) -> str:
    """The Markdown verdict table of docs/thermal_models.md."""
    lines = ["| recording | 10 s-mean RMS, polynomial alone [°/s] | with residual PSO-BP [°/s] (seeds "
             + "/".join(map(str, seeds)) + ") | enable_psobp |", "|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {LABELS[r['recording']]} ({r['windows']} held-out windows) | {r['polynomial_dps']:.4f} | "
                     + " / ".join(f"{x:.4f}" for x in r["hybrid_dps"]) + f" | {_switch_text(r['enable'])} |")
    return "\n".join(lines) + "\n"


def gain_bias_rows(iterations: int, degree: int = VERDICT_DEGREE, seed: int = 0) -> list[dict]:
    """Per GAIN_BIAS_FITS entry, at an iteration budget of `iterations`: iterations run, converged, gyro
    RMS [°/s] of corrected - ref_gyr on the calibration set and on the held-out evaluation set, CPU s;
    a diverged fit reports its message."""
    calibration, evaluation = (simulate(load_scenario(p)) for p in GAIN_BIAS_SCENARIOS)
    # One untimed iteration first: torch's one-off start-up would otherwise be charged to the first row.
    GainBiasFitter(degree=degree, iterations=1).fit(calibration.gyr, calibration.ref_gyr, calibration.temp, seed,
                                                    "rad/s")
    rows = []
    for label, arguments in GAIN_BIAS_FITS:
        start = time.process_time()
        try:
            fitter = GainBiasFitter(degree=degree, iterations=iterations, **arguments)
            fit = fitter.fit(calibration.gyr, calibration.ref_gyr, calibration.temp, seed, "rad/s")
        except ValueError as e:
            rows.append({"fit": label, "error": str(e)})
            continue
        held = apply_thermal(fit.model, evaluation.gyr, evaluation.temp) - evaluation.ref_gyr
        rows.append({"fit": label, "iterations": fit.iterations, "converged": fit.converged,
                     "train_dps": fit.rms_after / DPS, "held_out_dps": float(np.sqrt(np.nanmean(held ** 2))) / DPS,
                     "cpu_s": time.process_time() - start})
    return rows


def gain_bias_table(rows: list[dict]) -> str:
    """The Markdown table of the gain/bias fit comparison (docs/thermal_models.md "As written / as built")."""
    lines = ["| fit | iterations | converged | gyro RMS, calibration set [°/s] | gyro RMS, held-out set [°/s] "
             "| CPU [s] |", "|---|---|---|---|---|---|"]
    for r in rows:
        if "error" in r:
            lines.append(f"| {r['fit']} | {r['error']} | — | — | — | — |")
            continue
        lines.append(f"| {r['fit']} | {r['iterations']} | {'yes' if r['converged'] else 'no'} | {r['train_dps']:.5f} "
                     f"| {r['held_out_dps']:.5f} | {r['cpu_s']:.2f} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    """Simulate (or locate) the recording(s), run the comparison or the verdict, print the Markdown table."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("recording", choices=["plateaus", "rate", "pan", "verdict", "gainbias"])
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--runs", type=int, default=50)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2], help="verdict: the network's seeds")
    p.add_argument("--recordings", nargs="+", choices=list(LABELS), default=list(LABELS),
                   help="verdict: the recordings")
    p.add_argument("--bp-epochs", type=int, default=3000)
    p.add_argument("--tau-s", type=float, default=TARGETS["tau_s"],
                   help="the networks' dT/dt low-pass time constant [s] (the fitter's default 10)")
    p.add_argument("--iterations", type=int, default=GAIN_BIAS_ITERATIONS,
                   help="gainbias: the gain/bias fits' iteration budget (GainBiasFitter's default)")
    p.add_argument("--pan-dir", type=Path, default=PAN_DIR)
    p.add_argument("--as-written", action="store_true",
                   help="the PSO-BP paper's comparison as written, beside the product's variants")
    a = p.parse_args()
    if not a.tau_s > 0:
        p.error(f"--tau-s must be positive, got {a.tau_s}")
    if a.as_written and a.recording in ("verdict", "gainbias"):
        p.error(f"--as-written applies to plateaus, rate and pan, not to {a.recording}")
    torch.set_num_threads(1)
    out = a.out / (f"{a.recording}_as_written" if a.as_written else a.recording)
    out.mkdir(parents=True, exist_ok=True)
    if a.recording == "gainbias":
        text = gain_bias_table(gain_bias_rows(a.iterations))
        (out / "gainbias.md").write_text(text)
        print(text)
        return
    if a.recording == "verdict":
        paths = {name: recording_path(name, out, a.pan_dir) for name in a.recordings}
        text = verdict_table(verdict_rows(paths, a.seeds, a.bp_epochs, a.tau_s), a.seeds)
        (out / "verdict.md").write_text(text)
        print(text)
        return
    path = recording_path(a.recording, out, a.pan_dir)
    fraction = PAN_TRAIN_FRACTION if a.recording == "pan" else PLATEAU_TRAIN_FRACTION
    compare_thermal([path], out, runs=a.runs, seed=a.seed, train_fraction=fraction,
                    bp_epochs=a.bp_epochs, tau_s=a.tau_s, as_written=a.as_written, progress=False)
    print((out / "compare_thermal.md").read_text())


if __name__ == "__main__":
    main()
