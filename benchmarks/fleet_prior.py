"""What the fleet prior buys (issue 19 item 3): new units, never in the fleet, calibrated from the first
60 s of their calibration recording with and without `--prior`, and from the whole recording, scored on
their held-out test recording through the C runtime (training.fleet.heldout).

Usage: OMP_NUM_THREADS=1 .venv/bin/python benchmarks/fleet_prior.py --prior FLEET_OUT/fleet.json
       [--fleet scenarios/fleet/mems_grade.toml] [--units 5] [--seconds 60]
or, building the prior first from a fleet of K units (simulate-fleet --seed 0, then fleet train):
       OMP_NUM_THREADS=1 .venv/bin/python benchmarks/fleet_prior.py --fleet-units K [--units 5] [--seconds 60]
The new units are units 1000, 1001, … of the fleet seed 0, so none was in a fleet of fewer than 1000.

The column `slope-limited` predicts the rate error of any calibration from the first seconds at one
temperature: the full calibration's, with (in quadrature) what the unit's gyro bias slope differs
from the type's (the sensor file's nominal, the population's mean: all a prior can know) times the
test's distance in temperature from the seconds' mean. Its ratio to the full calibration is the
information limit of the rate bound.
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT)]

from training.data.io import read_imu_csv, write_imu_csv  # noqa: E402
from training.fleet.heldout import HELD_OUT_METRICS, held_out_errors  # noqa: E402
from training.fleet.simulate import simulate_unit  # noqa: E402
from training.fleet.spec import load_fleet  # noqa: E402
from training.train import train_to_folder  # noqa: E402

#: First unit index of the new units.
FIRST_NEW_UNIT = 1000
#: Acceptance ratios of issue 19: with the prior ≤ 1.5 × the full calibration, ≤ 0.5 × the same
#: seconds without the prior.
RATIO_FULL, RATIO_SHORT = 1.5, 0.5


def slope_limited(spec, folder: Path, short_temp: np.ndarray, tests: list[Path], full_rate: float) -> float:
    """The rate error [°/s] predicted for a calibration from the short window: full_rate and, in
    quadrature, the RMS over the tests' samples and axes of the unit's gyro bias slope error against
    the type's nominal times the temperature's distance from the window's mean."""
    drawn = json.loads((folder / "unit.json").read_text())["sensor"]["gyr"]["bias_t1_dps_per_c"]
    slope_error = np.asarray(drawn) - np.asarray(spec.sensor_raw["gyr"]["bias_t1_dps_per_c"])
    distance = np.concatenate([read_imu_csv(p).temp for p in tests]) - float(np.mean(short_temp))
    return float(np.sqrt(full_rate ** 2 + np.mean(np.outer(distance, slope_error) ** 2)))


def unit_rows(spec, k: int, prior: Path, seconds: float, work: Path) -> tuple[dict[str, dict[str, float]], float]:
    """({calibration: {metric: value}} of new unit k: full, first `seconds` s, same with the prior;
    its slope-limited rate error [°/s])."""
    folder = simulate_unit(spec, k, 0, work)
    full = folder / "calibration" / "calibration.csv.gz"
    data = read_imu_csv(full)
    window = data.slice(slice(0, int(round(seconds * data.meta["rate_hz"]))))
    short = write_imu_csv(window, work / f"short_{k}.csv.gz")
    tests = sorted((folder / "test").glob("*.csv.gz"))
    rows = {}
    for label, paths, prior_path in (("full recording", [full], None), (f"first {seconds:g} s", [short], None),
                                     (f"first {seconds:g} s + fleet prior", [short], prior)):
        done = train_to_folder(paths, work / f"{k}_{len(rows)}", progress=False, prior_path=prior_path)
        rows[label] = held_out_errors(done.model, tests)
    return rows, slope_limited(spec, folder, window.temp, tests, rows["full recording"]["rate_err_dps"])


def fleet_prior(fleet: Path, units: int, work: Path) -> Path:
    """fleet.json of a fleet of `units` units (fleet seed 0) trained on the local cluster."""
    from training.fleet.report import write_fleet_report
    from training.fleet.simulate import simulate_fleet
    from training.fleet.train import train_fleet
    simulate_fleet(fleet, units, work / "fleet", seed=0)
    return write_fleet_report(train_fleet(work / "fleet", work / "fleet_out"), work / "fleet_out")[0]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    source = p.add_mutually_exclusive_group(required=True)
    source.add_argument("--prior", type=Path, help="fleet.json of `imufmu fleet train`")
    source.add_argument("--fleet-units", type=int, help="build the prior from a fleet of this many units first")
    p.add_argument("--fleet", type=Path, default=ROOT / "scenarios" / "fleet" / "mems_grade.toml")
    p.add_argument("--units", type=int, default=5)
    p.add_argument("--seconds", type=float, default=60.0)
    a = p.parse_args(argv)
    spec = load_fleet(a.fleet)
    print("| unit | calibration | " + " | ".join(HELD_OUT_METRICS) + " | slope-limited rate [°/s] |")
    print("|---|---|" + "---|" * (len(HELD_OUT_METRICS) + 1))
    ratios, limits = [], []
    with tempfile.TemporaryDirectory(prefix="imufusion-fleet-prior-") as tmp:
        prior = a.prior or fleet_prior(a.fleet, a.fleet_units, Path(tmp))
        for k in range(FIRST_NEW_UNIT, FIRST_NEW_UNIT + a.units):
            rows, limit = unit_rows(spec, k, prior, a.seconds, Path(tmp))
            for label, errors in rows.items():
                print(f"| {k} | {label} | " + " | ".join(f"{errors[m]:.4f}" for m in HELD_OUT_METRICS) + " | "
                      + (f"{limit:.4f} |" if label.endswith("prior") else "|"), flush=True)
            full, short, with_prior = rows.values()
            limits.append(limit / full["rate_err_dps"])
            ratios.append([[with_prior[m] / full[m], with_prior[m] / short[m]] for m in HELD_OUT_METRICS])
    worst = np.max(np.array(ratios), axis=0)
    print(f"\nworst ratio over {a.units} units, with the prior / full calibration (bound {RATIO_FULL:g}) and "
          f"/ the same {a.seconds:g} s without it (bound {RATIO_SHORT:g}):")
    for m, (to_full, to_short) in zip(HELD_OUT_METRICS, worst):
        print(f"- {m}: {to_full:.2f} ({'met' if to_full <= RATIO_FULL else 'NOT met'}), "
              f"{to_short:.2f} ({'met' if to_short <= RATIO_SHORT else 'NOT met'})")
    print(f"- slope-limited rate / full calibration: {min(limits):.2f}-{max(limits):.2f}, mean {np.mean(limits):.2f} "
          f"(what the unit's own temperature slope, unseen in these {a.seconds:g} s, costs any calibration)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
