"""`imufmu diagnose` on undeclared effects: the table in docs/diagnosis/effects.md (issue 14).

    python benchmarks/diagnose_effects.py [--out docs/diagnosis/effects.md] [--work DIR]

Trains the diag_base sensor on scenarios/variants/diag_calibration_clean.toml, simulates the
held-out handheld recording scenarios/variants/diag_effects.toml once, injects every effect of the
tests' generator (tests/effects.py) and diagnoses each at the defaults. For each: the effect
selected, its physical reading, the held-out error before/after (training.diagnosis.diagnose's metric) and
the same held-out error through the FMU (fmpy, FMI 2) built from the base and the diagnosed
artefacts. The noise floor is the sensor's white noise per sample (benchmarks/effect_sizes.py).
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from effects import EFFECTS  # noqa: E402
from test_diagnose_effects import _build, _fmu_error  # noqa: E402
from training.data.io import write_imu_csv  # noqa: E402
from training.diagnosis.diagnose import diagnose  # noqa: E402
from training.simulator import load_scenario, simulate  # noqa: E402
from training.train import train  # noqa: E402

VARIANTS = ROOT / "scenarios" / "variants"
COMMAND = "python benchmarks/diagnose_effects.py --out docs/diagnosis/effects.md"
NOISE = {"gyr": "0.030 °/s", "acc": "0.0098 m/s²", "mag": "0.10 µT"}


def _row(name: str, result: dict, fmu_pct: float | None) -> str:
    effect, sel = EFFECTS[name], result["selected"]
    if sel is None:
        return (f"| {name} | {effect.description} | nothing | — | {result['before']:.4g} | {result['after']:.4g} | "
                f"0 % | — | — |")
    triad = effect.target or ""
    return (f"| {name} | {effect.description} | {sel['name']} → {sel['target']} | {'; '.join(sel['readings']) or '—'} | "
            f"{result['before']:.4g} | {result['after']:.4g} | {result['improvement_pct']:.1f} % | "
            f"{fmu_pct:.1f} % | {NOISE.get(triad, '')} |")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "diagnosis" / "effects.md")
    parser.add_argument("--work", type=Path, default=None, help="working folder (default: a temporary one)")
    args = parser.parse_args(argv)
    from tqdm import tqdm
    work = args.work or Path(tempfile.mkdtemp(prefix="diagnose_effects_"))
    cal = simulate(load_scenario(VARIANTS / "diag_calibration_clean.toml"))
    model = train([cal], seed=0, progress=False).save(work / "model" / "model.json")
    clean = simulate(load_scenario(VARIANTS / "diag_effects.toml"))
    base_fmu = _build(model, work / "base.fmu")
    rows = []
    for name, effect in tqdm(EFFECTS.items(), desc="effects", unit="effect"):
        data = effect(clean, np.random.default_rng(7))
        path = write_imu_csv(data, work / name / "diag_effects.csv.gz")
        result = diagnose([path], model, work / name / "report", seed=0, plots=False, progress=False)
        fmu_pct = None
        if result["selected"] is not None:
            new = work / name / "report" / "model.json"
            before = _fmu_error(base_fmu, model, data, effect.target)
            after = _fmu_error(_build(new, work / name / "diagnosed.fmu"), new, data, effect.target)
            fmu_pct = 100.0 * (before - after) / before
        rows.append(_row(name, result, fmu_pct))
        print(rows[-1])
    lines = ["# `imufmu diagnose` on effects nobody declared", "",
             f"Regenerate: `{COMMAND}` (about two minutes).", "",
             "Sensor `scenarios/sensors/diag_base.toml`, trained on `scenarios/variants/diag_calibration_clean.toml` "
             "(its declared errors are all in the model); every effect is injected by the tests' generator "
             "(`tests/effects.py`) into one held-out handheld recording (`scenarios/variants/diag_effects.toml`, "
             "150 s at 100 Hz, 15 → 35 °C) and diagnosed at the defaults. Error: held-out RMS of the effect's triad "
             "against the truth (every third of 48 blocks); FMU: the same rows through fmpy with the FMU built from "
             "the base and from the diagnosed artefact. Noise floor: the triad's white noise per sample.", "",
             "| effect | injected | selected | reading | before | after | lower by | FMU lower by | noise floor |",
             "|---|---|---|---|---|---|---|---|---|"] + rows
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("\n".join(lines) + "\n", encoding="utf-8")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
