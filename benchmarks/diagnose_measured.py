"""Reproduce the measured-data diagnoses in docs/diagnosis/ (issue 7).

    python benchmarks/diagnose_measured.py [--data ../shared/data] [--out docs/diagnosis]

BROAD (Laidig et al., Data 6(7), 2021, doi:10.3390/data6070072, CC-BY-4.0): the model is trained
on the undisturbed trials TRAIN_BROAD with references derived from ref_q and the optical marker
position (training.data.reference), decimated to ~57 Hz; the diagnosis runs on the OTHER undisturbed
trials DIAGNOSE_BROAD at full rate. pan_thermal (PAN cubesat, MIT): the identity model (a gain/bias
fit against ref_gyr = 0 of a static unit is degenerate); the diagnosis fits on the first 70 % of the
log and scores the last 30 %. Each writes OUT/<name>/trained/model.json (the model
diagnosed) and OUT/<name>/{diagnosis.json, model.json, report.md, *.png}, then prints a table.
The equivalent CLI call is printed for each.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from contract.layout import TRIAD_ORDER, settings_defaults
from training.artefact import ModelArtefact
from training.data.io import read_imu_csv
from training.data.reference import derive_references
from training.diagnosis.diagnose import diagnose
from training.models.thermal import ThermalModel
from training.train import train

ROOT = Path(__file__).resolve().parents[1]
TRAIN_BROAD = ("01_undisturbed_slow_rotation_A", "06_undisturbed_fast_rotation_A",
               "10_undisturbed_slow_translation_A")
DIAGNOSE_BROAD = ("02_undisturbed_slow_rotation_B", "11_undisturbed_slow_translation_B")
#: Every 5th sample of BROAD's 285.7 Hz for training: 57 Hz keeps the slow and fast motions
#: (≤ ~5 Hz) and makes the thermal fit a matter of seconds.
BROAD_DECIMATION = 5
PAN = "pan_etu_cold_chamber"


def _train_broad(data_dir: Path, out: Path) -> Path:
    """Model from the TRAIN_BROAD trials (derived references, decimated); returns its path."""
    sets = []
    for name in TRAIN_BROAD:
        d, _ = derive_references(read_imu_csv(data_dir / "broad" / f"{name}.csv.gz"))
        sets.append(d.slice(np.arange(0, len(d), BROAD_DECIMATION)))
    return train(sets, seed=0, progress=False).save(out / "trained" / "model.json")


def _identity_pan(data_dir: Path, out: Path) -> Path:
    """The identity model (every triad passes through, default settings): the pan_thermal log has
    only ref_gyr = 0 at rest, against which the gain/bias fit is degenerate (A = 0 reproduces a
    zero reference exactly), so the diagnosis starts from the raw sensor; returns its path."""
    model = ModelArtefact(seed=0, thermal={k: ThermalModel.identity(enabled=False) for k in TRIAD_ORDER},
                          settings=settings_defaults(),
                          notes=["identity model: the diagnosis of the pan_thermal log starts from the raw sensor"])
    return model.save(out / "trained" / "model.json")


def _transfer(data_dir: Path, out: Path) -> Path:
    """OUT/broad/transfer.md: every undisturbed BROAD trial's held-out-agnostic error (all rows)
    of each triad against its derived reference, with the trained and with the diagnosed model —
    whether the terms added on trials 02 and 11 (mounting B) carry over to the other trials and to
    mounting A."""
    from training.artefact import load_artefact
    from training.diagnosis.diagnose import load_recordings, residuals, targets_of
    models = {k: load_artefact(out / "broad" / p) for k, p in (("trained", "trained/model.json"),
                                                                ("diagnosed", "model.json"))}
    lines = ["# BROAD: do the diagnosed terms carry over to other trials?", "",
             "Regenerate: `python benchmarks/diagnose_measured.py --only broad`. RMS over all rows of each "
             "undisturbed trial against the references derived from the optical system (training.data.reference); "
             "diagnosed on 02 and 11 (mounting B).", "",
             "| trial | specific force, trained → diagnosed [m/s²] | field, trained → diagnosed [µT] |", "|---|---|---|"]
    for path in sorted((data_dir / "broad").glob("*_undisturbed_*.csv.gz")):
        datasets, _, smoothed = load_recordings([path])
        targets = targets_of(datasets[0])
        rms = {k: {t: _rms(residuals(m, datasets, targets, smoothed).residual[t]) for t in ("acc", "mag")}
               for k, m in models.items()}
        lines.append(f"| {path.name.removesuffix('.csv.gz')} | " + " | ".join(
            f"{rms['trained'][t]:.3f} → {rms['diagnosed'][t]:.3f}" for t in ("acc", "mag")) + " |")
    path = out / "broad" / "transfer.md"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def _rms(e: np.ndarray) -> float:
    e = e[np.all(np.isfinite(e), axis=1)]
    return float(np.sqrt(np.mean(e * e)))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "diagnosis")
    parser.add_argument("--only", choices=("broad", "pan_thermal"))
    args = parser.parse_args(argv)
    cases = {"broad": (_train_broad, [args.data / "broad" / f"{n}.csv.gz" for n in DIAGNOSE_BROAD]),
             "pan_thermal": (_identity_pan, [args.data / "pan_thermal" / f"{PAN}.csv.gz"])}
    rows = []
    for name, (fit, paths) in cases.items():
        if args.only and name != args.only:
            continue
        out = args.out / name
        model = fit(args.data, out)
        print(f"imufmu diagnose {' '.join(map(str, paths))} --model {model} --out {out}")
        r = diagnose(paths, model, out, seed=0)
        rows.append((name, r["target"], r["selected"]["name"] if r["selected"] else "-",
                     r["metric"], r["before"], r["after"], r["improvement_pct"]))
        if name == "broad":
            print(f"wrote {_transfer(args.data, args.out)}")
    print(f"{'data':12s} {'target':8s} {'selected':28s} {'before':>10s} {'after':>10s} {'gain %':>7s}  metric")
    for name, target, sel, metric, before, after, pct in rows:
        print(f"{name:12s} {target:8s} {sel:28s} {before:10.4g} {after:10.4g} {pct:7.1f}  {metric}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
