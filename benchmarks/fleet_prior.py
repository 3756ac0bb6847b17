"""What the fleet prior buys (issue 19 item 3): new units, never in the fleet, calibrated from the first
60 s of their calibration recording with and without `--prior`, and from the whole recording, scored on
their held-out test recording through the C runtime (training.fleet.heldout).

Usage: OMP_NUM_THREADS=1 .venv/bin/python benchmarks/fleet_prior.py --prior FLEET_OUT/fleet.json
       [--fleet scenarios/fleet/mems_grade.toml] [--units 5] [--seconds 60]
or, building the prior first from a fleet of K units (simulate-fleet --seed 0, then fleet train):
       OMP_NUM_THREADS=1 .venv/bin/python benchmarks/fleet_prior.py --fleet-units K [--units 5] [--seconds 60]
The new units are units 1000, 1001, … of the fleet seed 0, so none was in a fleet of fewer than 1000.
"""
from __future__ import annotations

import argparse
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


def unit_rows(spec, k: int, prior: Path, seconds: float, work: Path) -> dict[str, dict[str, float]]:
    """{calibration: {metric: value}} of new unit k: full, first `seconds` s, same with the prior."""
    folder = simulate_unit(spec, k, 0, work)
    full = folder / "calibration" / "calibration.csv.gz"
    data = read_imu_csv(full)
    short = write_imu_csv(data.slice(slice(0, int(round(seconds * data.meta["rate_hz"])))), work / f"short_{k}.csv.gz")
    tests = sorted((folder / "test").glob("*.csv.gz"))
    rows = {}
    for label, paths, prior_path in (("full recording", [full], None), (f"first {seconds:g} s", [short], None),
                                     (f"first {seconds:g} s + fleet prior", [short], prior)):
        done = train_to_folder(paths, work / f"{k}_{len(rows)}", progress=False, prior_path=prior_path)
        rows[label] = held_out_errors(done.model, tests)
    return rows


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
    print("| unit | calibration | " + " | ".join(HELD_OUT_METRICS) + " |")
    print("|---|---|" + "---|" * len(HELD_OUT_METRICS))
    ratios = []
    with tempfile.TemporaryDirectory(prefix="imufusion-fleet-prior-") as tmp:
        prior = a.prior or fleet_prior(a.fleet, a.fleet_units, Path(tmp))
        for k in range(FIRST_NEW_UNIT, FIRST_NEW_UNIT + a.units):
            rows = unit_rows(spec, k, prior, a.seconds, Path(tmp))
            for label, errors in rows.items():
                print(f"| {k} | {label} | " + " | ".join(f"{errors[m]:.4f}" for m in HELD_OUT_METRICS) + " |", flush=True)
            full, short, prior = rows.values()
            ratios.append([[prior[m] / full[m], prior[m] / short[m]] for m in HELD_OUT_METRICS])
    worst = np.max(np.array(ratios), axis=0)
    print(f"\nworst ratio over {a.units} units, with the prior / full calibration (bound {RATIO_FULL:g}) and "
          f"/ the same {a.seconds:g} s without it (bound {RATIO_SHORT:g}):")
    for m, (to_full, to_short) in zip(HELD_OUT_METRICS, worst):
        print(f"- {m}: {to_full:.2f} ({'met' if to_full <= RATIO_FULL else 'NOT met'}), "
              f"{to_short:.2f} ({'met' if to_short <= RATIO_SHORT else 'NOT met'})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
