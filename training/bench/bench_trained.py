"""BROAD as a user gets it: `train` on two trials, the FMU at the settings `train` wrote, through fmpy.

BROAD data: D. Laidig, M. Caruso, A. Cereatti, T. Seel, "BROAD — A Benchmark for Robust Inertial
Orientation Estimation", Data 6(7), 2021, doi:10.3390/data6070072 (CC-BY-4.0).

Two trainings on the same calibration trials (default 01 and 02):

- **no reference**: every reference column (ref_q, ref_gyr/acc/mag) and the eval mask removed and
  the sidecar's "reference" set to "none" — a user's own log; `train` self-calibrates;
- **attitude reference**: the optical ref_q kept, so `train` derives the rate and field references.

Each artefact is built into an FMU (`fmu.packer.build_fmu`) and every trial is co-simulated through
it with fmpy, with only what `imufmu run` sets by default on top of the trained settings (the
trial sidecar's declination and field norm), then once more with `enable_pf = 1` alone on top.
VQF 9D (defaults) runs on the same trials in the same process. Metric: BROAD's (training.bench.bench).
"""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from contract import layout
from training.bench.bench import (BROAD_CITATION, GROUPS, _group_means, broad_errors, run_vqf, trial_number,
                                  trial_paths)
from training.data.dataset import ImuData
from training.data.io import read_imu_csv
from training.data.reference_source import strip_references

#: Calibration trials of the acceptance: the first two undisturbed trials (one of each BROAD IMU
#: mounting, A and B).
TRAIN_TRIALS = ("01", "02")
#: Trials with a magnet attached to the IMU (a hard-iron change the particle filter must follow).
MAGNET_TRIALS = (32, 33, 35)
#: The anchor every FMU row is compared with, run in the same process.
VQF_LABEL = "VQF 9D (defaults)"
_Q = [layout.OUTPUTS.index(n) for n in ("q_w", "q_x", "q_y", "q_z")]
_FIELD = [layout.OUTPUTS.index(n) for n in ("field_x", "field_y", "field_z")]


def field_norm_spread(field: np.ndarray, data: ImuData) -> float:
    """100 · std/mean of |field| [%] over the eval_mask samples with a finite field."""
    mask = data.eval_mask.astype(bool) & np.all(np.isfinite(field), axis=1)
    norm = np.linalg.norm(field[mask], axis=1)
    return 100.0 * float(np.std(norm) / np.mean(norm))


def _train_and_build(datasets: list[ImuData], out: Path, seed: int) -> Path:
    """train() -> model.json, calibration.md and the FMU in `out`; returns the FMU path."""
    from training.artefact import coefficients_array, settings_dict
    from training.fmu_build import build_fmu
    from training.reports.calibration_report import write_calibration_report
    from training.train import train
    artefact = train(datasets, seed=seed, progress=False)
    artefact.save(out / "model.json")
    write_calibration_report(artefact, datasets, out)
    return build_fmu(coefficients_array(artefact), settings_dict(artefact), out / "ImuFusion.fmu",
                     provenance=f"BROAD trials {', '.join(d.name for d in datasets)}",
                     aux_inputs=artefact.aux_inputs, training_data=artefact.training_data, notes=artefact.notes)


def _run(fmu_path: Path, data: ImuData, extra: dict | None = None) -> np.ndarray:
    """(N, len(OUTPUTS)) FMU outputs through fmpy with the recording's sidecar parameters + extra."""
    from fmu.cosim import run_fmu
    from fmu.packer import fmu_aux_columns
    from training.main_job import recording_parameters
    params = {**recording_parameters(data), **(extra or {})}
    return run_fmu(fmu_path, data.t - data.t[0], data.inputs(fmu_aux_columns(fmu_path)), parameters=params)


def _rows(fmus: dict[str, Path], datas: list[ImuData]) -> tuple[list[dict], list[dict]]:
    """Per-trial BROAD errors of every FMU variant (with and without the particle filter) and VQF;
    per-trial field-norm spreads of the magnet trials."""
    from tqdm import tqdm

    from fmu.archive import declared_mounting
    from training.mounting import body_references
    rows, spreads = [], []
    for data in tqdm(datas, desc="BROAD trials through the FMUs"):
        base = {"name": data.name, "trial": trial_number(data)}
        rows.append({**base, "filter": VQF_LABEL, **broad_errors(run_vqf(data), data)})
        for label, path in fmus.items():
            out = _run(path, data)
            out_pf = _run(path, data, {"enable_pf": 1.0})
            body = body_references(data, declared_mounting(path))  # the FMU reports in its body axes
            rows.append({**base, "filter": f"ImuFusion FMU, {label}", **broad_errors(out[:, _Q], body)})
            rows.append({**base, "filter": f"ImuFusion FMU, {label}, enable_pf = 1",
                         **broad_errors(out_pf[:, _Q], body)})
            if base["trial"] in MAGNET_TRIALS:
                spreads.append({**base, "training": label, "raw": field_norm_spread(data.mag, data),
                                "without filter": field_norm_spread(out[:, _FIELD], data),
                                "with filter": field_norm_spread(out_pf[:, _FIELD], data)})
    return rows, spreads


def inclination_wins(rows: list[dict], name: str) -> tuple[int, int]:
    """(trials where filter `name` has a lower inclination RMSE than VQF_LABEL, trials of both)."""
    by_trial: dict[str, dict[str, float]] = {}
    for r in rows:
        by_trial.setdefault(r["name"], {})[r["filter"]] = r["inclination"]
    pairs = [v for v in by_trial.values() if name in v and VQF_LABEL in v]
    return sum(v[name] < v[VQF_LABEL] for v in pairs), len(pairs)


def _markdown(groups: dict, rows: list[dict], spreads: list[dict], train_names: list[str]) -> str:
    """The report: group means, per-trial totals, magnet-trial spreads and heading."""
    lines = [f"BROAD data: {BROAD_CITATION}.", "",
             f"Trained on {', '.join(train_names)}; FMU at the settings `train` wrote, through fmpy; "
             "sidecar declination and field norm as `imufmu run` sets them.", "",
             "Mean over trials of the per-trial RMSE [°] (total / heading / inclination):", "",
             "| filter | " + " | ".join(GROUPS) + " |", "|---|" + "---|" * len(GROUPS)]
    for name, g in groups.items():
        lines.append(f"| {name} | " + " | ".join(
            f"{g[k]['total']:.2f} / {g[k]['heading']:.2f} / {g[k]['inclination']:.2f} (n={g[k]['n_trials']})"
            if k in g else "–" for k in GROUPS) + " |")
    names = list(groups)
    lines += ["", f"Inclination RMSE lower than {VQF_LABEL}'s:", ""]
    lines += [f"- {n}: on {won} of {total} trials" for n in names if n != VQF_LABEL
              for won, total in [inclination_wins(rows, n)]]
    lines += ["", "Total RMSE [°] per trial:", "", "| trial | " + " | ".join(names) + " |",
              "|---|" + "---|" * len(names)]
    for trial in dict.fromkeys(r["name"] for r in rows):
        vals = {r["filter"]: r["total"] for r in rows if r["name"] == trial}
        lines.append(f"| {trial} | " + " | ".join(f"{vals[n]:.2f}" for n in names) + " |")
    lines += ["", "Attached-magnet trials: corrected field-norm spread 100·std/mean [%] over eval_mask, "
              "heading RMSE [°] without → with `enable_pf = 1`:", "",
              "| trial | training | spread raw | spread without filter | spread with filter | heading without | heading with |",
              "|---|---|---|---|---|---|---|"]
    for s in spreads:
        heading = {r["filter"]: r["heading"] for r in rows if r["name"] == s["name"]}
        label = f"ImuFusion FMU, {s['training']}"
        lines.append(f"| {s['name']} | {s['training']} | {s['raw']:.2f} | {s['without filter']:.2f} | "
                     f"{s['with filter']:.2f} | {heading[label]:.2f} | {heading[label + ', enable_pf = 1']:.2f} |")
    return "\n".join(lines) + "\n"


def bench_broad_trained(out_dir: str | Path, trials: list[str] | None = None,
                        train_trials: tuple[str, ...] = TRAIN_TRIALS, data_dir: str | Path | None = None,
                        seed: int = 0) -> dict:
    """Train on `train_trials` without any reference and with the attitude reference, build both
    FMUs, co-simulate `trials` (default all) through them with fmpy beside VQF 9D. Writes broad_trained.md,
    broad_trained.csv and both models' calibration.md to out_dir; prints the report; returns
    {"groups": {filter: {group: {total, heading, inclination, n_trials}}}, "trials": rows, "spreads": rows}."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    calibration = [read_imu_csv(p) for p in trial_paths(list(train_trials), data_dir)]
    fmus = {"no reference": _train_and_build([strip_references(d) for d in calibration],
                                              out_dir / "no_reference", seed),
            "attitude reference": _train_and_build(calibration, out_dir / "attitude_reference", seed)}
    datas = [read_imu_csv(p) for p in trial_paths(trials, data_dir)]
    rows, spreads = _rows(fmus, datas)
    groups = _group_means(rows, "filter")
    text = _markdown(groups, rows, spreads, [d.name for d in calibration])
    (out_dir / "broad_trained.md").write_text(text)
    with open(out_dir / "broad_trained.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=["name", "trial", "filter", "total", "heading", "inclination"])
        writer.writeheader()
        writer.writerows(rows)
    print(text)
    return {"groups": groups, "trials": rows, "spreads": spreads}
