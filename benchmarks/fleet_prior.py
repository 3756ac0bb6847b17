"""What the fleet prior buys (issue 19 item 3): new units, never in the fleet, calibrated from the first
60 s of their calibration recording with and without `--prior`, and from the whole recording, scored on
their held-out test recording through the C runtime (training.fleet.heldout).

Usage: OMP_NUM_THREADS=1 .venv/bin/python benchmarks/fleet_prior.py --prior FLEET_OUT/fleet.json
       [--fleet scenarios/fleet/mems_grade.toml] [--units 5] [--seconds 60] [--two-temperatures]
       [--use-minutes M]
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

With --use-minutes M each unit's full and prior calibrations also run, bias learning on (train's
settings) and off, on a use recording of M minutes: the fleet's test scenario stretched, 10 s rests
after 20 s moves, 15 -> 30 °C, the unit's own sensor; the rate error after 10 minutes and the prior's
ratio to the full calibration (issue 33: the online learning learns the unit's own slope at its rests).
"""
from __future__ import annotations

import argparse
from dataclasses import replace
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT), str(ROOT / "benchmarks")]

from bias_learning import SETTLE_S, stretched  # noqa: E402
from contract.layout import OUTPUTS, settings_array  # noqa: E402
from training.artefact import coefficients_array, load_artefact, settings_dict  # noqa: E402
from training.data.io import read_imu_csv, write_imu_csv  # noqa: E402
from training.fleet.heldout import HELD_OUT_METRICS, held_out_errors  # noqa: E402
from training.fleet.simulate import simulate_unit  # noqa: E402
from training.fleet.spec import load_fleet  # noqa: E402
from training.runtime import run_batch  # noqa: E402
from training.simulator import simulate  # noqa: E402
from training.simulator.scenario import sensor_from_raw  # noqa: E402
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
#: --use-minutes: the rest after every 20 s move of the use recording [s] (benchmarks/bias_learning.py).
USE_REST_S = 10.0
#: Seed of each unit's use recording (its calibration and test recordings take the fleet's seeds).
USE_SEED = 7
RATE = slice(OUTPUTS.index("rate_x"), OUTPUTS.index("rate_x") + 3)


def use_rate_errors(spec, folder: Path, models: dict[str, Path], minutes: float) -> dict[str, float]:
    """{label: rate error [°/s] after SETTLE_S} of each model, bias learning on (train's settings) and off
    (label + ', no learning'), on a use recording of the unit: the fleet's test scenario stretched to
    `minutes` with USE_REST_S rests (temperature 15 -> 30 °C over the whole), simulated with the unit's
    own drawn sensor."""
    raw = json.loads((folder / "unit.json").read_text())["sensor"]
    scenario = replace(stretched(spec.test[0], minutes, USE_REST_S), sensor=sensor_from_raw(raw, spec.sensor_path))
    data = simulate(scenario, USE_SEED)
    late = data.t >= SETTLE_S
    errors = {}
    for label, model in models.items():
        artefact = load_artefact(model)
        for suffix, learning in (("", 1.0), (", no learning", 0.0)):
            values = {**settings_dict(artefact), "bias_learning": learning}
            out = run_batch(coefficients_array(artefact), np.asarray(settings_array(values)), data.t, data.inputs())
            errors[label + suffix] = float(np.degrees(np.sqrt(np.mean((out[late, RATE] - data.ref_gyr[late]) ** 2))))
    return errors


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


def unit_rows(spec, k: int, prior: Path, seconds: float, work: Path, two_temperatures: bool,
              use_minutes: float | None = None) -> tuple[dict[str, dict[str, float]], float | None, dict[str, float]]:
    """({calibration: {metric: value}} of new unit k: full, the short windows, same with the prior;
    its slope-limited rate error [°/s], None for windows at two temperatures; with use_minutes the
    use_rate_errors of the full and the prior calibration, else {})."""
    folder = simulate_unit(spec, k, 0, work)
    full = folder / "calibration" / "calibration.csv.gz"
    windows = short_windows(read_imu_csv(full), seconds, two_temperatures)
    short = [write_imu_csv(w, work / f"short_{k}_{i}.csv.gz") for i, w in enumerate(windows)]
    tests = sorted((folder / "test").glob("*.csv.gz"))
    rows, models = {}, {}
    for label, paths, prior_path in (("full recording", [full], None), (f"first {seconds:g} s", short, None),
                                     (f"first {seconds:g} s + fleet prior", short, prior)):
        done = train_to_folder(paths, work / f"{k}_{len(rows)}", progress=False, prior_path=prior_path)
        rows[label], models[label] = held_out_errors(done.model, tests), done.model
    use = {} if use_minutes is None else use_rate_errors(
        spec, folder, {"full": models["full recording"], "prior": models[f"first {seconds:g} s + fleet prior"]}, use_minutes)
    if two_temperatures:
        return rows, None, use
    return rows, slope_limited(spec, folder, windows[0].temp, tests, rows["full recording"]["rate_err_dps"]), use


def print_use_table(uses: list[tuple[int, dict[str, float]]], seconds: float, minutes: float) -> None:
    """The rate errors of the use recordings and the prior's ratio to the full calibration."""
    print(f"\n| unit | use rate after 10 min [°/s], full | {seconds:g} s + prior | prior ÷ full (bound ≤ {RATIO_FULL:g}) "
          f"| full, no learning | {seconds:g} s + prior, no learning | prior ÷ full, no learning |")
    print("|---|---|---|---|---|---|---|")
    ratios = []
    for k, e in uses:
        ratios.append((e["prior"] / e["full"], e["prior, no learning"] / e["full, no learning"]))
        print(f"| {k} | {e['full']:.4f} | {e['prior']:.4f} | {ratios[-1][0]:.2f} | {e['full, no learning']:.4f} | "
              f"{e['prior, no learning']:.4f} | {ratios[-1][1]:.2f} |")
    on, off = np.array(ratios).T
    print(f"\nuse recordings of {minutes:g} min ({USE_REST_S:g} s rests after 20 s moves, 15 -> 30 °C): the prior unit "
          f"÷ its full calibration {on.min():.2f}–{on.max():.2f} with bias learning ({int(np.sum(on <= RATIO_FULL))} of "
          f"{len(on)} within {RATIO_FULL:g}), {off.min():.2f}–{off.max():.2f} without")


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
    p.add_argument("--use-minutes", type=float, default=None,
                   help="also run each unit's full and prior calibrations on a use recording this long (the test "
                        "scenario stretched, 10 s rests) and print the rate error after 10 min, bias learning on and off")
    a = p.parse_args(argv)
    spec = load_fleet(a.fleet)
    columns = [f"{LABELS[m]}, {c}" for m in HELD_OUT_METRICS for c in ("full", f"{a.seconds:g} s", f"{a.seconds:g} s + prior")]
    columns.insert(3, "rate, slope-limited")
    print("| unit | " + " | ".join(columns) + " |")
    print("|---|" + "---|" * len(columns))
    ratios, limits, uses = [], [], []
    with tempfile.TemporaryDirectory(prefix="imufusion-fleet-prior-") as tmp:
        prior = a.prior or fleet_prior(a.fleet, a.fleet_units, Path(tmp))
        for k in range(FIRST_NEW_UNIT, FIRST_NEW_UNIT + a.units):
            rows, limit, use = unit_rows(spec, k, prior, a.seconds, Path(tmp), a.two_temperatures, a.use_minutes)
            uses.append((k, use))
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
    if a.use_minutes is not None:
        print_use_table(uses, a.seconds, a.use_minutes)
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
