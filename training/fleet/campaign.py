"""`imufmu campaign FMU.fmu DATA --runs N --vary NAME=DIST … --out DIR`: Monte-Carlo co-simulation.

Run r co-simulates the recording DATA through the FMU with its own draw of every variation, from
numpy's SeedSequence(seed, spawn_key=(r,)), so run r is the same whatever N, the partitioning or
the worker that runs it. A variation is

    NAME=normal(MEAN,SIGMA) | uniform(LOW,HIGH) | choice(A,B,…) | unit=FLEET_DIR

where NAME is an FMU parameter (set before initialisation) or an input perturbation
`noise_gyr` [rad/s], `noise_acc` [m/s²], `noise_mag` [µT]: the σ of white noise added to that raw
input triad in this run (its samples drawn after the variations, from the same stream).
`unit=FLEET_DIR` varies the unit (issue 32): each run draws one of the units `imufmu fleet train` wrote to
FLEET_DIR (every sub-folder with a calibration.ssv, in name order) and sets its coefficients and settings in
the FMU before initialisation; the run's `unit` column is the drawn unit's index in that order.

The runs are split into partitions, one Dask task each; a task instantiates the FMU once and
resets it between its runs (fmu.cosim.fmu_runner). Each run's errors against the recording's truth
are training.evaluate's (rate, field, roll, pitch, yaw, tilt, heading).

`--sensor ImuSensor.fmu` closes the loop (issue 34, training.sensor.closed_loop): each run drives the virtual
sensor with the recording's truth and the ImuFusion FMU with the sensor's outputs (fmpy, the exchange Ecos makes;
the outputs aligned by its one-step delay). The sensor's noise `seed` is the run's own draw from its stream
(after the variations) unless `--vary seed=choice(...)` names it; any other sensor parameter (noise,
gyr_noise_density_x, …) may be varied too. A name both FMUs have (field_norm, field_dip, declination) varies the
ImuFusion FMU's. Input noise (noise_*) and the unit are not varied in a closed loop: the sensor makes the noise,
and it models the one unit whose model it was built from.
"""
from __future__ import annotations

import functools
import math
import os
import re
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from contract.errors import ImuFusionError, one_line
from contract.layout import INPUTS
from contract.mounting import MOUNT_SETTINGS, settings_codes
from contract.ranges import BOOLEAN, FIELD_NORM_MAX_UT, INTEGER, REAL, SettingRange
from contract.variables import by_name
from training.data.input_limits import ACC_LIMIT_M_S2, GYR_LIMIT_RAD_S, MAG_SATURATION
from training.data.dataset import ImuData
from training.data.io import read_imu_csv
from training.evaluate import compute_metrics
from training.main_job import recording_parameters
from training.mounting import body_references

#: The sensor parameter a closed-loop run draws itself when no variation names it (--sensor).
SENSOR_SEED = "seed"

#: Input perturbations a variation may name, with the INPUTS columns they add noise to.
NOISE_INPUTS = {f"noise_{triad}": [INPUTS.index(f"{triad}_{axis}") for axis in "xyz"] for triad in ("gyr", "acc", "mag")}
#: Largest noise σ of each perturbation [the input's unit]: the runtime's plausibility limit of that input
#: (training.data.input_limits; the field's: saturation at the largest field norm a setting allows) —
#: beyond it every perturbed sample is bad input, and nothing is measured.
NOISE_MAX = {"noise_gyr": GYR_LIMIT_RAD_S, "noise_acc": ACC_LIMIT_M_S2,
             "noise_mag": MAG_SATURATION * FIELD_NORM_MAX_UT}
#: The variation of the unit itself (--vary unit=FLEET_DIR).
UNIT = "unit"
#: Distributions of a variation and their argument counts (None: any number ≥ 1).
DISTRIBUTIONS = {"normal": 2, "uniform": 2, "choice": None}
#: Metrics of each run (training.evaluate.Metrics.as_dict names, units in the name).
CAMPAIGN_METRICS = ("rate_err_dps", "field_err_ut", "roll_err_deg", "pitch_err_deg", "yaw_err_deg",
                    "tilt_err_deg", "heading_err_deg")
#: Partitions per worker: enough to balance uneven runs, few enough that the FMU is instantiated rarely.
PARTITIONS_PER_WORKER = 4
#: Memory [bytes] one value of a result row takes in the table held for the report: measured 53
#: (tracemalloc, 100 000 rows of 10 floats in a dict: 528 bytes a row), rounded up.
ROW_VALUE_BYTES = 64
_SPEC = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*=\s*([a-z]+)\s*\((.*)\)\s*$")


class CampaignError(ImuFusionError):
    """A variation or campaign argument is malformed."""


@dataclass(frozen=True)
class Variation:
    """One --vary NAME=DIST, or the unit (UNIT: `units` are the units' calibration files, drawn by index)."""

    name: str
    distribution: str
    args: tuple[float, ...]
    units: tuple[str, ...] = ()

    def draw(self, rng: np.random.Generator) -> float:
        """One value of this variation."""
        if self.distribution == "normal":
            return float(rng.normal(self.args[0], self.args[1]))
        if self.distribution == "uniform":
            return float(rng.uniform(self.args[0], self.args[1]))
        return float(self.args[int(rng.integers(len(self.args)))])

    def text(self) -> str:
        """The variation as the user wrote it (normalised)."""
        if self.name == UNIT:
            return f"unit={Path(self.units[0]).parent.parent} ({len(self.units)} units, drawn uniformly)"
        return f"{self.name}={self.distribution}({', '.join(f'{a:g}' for a in self.args)})"


def _unit_variation(folder: str, text: str) -> Variation:
    """The unit variation over the units of a `fleet train` folder: its sub-folders with a calibration.ssv."""
    from fmu.calibration_file import FILE_NAME
    root = Path(folder)
    if not root.is_dir():
        raise CampaignError(f"--vary {text!r}: '{folder}' is not a folder (the output of imufmu fleet train)")
    units = tuple(str(p / FILE_NAME) for p in sorted(root.iterdir()) if (p / FILE_NAME).is_file())
    if not units:
        raise CampaignError(f"--vary {text!r}: no unit of '{folder}' has a {FILE_NAME} (imufmu fleet train writes one "
                            "per unit)")
    return Variation(UNIT, "choice", tuple(float(k) for k in range(len(units))), units)


def parse_variation(text: str, sensor: bool = False) -> Variation:
    """A Variation from NAME=DIST or unit=FLEET_DIR; CampaignError naming the problem. `sensor`: the campaign
    closes the loop through a virtual-sensor FMU, whose parameters may be varied too."""
    name, sep, folder = text.partition("=")
    if sep and name.strip() == UNIT:
        return _unit_variation(folder.strip(), text)
    match = _SPEC.match(text)
    if not match:
        raise CampaignError(f"--vary {text!r}: expected NAME=normal(MEAN,SIGMA), NAME=uniform(LOW,HIGH) or "
                            "NAME=choice(A,B,...)")
    name, distribution, body = match.groups()
    if distribution not in DISTRIBUTIONS:
        raise CampaignError(f"--vary {text!r}: unknown distribution '{distribution}' (one of {', '.join(DISTRIBUTIONS)})")
    try:
        args = tuple(float(a) for a in body.split(","))
    except ValueError:
        raise CampaignError(f"--vary {text!r}: the arguments must be numbers") from None
    wanted = DISTRIBUTIONS[distribution]
    if (wanted is not None and len(args) != wanted) or not args or not all(math.isfinite(a) for a in args):
        raise CampaignError(f"--vary {text!r}: {distribution} takes {wanted or 'one or more'} finite numbers")
    if distribution == "normal" and args[1] < 0 or distribution == "uniform" and args[1] < args[0]:
        raise CampaignError(f"--vary {text!r}: need SIGMA ≥ 0 / LOW ≤ HIGH")
    if distribution == "uniform" and not math.isfinite(args[1] - args[0]):
        raise CampaignError(f"--vary {text!r}: HIGH − LOW must be a finite number (it overflows)")
    _check_name(name, text, sensor)
    _check_support(name, distribution, args, text)
    return Variation(name, distribution, args)


def _support(name: str) -> SettingRange | None:
    """The values a variation of `name` may draw: a parameter's declared range, a noise σ's [0, NOISE_MAX]."""
    if name in NOISE_INPUTS:
        return SettingRange(REAL, 0.0, NOISE_MAX[name])
    sensor = _sensor_parameter(name)
    return sensor.range if sensor is not None and not _fusion_parameter(name) else by_name(name).range


def _check_support(name: str, distribution: str, args: tuple[float, ...], text: str) -> None:
    """CampaignError when a variation's draws can leave what `name` takes (`_support`): every value of a
    uniform or a choice must lie in it, a normal's mean too (its tails may still leave it: such a run
    fails alone, with its reason, run_partition); an Integer or Boolean parameter takes a choice of
    whole numbers only (a normal or uniform draws fractions)."""
    r = _support(name)
    if r is None:
        return
    if r.type in (INTEGER, BOOLEAN) and (distribution != "choice" or any(a != int(a) for a in args)):
        article = "an" if r.type == INTEGER else "a"
        raise CampaignError(f"--vary {text!r}: {name} is {article} {r.type} parameter: vary it as choice(A,B,...) of "
                            "whole numbers")
    support = {"uniform": args, "choice": args, "normal": args[:1]}[distribution]
    inside = all((v > r.min if r.min_open else v >= r.min) and (v < r.max if r.max_open else v <= r.max)
                 for v in support)
    if not inside:
        interval = f"{'(' if r.min_open else '['}{r.min:g}, {r.max:g}{')' if r.max_open else ']'}"
        what = "the input's plausibility limit" if name in NOISE_INPUTS else "its declared range"
        raise CampaignError(f"--vary {text!r}: {name} must stay in {interval} ({what}); "
                            f"{distribution}({', '.join(f'{a:g}' for a in args)}) draws outside it")


def _fusion_parameter(name: str) -> bool:
    """Whether `name` is a parameter of the ImuFusion FMU."""
    try:
        return by_name(name).causality == "parameter"
    except KeyError:
        return False


def _sensor_parameter(name: str):
    """The virtual-sensor FMU's parameter `name` (contract.sensor_variables), None when it has none."""
    from contract.sensor_variables import sensor_parameters
    return next((v for v in sensor_parameters() if v.name == name), None)


def _check_name(name: str, text: str, sensor: bool = False) -> None:
    """CampaignError unless name is an input perturbation or an FMU parameter (`sensor`: of either FMU)."""
    if name in NOISE_INPUTS or sensor and _sensor_parameter(name) is not None:
        return
    try:
        variable = by_name(name)
    except KeyError:
        also = "" if sensor else " (a virtual-sensor parameter needs --sensor)" if _sensor_parameter(name) else ""
        raise CampaignError(f"--vary {text!r}: '{name}' is neither an FMU parameter nor one of "
                            f"{', '.join(NOISE_INPUTS)}{also}") from None
    if variable.causality != "parameter":
        raise CampaignError(f"--vary {text!r}: '{name}' is an {variable.causality}, not a parameter")


def run_draws(variations: tuple[Variation, ...], seed: int, run: int, samples: int,
              sensor: bool = False) -> tuple[dict[str, float], dict[str, float], np.ndarray]:
    """(FMU parameters, input-noise σ by name, additive input noise (samples, len(INPUTS))) of one run. `sensor`
    (a closed loop): the sensor's noise seed is drawn after the variations when none of them names it."""
    from contract.ranges import INT32_MAX
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(run,)))
    values = {v.name: v.draw(rng) for v in variations}
    if sensor and SENSOR_SEED not in values:
        values[SENSOR_SEED] = float(rng.integers(0, INT32_MAX, endpoint=True))
    parameters = {k: v for k, v in values.items() if k not in NOISE_INPUTS}
    noise_sigma = {k: abs(v) for k, v in values.items() if k in NOISE_INPUTS}
    noise = np.zeros((samples, len(INPUTS)))
    for name, sigma in noise_sigma.items():
        noise[:, NOISE_INPUTS[name]] = sigma * rng.standard_normal((samples, 3))
    return parameters, noise_sigma, noise


@functools.lru_cache(maxsize=2)
def _recording(path: str) -> ImuData:
    """The recording (read once per worker process)."""
    return read_imu_csv(path)


@functools.lru_cache(maxsize=2)
def _declared_mounting(fmu_path: str) -> tuple[int, int, int]:
    """The FMU's declared mounting (read once per worker)."""
    from fmu.archive import declared_mounting
    return declared_mounting(fmu_path)


def _mounting(fmu_path: str, parameters: dict[str, float]) -> tuple[int, int, int]:
    """The run's mounting codes: the FMU's declared mounting unless varied."""
    return settings_codes({**dict(zip(MOUNT_SETTINGS, _declared_mounting(fmu_path))), **parameters})


@functools.lru_cache(maxsize=256)
def _unit(path: str) -> tuple[np.ndarray, dict[str, float]]:
    """A unit's coefficients and settings from its calibration.ssv (read once per worker process)."""
    from fmu.calibration_file import read_calibration
    coefficients, settings, _ = read_calibration(path)
    return coefficients, settings


def _unit_of(variations: tuple[Variation, ...], parameters: dict[str, float]) -> tuple[np.ndarray | None, dict]:
    """(the drawn unit's coefficients or None, its settings) of a run whose draws are `parameters` (the unit's
    index removed from them)."""
    unit = next((v for v in variations if v.name == UNIT), None)
    if unit is None:
        return None, {}
    coefficients, settings = _unit(unit.units[int(parameters.pop(UNIT))])
    return coefficients, settings


@functools.lru_cache(maxsize=2)
def _trajectory(data_path: str, fmu_path: str):
    """The closed loop's trajectory source of the recording (built once per worker process)."""
    from training.sensor.closed_loop import trajectory
    return trajectory(_recording(data_path), fmu_path)


def run_closed_loop_partition(runs: Iterable[int], fmu_path: str, data_path: str, variations: tuple[Variation, ...],
                              seed: int, sensor_path: str) -> list[dict]:
    """Each of `runs` as a closed loop (training.sensor.closed_loop.run_fmpy): the recording's truth through the
    sensor FMU at sensor_path with the run's seed and sensor draws, then the FMU with the recording's parameters
    and its draws; one dict per run as run_partition's, the sensor's seed among the drawn values."""
    from training.sensor.closed_loop import aligned, run_fmpy, sensor_parameters
    traj = _trajectory(data_path, fmu_path)
    out = []
    for r in runs:
        parameters, _, _ = run_draws(variations, seed, r, 0, sensor=True)
        metrics, failed = dict.fromkeys(CAMPAIGN_METRICS, float("nan")), ""
        try:
            fusion = {k: v for k, v in parameters.items() if _fusion_parameter(k)}
            sensor = sensor_parameters(int(parameters[SENSOR_SEED]), traj.sensor_parameters,
                                       {k: v for k, v in parameters.items() if k not in fusion})
            stepped = run_fmpy(sensor_path, fmu_path, traj, sensor, {**traj.fusion_parameters, **fusion})
            metrics = compute_metrics(aligned(stepped), traj.body).as_dict()
        except Exception as e:  # noqa: BLE001 - a run that fails is reported with its reason, the others go on
            failed = one_line(f"{type(e).__name__}: {e}")
        out.append({"run": r, **parameters, **{m: metrics[m] for m in CAMPAIGN_METRICS}, "failed": failed})
    return out


def run_partition(runs: Iterable[int], fmu_path: str, data_path: str, variations: tuple[Variation, ...],
                  seed: int, sensor_path: str | None = None) -> list[dict]:
    """Co-simulate `runs` with one FMU instance (reset between runs); one dict per run: run, the
    drawn values and CAMPAIGN_METRICS. A unit variation sets the drawn unit's coefficients and settings
    first; the recording's parameters and the other variations apply over its settings. `sensor_path`: each run
    is a closed loop through that virtual-sensor FMU (run_closed_loop_partition)."""
    if sensor_path is not None:
        return run_closed_loop_partition(runs, fmu_path, data_path, variations, seed, sensor_path)
    from fmu.cosim import fmu_runner
    from fmu.packer import fmu_aux_columns
    data = _recording(data_path)
    inputs = data.inputs(fmu_aux_columns(fmu_path))
    fixed = recording_parameters(data)
    out = []
    with fmu_runner(fmu_path) as simulate:
        for r in runs:
            parameters, noise_sigma, noise = run_draws(variations, seed, r, len(data))
            drawn = dict(parameters)
            metrics, failed = dict.fromkeys(CAMPAIGN_METRICS, float("nan")), ""
            try:
                coefficients, unit_settings = _unit_of(variations, parameters)
                run_parameters = {**unit_settings, **fixed, **parameters}
                outputs = simulate(data.t, inputs + noise, run_parameters, coefficients)
                body = body_references(data, _mounting(fmu_path, run_parameters))
                metrics = compute_metrics(outputs, body).as_dict()
            except Exception as e:  # noqa: BLE001 - a run that fails is reported with its reason, the others go on
                failed = one_line(f"{type(e).__name__}: {e}")
            out.append({"run": r, **drawn, **noise_sigma, **{m: metrics[m] for m in CAMPAIGN_METRICS},
                        "failed": failed})
    return out


def partitions(runs: int, workers: int) -> list[range]:
    """Runs 0..runs−1 in contiguous ranges, PARTITIONS_PER_WORKER per worker (ranges, not index
    lists: their size does not grow with the number of runs)."""
    count = max(1, min(runs, workers * PARTITIONS_PER_WORKER))
    bounds = [runs * k // count for k in range(count + 1)]
    return [range(a, b) for a, b in zip(bounds, bounds[1:]) if b > a]


def result_bytes(runs: int, variations: tuple[Variation, ...], sensor: bool = False) -> int:
    """Memory [bytes] the campaign's result table takes: ROW_VALUE_BYTES per value of a row (the run,
    each variation's value and, for noise, its sigma, CAMPAIGN_METRICS; `sensor`: a closed loop's drawn seed)."""
    return runs * ROW_VALUE_BYTES * (1 + int(sensor) + 2 * len(variations) + len(CAMPAIGN_METRICS))


def available_memory() -> int | None:
    """Physical memory [bytes] free now (Linux, macOS: sysconf), None where it cannot be read."""
    try:
        return int(os.sysconf("SC_PAGE_SIZE")) * int(os.sysconf("SC_AVPHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return None


def check_size(runs: int, variations: tuple[Variation, ...], free: int | None, sensor: bool = False) -> None:
    """CampaignError with the estimate when the result table would take more than half of `free`
    [bytes] (issue 31: --runs 1000000000 had built every run index first, 4.3 GB in 12 s)."""
    need = result_bytes(runs, variations, sensor)
    if free is not None and need > free // 2:
        raise CampaignError(f"--runs {runs}: the results would take about {need / 1e9:.3g} GB of memory "
                            f"({ROW_VALUE_BYTES} bytes per value, {need // runs} per run), more than half of the "
                            f"{free / 1e9:.3g} GB free; run the campaign in parts with fewer runs and other --seed values")


def check_closed_loop(sensor_path: str, data: ImuData, variations: tuple[Variation, ...]) -> None:
    """CampaignError (one line) unless the closed loop can run: an ImuSensor FMU, a recording with the truth it
    takes, no variation it cannot make (input noise, the unit)."""
    from training.sensor.closed_loop import check_sensor_fmu, missing_truth
    try:
        check_sensor_fmu(sensor_path)
    except ImuFusionError as e:
        raise CampaignError(f"--sensor: {e}") from None
    missing = missing_truth(data)
    if missing:
        raise CampaignError(f"{data.name}: --sensor drives the virtual sensor with the recording's truth, and it lacks "
                            f"{', '.join(missing)}")
    for v in variations:
        if v.name in NOISE_INPUTS or v.name == UNIT:
            what = ("the virtual sensor makes the noise: vary its figures (gyr_noise_density_x, ...) or its seed"
                    if v.name in NOISE_INPUTS else
                    "the virtual sensor models the one unit whose model it was built from")
            raise CampaignError(f"--vary {v.text()!r} with --sensor: {what}")


def campaign_runs(fmu_path: str | Path, data_path: str | Path, runs: int, variations: tuple[Variation, ...],
                  seed: int = 0, workers: int | None = None, scheduler: str | None = None,
                  progress: bool = True, sensor_path: str | Path | None = None) -> list[dict]:
    """Every run's result (run_partition), sorted by run, computed on Dask (training.fleet.engine). `sensor_path`:
    every run a closed loop through that virtual-sensor FMU."""
    from training.fleet.engine import dask_client, default_workers, run_tasks
    if runs < 1:
        raise CampaignError(f"--runs must be ≥ 1, got {runs}")
    check_size(runs, variations, available_memory(), sensor_path is not None)
    fmu_path, data_path = str(Path(fmu_path).resolve()), str(Path(data_path).resolve())
    data = _recording(data_path)  # a bad recording fails here, once, with its one-line error
    if all(getattr(data, f"ref_{kind}") is None for kind in ("q", "gyr", "acc", "mag")):
        raise CampaignError(f"{data_path}: no reference (ref_q or ref_gyr/ref_acc/ref_mag columns): the campaign "
                            "measures each run's errors against it")
    if sensor_path is not None:
        sensor_path = str(Path(sensor_path).resolve())
        check_closed_loop(sensor_path, data, variations)
    results = []
    with dask_client(workers, scheduler) as client:
        parts = partitions(runs, workers or len(client.scheduler_info().get("workers", {})) or default_workers())
        for _, rows in run_tasks(client, run_partition, parts, "partitions", progress, "partition", fmu_path=fmu_path,
                                 data_path=data_path, variations=variations, seed=seed, sensor_path=sensor_path):
            results.extend(rows)
    return sorted(results, key=lambda row: row["run"])
