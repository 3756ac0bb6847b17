"""`imufmu diagnose` on undeclared effects: the tables in docs/diagnosis/effects.md (issue 14) and
docs/diagnosis/effects_in_calibration.md (issue 30: the effect in the calibration recording too).

    python benchmarks/diagnose_effects.py [--out docs/diagnosis/effects.md] [--work DIR]
    python benchmarks/diagnose_effects.py --in-calibration [--out docs/diagnosis/effects_in_calibration.md]

Trains the diag_base sensor on scenarios/variants/diag_calibration_clean.toml, simulates the
held-out handheld recording scenarios/variants/diag_effects.toml once, injects every effect of the
tests' generator (tests/effects.py) and diagnoses each at the defaults. For each: the effect
selected, its physical reading, the held-out error before/after (training.diagnosis.diagnose's metric) and
the same held-out error through the FMU (fmpy, FMI 2) built from the base and the diagnosed
artefacts. The noise floor is the sensor's white noise per sample (benchmarks/effect_sizes.py).
With --in-calibration every effect is injected into the calibration recording as well (as on a real
sensor, whose effects are present whenever it runs), and the model is trained on that. An effect of a
family `train` itself models (TRAIN_FAMILIES: its bias(T)) leaves nothing for the diagnosis; its row then
reads what `train`'s calibration removes: the runtime's output with the effect-free calibration minus its
output with the calibration trained on the effect, on the diagnosed recording, regressed on T − 25 °C.
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
from training.artefact import load_artefact  # noqa: E402
from training.data.io import write_imu_csv  # noqa: E402
from training.diagnosis import diagnose as diagnose_module  # noqa: E402
from training.diagnosis.diagnose import diagnose  # noqa: E402
from training.simulator import load_scenario, simulate  # noqa: E402
from training.train import train  # noqa: E402

VARIANTS = ROOT / "scenarios" / "variants"
COMMANDS = {False: "python benchmarks/diagnose_effects.py --out docs/diagnosis/effects.md",
            True: "python benchmarks/diagnose_effects.py --in-calibration --out docs/diagnosis/effects_in_calibration.md"}
#: What each table's training saw.
TRAINING = {False: "trained on `scenarios/variants/diag_calibration_clean.toml` (its declared errors are all in "
                   "the model); every effect is injected by the tests' generator (`tests/effects.py`) into one "
                   "held-out handheld recording",
            True: "every effect injected by the tests' generator (`tests/effects.py`, the same magnitudes) into the "
                  "calibration recording `scenarios/variants/diag_calibration_clean.toml` AND into one held-out "
                  "handheld recording; trained on the calibration recording with the effect, so `train`'s linear "
                  "fit saw it (the diagnosis refits the triad's gain matrix with every family)"}
NOISE = {"gyr": "0.030 °/s", "acc": "0.0098 m/s²", "mag": "0.10 µT"}
#: Regressor families (tests/effects.py's regressor_family) of what `train` fits itself: the bias(T) polynomial.
TRAIN_FAMILIES = {"temp"}
#: Temperature the calibration's reading is referred to [°C] (tests/effects.py's T_REF_C).
T_REF_C = 25.0


def calibration_reading(name: str, clean_model: Path, model: Path, data) -> str:
    """What the calibration trained on the effect removes beyond the effect-free one, per °C of T − T_REF_C,
    on the triad's output (display unit): '' for an effect outside TRAIN_FAMILIES."""
    effect = EFFECTS[name]
    if not effect.family or not effect.family <= TRAIN_FAMILIES:
        return ""
    triad = effect.target
    unit, scale = diagnose_module.DISPLAY[triad]
    clean, trained = (diagnose_module._run(load_artefact(m), data)[:, diagnose_module._SLICES[triad]]
                      for m in (clean_model, model))
    X = np.column_stack([np.ones(len(data.t)), data.temp - T_REF_C])
    ok = np.all(np.isfinite(clean - trained), axis=1) & np.isfinite(data.temp)
    slope = np.linalg.lstsq(X[ok], (clean - trained)[ok], rcond=None)[0][1] * scale
    return f"in `train`'s bias(T): {np.round(slope, 4).tolist()} {unit}/°C removed beyond the effect-free calibration"


def _row(name: str, result: dict, fmu_pct: float | None, in_training: str = "") -> str:
    effect, sel = EFFECTS[name], result["selected"]
    if sel is None:
        return (f"| {name} | {effect.description} | nothing | {in_training or '—'} | {result['before']:.4g} | "
                f"{result['after']:.4g} | 0 % | — | {NOISE[effect.target] if in_training else '—'} |")
    triad = effect.target or ""
    return (f"| {name} | {effect.description} | {sel['name']} → {sel['target']} | {'; '.join(sel['readings']) or '—'} | "
            f"{result['before']:.4g} | {result['after']:.4g} | {result['improvement_pct']:.1f} % | "
            f"{fmu_pct:.1f} % | {NOISE.get(triad, '')} |")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=None,
                        help="table to write (default docs/diagnosis/effects.md, or effects_in_calibration.md)")
    parser.add_argument("--in-calibration", action="store_true",
                        help="inject every effect into the calibration recording too and train on it")
    parser.add_argument("--work", type=Path, default=None, help="working folder (default: a temporary one)")
    parser.add_argument("--only", nargs="+", choices=sorted(EFFECTS), help="these effects only (prints, writes no table)")
    args = parser.parse_args(argv)
    from tqdm import tqdm
    both = args.in_calibration
    out = args.out or ROOT / "docs" / "diagnosis" / ("effects_in_calibration.md" if both else "effects.md")
    work = args.work or Path(tempfile.mkdtemp(prefix="diagnose_effects_"))
    cal = simulate(load_scenario(VARIANTS / "diag_calibration_clean.toml"))
    model = clean_model = train([cal], seed=0, progress=False).save(work / "model" / "model.json")
    clean = simulate(load_scenario(VARIANTS / "diag_effects.toml"))
    base_fmu = _build(model, work / "base.fmu")
    rows = []
    for name, effect in tqdm([(k, v) for k, v in EFFECTS.items() if not args.only or k in args.only],
                             desc="effects", unit="effect"):
        if both:
            model = train([effect(cal, np.random.default_rng(3))], seed=0, progress=False).save(
                work / name / "model" / "model.json")
            base_fmu = _build(model, work / name / "base.fmu")
        data = effect(clean, np.random.default_rng(7))
        path = write_imu_csv(data, work / name / "diag_effects.csv.gz")
        result = diagnose([path], model, work / name / "report", seed=0, plots=False, progress=False, limits=False)
        fmu_pct = None
        if result["selected"] is not None:
            new = work / name / "report" / "model.json"
            before = _fmu_error(base_fmu, model, data, effect.target)
            after = _fmu_error(_build(new, work / name / "diagnosed.fmu"), new, data, effect.target)
            fmu_pct = 100.0 * (before - after) / before
        in_training = calibration_reading(name, clean_model, model, data) if both and fmu_pct is None else ""
        rows.append(_row(name, result, fmu_pct, in_training))
        print(rows[-1])
    if args.only:
        return 0
    title = "# `imufmu diagnose` on effects nobody declared" + (", present in the calibration too" if both else "")
    lines = [title, "",
             f"Regenerate: `{COMMANDS[both]}` (about {'ten' if both else 'two'} minutes).", "",
             f"Sensor `scenarios/sensors/diag_base.toml`, {TRAINING[both]} (`scenarios/variants/diag_effects.toml`, "
             "150 s at 100 Hz, 15 → 35 °C), diagnosed at the defaults. Error: held-out RMS of the effect's triad "
             "against the truth (every third of 48 blocks); FMU: the same rows through fmpy with the FMU built from "
             "the base and from the diagnosed artefact. Noise floor: the triad's white noise per sample."
             + (" An effect of a family `train` fits itself (its bias(T)) leaves the diagnosis nothing: its reading "
                "is what `train`'s calibration removes beyond the effect-free calibration (the runtime's outputs "
                "with both on the diagnosed recording, regressed on T − 25 °C)." if both else ""), "",
             "| effect | injected | selected | reading | before | after | lower by | FMU lower by | noise floor |",
             "|---|---|---|---|---|---|---|---|---|"] + rows
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(lines) + "\n", encoding="utf-8")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
