"""What the fleet prior buys (issue 19 item 3): new units, never in the fleet, calibrated from the first
60 s of their calibration recording with and without `--prior`, and from the whole recording, scored on
their held-out test recording through the C runtime (training.fleet.heldout).

Usage: OMP_NUM_THREADS=1 .venv/bin/python benchmarks/fleet_prior.py --prior FLEET_OUT/fleet.json
       [--fleet scenarios/fleet/mems_grade.toml] [--units 5] [--seconds 60] [--two-temperatures]
or, building the prior first from a fleet of K units (simulate-fleet --seed 0, then fleet train):
       OMP_NUM_THREADS=1 .venv/bin/python benchmarks/fleet_prior.py --fleet-units K [--units 5] [--seconds 60]
The new units are units 1000, 1001, … of the fleet seed 0, so none was in a fleet of fewer than 1000.

The column `rate, slope-limited` predicts the rate error of any calibration from the first seconds at one
temperature: the full calibration's, with (in quadrature) what the unit's gyro bias slope differs
from the type's (the sensor file's nominal, the population's mean: all a prior can know) times the
test's distance in temperature from the seconds' mean. Its ratio to the full calibration is the
information limit of the rate bound. With --two-temperatures the seconds are split in two halves: the
recording's first, and the first at its highest temperature (within HOT_BAND_C), so the short calibration
sees the unit's own slope; the slope-limited column does not apply there and reads "—".
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
#: Column titles of the held-out metrics, with their units.
LABELS = {"rate_err_dps": "rate [°/s]", "field_err_ut": "field [µT]"}
#: Acceptance ratios of issue 19: with the prior ≤ 1.5 × the full calibration, ≤ 0.5 × the same
#: seconds without the prior.
RATIO_FULL, RATIO_SHORT = 1.5, 0.5
#: --two-temperatures: the second half starts at the first sample this close [°C] to the highest temperature.
HOT_BAND_C = 0.1


def slope_limited(spec, folder: Path, short_temp: np.ndarray, tests: list[Path], full_rate: float) -> float:
    """The rate error [°/s] predicted for a calibration from the short window: full_rate and, in
    quadrature, the RMS over the tests' samples and axes of the unit's gyro bias slope error against
    the type's nominal times the temperature's distance from the window's mean."""
    drawn = json.loads((folder / "unit.json").read_text())["sensor"]["gyr"]["bias_t1_dps_per_c"]
    slope_error = np.asarray(drawn) - np.asarray(spec.sensor_raw["gyr"]["bias_t1_dps_per_c"])
    distance = np.concatenate([read_imu_csv(p).temp for p in tests]) - float(np.mean(short_temp))
    return float(np.sqrt(full_rate ** 2 + np.mean(np.outer(distance, slope_error) ** 2)))


def short_windows(data, seconds: float, two_temperatures: bool) -> list:
    """The short calibration's recordings: the first `seconds` s, or (two_temperatures) half of them from
    the start and half from the first sample within HOT_BAND_C of the highest temperature."""
    n = int(round(seconds * data.meta["rate_hz"]))
    if not two_temperatures:
        return [data.slice(slice(0, n))]
    hot = int(np.argmax(data.temp >= data.temp.max() - HOT_BAND_C))
    return [data.slice(slice(0, n // 2)), data.slice(slice(hot, hot + n - n // 2))]


def unit_rows(spec, k: int, prior: Path, seconds: float, work: Path,
              two_temperatures: bool) -> tuple[dict[str, dict[str, float]], float | None]:
    """({calibration: {metric: value}} of new unit k: full, the short windows, same with the prior;
    its slope-limited rate error [°/s], None for windows at two temperatures)."""
    folder = simulate_unit(spec, k, 0, work)
    full = folder / "calibration" / "calibration.csv.gz"
    windows = short_windows(read_imu_csv(full), seconds, two_temperatures)
    short = [write_imu_csv(w, work / f"short_{k}_{i}.csv.gz") for i, w in enumerate(windows)]
    tests = sorted((folder / "test").glob("*.csv.gz"))
    rows = {}
    for label, paths, prior_path in (("full recording", [full], None), (f"first {seconds:g} s", short, None),
                                     (f"first {seconds:g} s + fleet prior", short, prior)):
        done = train_to_folder(paths, work / f"{k}_{len(rows)}", progress=False, prior_path=prior_path)
        rows[label] = held_out_errors(done.model, tests)
    if two_temperatures:
        return rows, None
    return rows, slope_limited(spec, folder, windows[0].temp, tests, rows["full recording"]["rate_err_dps"])


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
    p.add_argument("--two-temperatures", action="store_true",
                   help="split the seconds between the recording's start and its highest temperature")
    a = p.parse_args(argv)
    spec = load_fleet(a.fleet)
    columns = [f"{LABELS[m]}, {c}" for m in HELD_OUT_METRICS for c in ("full", f"{a.seconds:g} s", f"{a.seconds:g} s + prior")]
    columns.insert(3, "rate, slope-limited")
    print("| unit | " + " | ".join(columns) + " |")
    print("|---|" + "---|" * len(columns))
    ratios, limits = [], []
    with tempfile.TemporaryDirectory(prefix="imufusion-fleet-prior-") as tmp:
        prior = a.prior or fleet_prior(a.fleet, a.fleet_units, Path(tmp))
        for k in range(FIRST_NEW_UNIT, FIRST_NEW_UNIT + a.units):
            rows, limit = unit_rows(spec, k, prior, a.seconds, Path(tmp), a.two_temperatures)
            cells = [f"{errors[m]:.4f}" for m in HELD_OUT_METRICS for errors in rows.values()]
            cells.insert(3, "—" if limit is None else f"{limit:.4f}")
            print(f"| {k} | " + " | ".join(cells) + " |", flush=True)
            full, short, with_prior = rows.values()
            if limit is not None:
                limits.append((limit / full["rate_err_dps"], with_prior["rate_err_dps"] / limit))
            ratios.append([[with_prior[m] / full[m], with_prior[m] / short[m]] for m in HELD_OUT_METRICS])
    ratios = np.array(ratios)   # unit, metric, (÷ full, ÷ short)
    print(f"\n| error | with prior ÷ full calibration (bound ≤ {RATIO_FULL:g}) | with prior ÷ same {a.seconds:g} s alone "
          f"(bound ≤ {RATIO_SHORT:g}) |")
    print("|---|---|---|")
    for j, m in enumerate(HELD_OUT_METRICS):
        cells = [f"{ratios[:, j, i].min():.2f}–{ratios[:, j, i].max():.2f} "
                 f"({'met' if ratios[:, j, i].max() <= bound else 'not met'}: {int(np.sum(ratios[:, j, i] <= bound))} of "
                 f"{len(ratios)} units within)" for i, bound in enumerate((RATIO_FULL, RATIO_SHORT))]
        print(f"| {m} | " + " | ".join(cells) + " |")
    if not limits:
        return 0
    limit_ratio, measured = np.array(limits).T
    print(f"\nslope-limited rate / full calibration: {limit_ratio.min():.2f}–{limit_ratio.max():.2f}, mean "
          f"{limit_ratio.mean():.2f} (what the unit's own temperature slope, unseen in these {a.seconds:g} s, costs any "
          f"calibration); the prior's rate error / slope-limited: {measured.min():.2f}–{measured.max():.2f}, median "
          f"{np.median(measured):.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
