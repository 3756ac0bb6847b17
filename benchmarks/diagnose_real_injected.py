"""Undeclared effects injected into REAL recordings, in the calibration and the diagnosed recordings
alike (issue 30's acceptance on measured data): found with the right family, the reading against the
injected value, the held-out error before and after, and the detection limit the diagnosis states.

    python benchmarks/diagnose_real_injected.py [--data ../shared/data] [--out DIR] [--only NAME ...]

BROAD (Laidig et al., Data 6(7), 2021, CC-BY-4.0): `train` on the undisturbed trials 01, 06 and 10
(references derived from ref_q and the marker position, decimated 5×, as benchmarks/diagnose_measured.py),
`imufmu diagnose` on trials 02 and 11 at full rate; every recording carries the effect. An effect acts
on the true signal; a real recording has none, so the effect is computed from the recording's own raw
triads (tests/effects.py with the raw signals as its "truth": the sensor's raw rate is the true rate
up to its calibration errors and noise), seeded waveforms for the aux columns.

x-io handheld (no reference at all): the first 60 % of the log calibrates, the last 40 % is diagnosed,
so the diagnosis sees only the invariants (field norm, gravity norm at rest); the field of an outside
current is the effect a norm can show.

A case not found at the issue's size is run again at the size its family's stated detection limit says
the loop resolves: the injected change scaled so that its RMS on the diagnosed recordings is
LIMIT_MULTIPLE times the limit the first run reported (every effect here is linear in its size), which
tests the stated limit as much as the loop.

Prints a Markdown table (writes it to OUT/real_injected.md with each case's report under OUT/<case>/).
"""
from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))

from effects import EFFECTS  # noqa: E402

from training.artefact import load_artefact  # noqa: E402
from training.data.io import read_imu_csv, write_imu_csv  # noqa: E402
from training.data.reference import derive_references  # noqa: E402
from training.diagnosis.diagnose import diagnose  # noqa: E402
from training.display import DISPLAY  # noqa: E402
from training.train import train  # noqa: E402

TRAIN_BROAD = ("01_undisturbed_slow_rotation_A", "06_undisturbed_fast_rotation_A",
               "10_undisturbed_slow_translation_A")
DIAGNOSE_BROAD = ("02_undisturbed_slow_rotation_B", "11_undisturbed_slow_translation_B")
BROAD_DECIMATION = 5
XIO = "xio_handheld"
#: Share of the x-io log that calibrates; the rest is diagnosed.
XIO_CALIBRATION = 0.6
#: Issue 30: on real recordings the reading within 25 % of the injected value.
READING_TOLERANCE = 0.25
#: A case missed at the issue's size is rerun with its effect this many times its family's stated
#: detection limit (held-out RMS): at the limit a family is selected half the time at best; three times it
#: leaves room for the reading's own error.
LIMIT_MULTIPLE = 3.0

#: case -> (data set, effect of tests/effects.py, magnitude, the candidate family that reads it, the injected
#: value the diagnosed model's terms must carry: {(term target, a, b): value in the terms' units}).
CASES = {
    "gyro rate nonlinearity": ("broad", "gyro_rate_scale", {"k": (0.005, -0.004, 0.006)}, "angular rate signed square",
                               {(f"gyr_{a}", f"gyr_{a}", f"abs_gyr_{a}"): v for a, v in zip("xyz", (0.005, -0.004, 0.006))}),
    "gyro cross-axis products": ("broad", "gyro_cross_products", {"k": (0.006, -0.005)}, "angular rate pairwise products",
                                 {("gyr_y", "gyr_x", "gyr_z"): 0.006, ("gyr_z", "gyr_x", "gyr_y"): -0.005}),
    "supply-voltage gyro bias + decoy": ("broad", "supply_gyro_bias", {"c_dps_per_v": (0.8, -0.6, 0.7)},
                                         "aux_supply_voltage", {(f"gyr_{a}", "aux_1", None): np.radians(v)
                                                                for a, v in zip("xyz", (0.8, -0.6, 0.7))}),
    "field of a motor current": ("broad", "aux_field", {"c_ut_per_a": (1.5, -1.0, 2.0)}, "aux_motor_current",
                                 {(f"mag_{a}", "aux_1", None): v for a, v in zip("xyz", (1.5, -1.0, 2.0))}),
    "gyro g-sensitivity": ("broad", "gyro_g_sensitivity", {}, "specific force",
                           {(f"gyr_{'xyz'[i]}", f"acc_{'xyz'[j]}", None): np.radians(g) / 9.80665
                            for i, row in enumerate(((0.4, 0.08, -0.06), (-0.07, 0.35, 0.1), (0.05, -0.09, 0.45)))
                            for j, g in enumerate(row)}),
    "accelerometer cross-axis products": ("broad", "acc_cross_nonlinearity", {}, "specific force pairwise products",
                                          {("acc_x", "acc_x", "acc_y"): 3e-3, ("acc_y", "acc_y", "acc_z"): -3e-3,
                                           ("acc_z", "acc_x", "acc_z"): 3e-3}),
    "field of a motor current (no reference)": ("xio", "aux_field", {"c_ut_per_a": (1.5, -1.0, 2.0)},
                                                "aux_motor_current", {(f"mag_{a}", "aux_1", None): v
                                                                      for a, v in zip("xyz", (1.5, -1.0, 2.0))}),
}


def _inject(data, effect: str, magnitude: dict, seed: int, scale: float = 1.0):
    """The recording with the effect computed from its own raw triads (its references kept), its change of
    the target triad times `scale`."""
    raw_truth = replace(data, ref_gyr=data.gyr, ref_acc=data.acc, ref_mag=data.mag)
    out = EFFECTS[effect](raw_truth, np.random.default_rng(seed), **magnitude)
    triad = EFFECTS[effect].target
    changed = getattr(data, triad) + scale * (getattr(out, triad) - getattr(data, triad))
    return replace(out, ref_gyr=data.ref_gyr, ref_acc=data.ref_acc, ref_mag=data.ref_mag, **{triad: changed})


def _effect_rms(data, effect: str, magnitude: dict, seed: int) -> float:
    """RMS of the effect's change of its triad on a recording, in the diagnosis's display unit."""
    triad = EFFECTS[effect].target
    change = getattr(_inject(data, effect, magnitude, seed), triad) - getattr(data, triad)
    return float(np.sqrt(np.nanmean(change ** 2))) * DISPLAY[triad][1]


def _broad(data_dir: Path, effect: str, magnitude: dict, work: Path, scale: float) -> tuple[list, list[Path], float]:
    """(calibration recordings, diagnosed paths, the effect's RMS on the diagnosed recordings at scale 1)."""
    calibration = []
    for k, name in enumerate(TRAIN_BROAD):
        d, _ = derive_references(read_imu_csv(data_dir / "broad" / f"{name}.csv.gz"))
        d = _inject(d, effect, magnitude, seed=10 + k, scale=scale)
        calibration.append(d.slice(np.arange(0, len(d), BROAD_DECIMATION)))
    paths, rms = [], []
    for k, name in enumerate(DIAGNOSE_BROAD):
        raw = read_imu_csv(data_dir / "broad" / f"{name}.csv.gz")
        rms.append(_effect_rms(raw, effect, magnitude, seed=20 + k))
        paths.append(write_imu_csv(_inject(raw, effect, magnitude, seed=20 + k, scale=scale),
                                   work / "data" / f"{name}.csv.gz"))
    return calibration, paths, float(np.sqrt(np.mean(np.square(rms))))


def _xio(data_dir: Path, effect: str, magnitude: dict, work: Path, scale: float) -> tuple[list, list[Path], float]:
    raw = read_imu_csv(data_dir / XIO / f"{XIO}.csv.gz")
    cut = int(XIO_CALIBRATION * len(raw))
    d = _inject(raw, effect, magnitude, seed=30, scale=scale)
    rms = _effect_rms(raw.slice(np.arange(cut, len(raw))), effect, magnitude, seed=30)
    return ([d.slice(np.arange(cut))], [write_imu_csv(d.slice(np.arange(cut, len(d))), work / "data" / f"{XIO}.csv.gz")],
            rms)


def _read(model_path: Path, keys: dict) -> dict:
    """The coefficient the diagnosed model's terms carry for each key (summed over its terms)."""
    terms = load_artefact(model_path).terms
    return {key: sum(t["coefficient"] for t in terms if (t["target"], t["a"], t["b"]) == key) for key in keys}


def run_case(name: str, data_dir: Path, out: Path, scale: float = 1.0) -> dict:
    """One case at `scale` times the issue's size."""
    data_set, effect, magnitude, family, injected = CASES[name]
    injected = {k: scale * v for k, v in injected.items()}
    work = out / (name.replace(" ", "_").replace("(", "").replace(")", "") + ("" if scale == 1.0 else f"_x{scale:g}"))
    calibration, paths, effect_rms = (_broad if data_set == "broad" else _xio)(data_dir, effect, magnitude, work, scale)
    model = train(calibration, seed=0, progress=False).save(work / "trained" / "model.json")
    result = diagnose(paths, model, work / "report", seed=0, plots=False, progress=False)
    target = EFFECTS[effect].target if data_set == "broad" else f"{EFFECTS[effect].target}_norm"
    read = _read(work / "report" / "model.json", injected)
    found = [it for it in result["iterations"] if it["target"] == target and family in it["selected"]["families"]]
    limit = next((lim for lim in result["detection_limits"] if lim["target"] == target and lim["family"] == family), None)
    return {"case": name, "data": data_set, "target": target, "family": family, "scale": scale,
            "effect_rms": scale * effect_rms,
            "found": bool(found), "readings": [x for it in found for x in it["selected"]["readings"]],
            "max_reading_error": max(abs(read[k] - v) / abs(v) for k, v in injected.items()),
            "norm_reading_error": float(np.linalg.norm([read[k] - v for k, v in injected.items()])
                                        / np.linalg.norm(list(injected.values()))),
            "before": result["metrics_before"][target], "after": result["metrics_after"][target],
            "metric": result["metric_names"][target], "selected": [it["selected"]["name"] + " -> " + it["target"]
                                                                   for it in result["iterations"]],
            "limit": limit, "report": str(work / "report" / "report.md")}


def scale_for(row: dict) -> float | None:
    """The scale at which a missed case's effect is LIMIT_MULTIPLE times its family's stated detection limit
    (None when found, without a stated limit, or already above it)."""
    limit = row["limit"]
    if row["found"] or limit is None or limit["status"] != "limit" or not limit["rms"]:
        return None
    scale = float(f"{LIMIT_MULTIPLE * limit['rms'] / row['effect_rms']:.2g}")
    return scale if scale > 1.0 else None


def _limit_text(limit: dict | None) -> str:
    if limit is None:
        return "–"
    if limit["status"] != "limit":
        return limit["status"]
    return f"{limit['rms']:.3g} RMS" + (f": {limit['reading']}" if limit["reading"] else "")


def _table(rows: list[dict]) -> str:
    lines = ["| case | data | size | effect RMS | family on target | found | reading | largest reading error | "
             "reading error of the whole (norm) | "
             "target's held-out error, before → after the loop | detection limit of the family after the loop | "
             "everything selected |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        size = "issue's" if r["scale"] == 1.0 else f"× {r['scale']:g}"
        lines.append(f"| {r['case']} | {r['data']} | {size} | {r['effect_rms']:.3g} | {r['family']} on {r['target']} | "
                     f"{'yes' if r['found'] else 'no'} | "
                     f"{'; '.join(r['readings']) or '–'} | {100 * r['max_reading_error']:.1f} % | "
                     f"{100 * r['norm_reading_error']:.1f} % | "
                     f"{r['before']:.4g} → {r['after']:.4g} ({r['metric']}) | {_limit_text(r['limit'])} | "
                     f"{'; '.join(r['selected']) or 'nothing'} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data")
    parser.add_argument("--out", type=Path, default=ROOT / "bench" / "diagnose_real_injected")
    parser.add_argument("--only", nargs="+", choices=sorted(CASES))
    args = parser.parse_args(argv)
    rows = []
    for name in args.only or CASES:
        rows.append(run_case(name, args.data, args.out))
        scale = scale_for(rows[-1])
        if scale is not None:
            rows.append(run_case(name, args.data, args.out, scale))
        for row in rows[-1 if scale is None else -2:]:
            print(f"{name} × {row['scale']:g}: found {row['found']}, reading error {100 * row['max_reading_error']:.1f} %, "
                  f"limit {_limit_text(row['limit'])}", flush=True)
    table = _table(rows)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "real_injected.md").write_text(table + "\n", encoding="utf-8")
    (args.out / "real_injected.json").write_text(json.dumps(rows, indent=2, default=str) + "\n", encoding="utf-8")
    print(table)
    return 0 if all(r["max_reading_error"] <= READING_TOLERANCE for r in rows) else 1


if __name__ == "__main__":
    raise SystemExit(main())
