"""The closed loop of issue 34 item 3 (docs/virtual_sensor.md, "Closed loop"): a recording's truth drives the
virtual-sensor FMU (ImuSensor), whose raw outputs drive the ImuFusion FMU, in one co-simulation.

    truth (ref_gyr, ref_acc, ref_q or ref_mag, temp, aux_*)  ->  sensor  --gyr_x..temp-->  imu  ->  outputs

Two masters run it, with the same exchange: every FMU steps from t to t + h on the inputs it holds, then the
sensor's outputs are copied to the ImuFusion FMU's inputs of the same name (a Jacobi master, which is what
Ecos's fixed-step algorithm does: step every instance, then transfer every connection):

- `run_ecospy`: Ecos (ecospy, fmi4c), the two FMUs in one EcosSimulationStructure with 10 real connections,
  the truth set on the sensor by a SimulationListener each step (training/sensor/ecos_loop.py, run in a
  subprocess: ecospy loads libtbb from the environment's lib folder, which must be on LD_LIBRARY_PATH when
  the process starts);
- `run_fmpy`: the same exchange with two fmpy instances (fmu.cosim) stepped in lockstep.

On the same time grid the two give the same outputs bit for bit (tests/test_closed_loop.py): the same
binaries see the same calls with the same values. Ecos steps a fixed h and computes its communication points as
t + h again and again; `ecos_grid` reproduces that grid, `run_fmpy` takes it or the recording's own times.

Timing: the sensor's doStep(t, h) outputs the raw sample of the truth set before it (time t); the ImuFusion
FMU receives it only after that step and consumes it in its step t + h. The outputs after the step of sample
k are therefore the estimate of sample k − 1: ALIGNMENT_STEPS, measured by `alignment_scan`.
"""
from __future__ import annotations

import math
import os
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from contract.errors import ImuFusionError, one_line
from contract.layout import AUX_INPUTS, INPUTS, OUTPUTS
from contract.sensor_variables import MODEL_NAME as SENSOR_MODEL_NAME, SENSOR_VARIABLES
from fmu.model_description import MODEL_NAME as FUSION_MODEL_NAME
from training.data.dataset import ImuData, recording_parameters

#: Instance names of the two FMUs in the co-simulation (Ecos identifiers "sensor::gyr_x", "imu::gyr_x").
SENSOR_INSTANCE, FUSION_INSTANCE = "sensor", "imu"
#: The sensor outputs, connected name for name to the ImuFusion FMU's raw inputs.
RAW = ("gyr_x", "gyr_y", "gyr_z", "acc_x", "acc_y", "acc_z", "mag_x", "mag_y", "mag_z", "temp")
#: The sensor inputs the trajectory sets each step (true_field_* only when the recording has ref_mag).
TRUE_MOTION = ("true_rate_x", "true_rate_y", "true_rate_z", "true_accel_x", "true_accel_y", "true_accel_z",
               "true_q_w", "true_q_x", "true_q_y", "true_q_z")
TRUE_FIELD = ("true_field_x", "true_field_y", "true_field_z")
#: Steps between a sample and the ImuFusion output that estimates it in the closed loop: one, the exchange
#: after each step (module docstring). Measured by `alignment_scan` on eval_rotations, noise off: the corrected
#: rate error is 8e-15 °/s at this shift and 0.843 °/s one step either side (docs/virtual_sensor.md).
ALIGNMENT_STEPS = 1
#: What the ImuFusion FMU's raw inputs hold in its first step, before the sensor has stepped: NaN, no sample yet
#: (every sensor absent: its outputs are NaN and its state untouched). Ecos's connections would carry the sensor's
#: outputs after initialisation, zeros, which the ImuFusion FMU takes for a sample: that zero accelerometer
#: sample turned the first attitude by 35° and left an attitude error of up to 0.008° over the first 10 s on
#: eval_rotations (noise off). Both masters therefore set NaN on the connected inputs for the first step.
FIRST_RAW = float("nan")
#: A fixed-step master needs evenly spaced samples: the largest relative deviation of a step from the
#: recording's median step that still counts as the same step (a 100 Hz clock written as decimal seconds
#: deviates by ~1e-12; a dropped sample by 1).
STEP_TOLERANCE = 1e-6
#: The importers `closed_loop` runs.
IMPORTERS = ("ecospy", "fmpy")
#: Seconds the ecospy subprocess may run per sample (plus a minute to start): 40 µs/sample measured, 100× margin.
ECOSPY_TIMEOUT_PER_SAMPLE_S = 4e-3


class ClosedLoopError(ImuFusionError):
    """An FMU, recording or option the closed loop cannot run."""


def _model_identifier(path: str | Path) -> str:
    from fmu.archive import read_description
    return read_description(path).coSimulation.modelIdentifier


def _check_fmu(path: str | Path, identifier: str, what: str, how: str) -> Path:
    """`path` when it is an FMU of model `identifier`; ClosedLoopError naming what it is otherwise."""
    path = Path(path)
    if not path.is_file():
        raise ClosedLoopError(f"{what} '{path}' not found")
    found = _model_identifier(path)
    if found != identifier:
        raise ClosedLoopError(f"{path}: not an {identifier} FMU (its model is '{found}'; {how} builds one)")
    return path


def check_sensor_fmu(path: str | Path) -> Path:
    """`path` when it is an ImuSensor FMU (imufmu build-sensor-fmu); ClosedLoopError naming what it is otherwise."""
    return _check_fmu(path, SENSOR_MODEL_NAME, "sensor FMU", "imufmu build-sensor-fmu")


def check_fusion_fmu(path: str | Path) -> Path:
    """`path` when it is an ImuFusion FMU; ClosedLoopError naming what it is otherwise."""
    return _check_fmu(path, FUSION_MODEL_NAME, "ImuFusion FMU", "imufmu build-fmu")


#: The truth columns the closed loop needs: ref_gyr, ref_acc (the sensor's true motion) and ref_q (its attitude:
#: the field when there is no ref_mag, and the attitude errors).
TRUTH = (("ref_gyr", "ref_gyr_x..z"), ("ref_acc", "ref_acc_x..z"), ("ref_q", "ref_qw..ref_qz"))


def missing_truth(data: ImuData) -> list[str]:
    """The TRUTH columns `data` lacks."""
    return [columns for name, columns in TRUTH if getattr(data, name) is None]


def check_truth(data: ImuData) -> None:
    """ClosedLoopError naming the recording and its missing truth columns (`missing_truth`)."""
    missing = missing_truth(data)
    if missing:
        raise ClosedLoopError(f"{data.name}: no truth to drive the virtual sensor with: the recording lacks "
                              f"{', '.join(missing)} (a simulated recording or one with a motion reference has them)")


@dataclass
class Trajectory:
    """The trajectory source: what is set on the sensor (and the ImuFusion FMU's aux inputs) each step.

    t: (N,) sample times [s]; sensor: sensor input name -> (N,) values (rad/s, m/s², quaternion, µT, °C, aux);
    aux: (N, len(AUX_INPUTS)) the ImuFusion FMU's auxiliary inputs per sample; sensor_parameters: the field the
    sensor turns into body axes (from the sidecar) and whether it takes it from the attitude;
    fusion_parameters: what the sidecar fixes in the ImuFusion FMU (recording_parameters); body: the recording
    with its truth in the FMUs' body axes, for the errors."""

    t: np.ndarray
    sensor: dict[str, np.ndarray]
    aux: np.ndarray
    sensor_parameters: dict[str, float]
    fusion_parameters: dict[str, float]
    body: ImuData
    name: str = "recording"
    rate_hz: float | None = None

    def sensor_inputs(self) -> tuple[tuple[str, ...], np.ndarray]:
        """(names, (N, len(names)) values) of the sensor inputs set each step."""
        names = tuple(self.sensor)
        return names, np.column_stack([self.sensor[n] for n in names])

    def fusion_aux(self) -> np.ndarray:
        """(N, len(AUX_INPUTS)): the aux inputs the ImuFusion FMU holds in the step of sample k, those of sample
        k − ALIGNMENT_STEPS (the raw sample it consumes then), the first sample's before that."""
        shifted = np.roll(self.aux, ALIGNMENT_STEPS, axis=0)
        shifted[:ALIGNMENT_STEPS] = self.aux[0]
        return shifted


def trajectory(data: ImuData, fusion_fmu: str | Path) -> Trajectory:
    """The trajectory source of `data` for the ImuFusion FMU at `fusion_fmu`: the truth turned into the body axes
    of the FMU's declared mounting (the sensor FMU inverts the same mounting), the field from ref_mag when the
    recording has it (field_from_attitude off) or else from ref_q and the sidecar's earth field, the aux columns
    the FMU maps. ClosedLoopError when the truth is missing."""
    from contract.mounting import MOUNT_SETTINGS, settings_codes
    from fmu.archive import declared_mounting
    from fmu.packer import fmu_aux_columns
    from training.mounting import body_references
    check_truth(data)
    codes = settings_codes(dict(zip(MOUNT_SETTINGS, declared_mounting(fusion_fmu))))
    body = body_references(data, codes)
    q = body.ref_q / np.linalg.norm(body.ref_q, axis=1, keepdims=True)
    sensor = {name: np.asarray(col, dtype=float) for name, col in zip(TRUE_MOTION, np.column_stack(
        [body.ref_gyr, body.ref_acc, q]).T)}
    parameters: dict[str, float] = {"field_from_attitude": 0.0 if body.ref_mag is not None else 1.0}
    if body.ref_mag is not None:
        sensor.update({name: np.asarray(col, dtype=float) for name, col in zip(TRUE_FIELD, body.ref_mag.T)})
    else:
        earth = data.meta.get("earth_field") or {}
        for key, name, scale in (("norm_ut", "field_norm", 1.0), ("dip_deg", "field_dip", math.pi / 180.0)):
            if isinstance(earth.get(key), (int, float)):
                parameters[name] = float(earth[key]) * scale
        parameters["declination"] = data.declination_rad
    sensor["true_temp"] = np.asarray(data.temp, dtype=float)
    aux = data.inputs(fmu_aux_columns(fusion_fmu))[:, len(INPUTS) - len(AUX_INPUTS):]
    for k, name in enumerate(AUX_INPUTS):
        sensor[name] = aux[:, k]
    rate = data.meta.get("rate_hz")
    return Trajectory(np.asarray(data.t, dtype=float), sensor, aux, parameters, recording_parameters(data), body,
                      data.name, float(rate) if isinstance(rate, (int, float)) and rate > 0 else None)


def fixed_step(t: np.ndarray, rate_hz: float | None = None) -> float:
    """The step [s] of evenly spaced sample times t: 1 / rate_hz (the sidecar's rate) when every step is that within
    STEP_TOLERANCE, else the median step; ClosedLoopError when a step deviates from it by more (a gap, a jittered
    clock): a fixed-step master cannot follow them."""
    if t.size < 2:
        raise ClosedLoopError("the recording has fewer than 2 samples: nothing to step")
    steps = np.diff(t)
    for h in ([1.0 / rate_hz] if rate_hz else []) + [float(np.median(steps))]:
        if float(np.max(np.abs(steps - h)) / h) <= STEP_TOLERANCE:
            return h
    raise ClosedLoopError(f"ecospy steps a fixed size and the recording's steps vary ({steps.min():.6g} to "
                          f"{steps.max():.6g} s): run it with --importer fmpy")


def ecos_grid(n: int, h: float) -> np.ndarray:
    """(n,) the communication points Ecos's fixed-step master passes to doStep: 0, then t + h after each step
    (accumulated in double precision, as simulation::step does)."""
    t = np.empty(n)
    now = 0.0
    for k in range(n):
        t[k] = now
        now = now + h
    return t


def sensor_parameters(seed: int, trajectory_parameters: dict[str, float],
                      extra: dict[str, float] | None = None) -> dict[str, float]:
    """The sensor's parameters of a run: its noise seed, the trajectory's field, then `extra` (name -> value)."""
    return {"seed": float(seed), **trajectory_parameters, **(extra or {})}


def run_fmpy(sensor_fmu: str | Path, fusion_fmu: str | Path, traj: Trajectory, sensor_params: dict[str, float],
             fusion_params: dict[str, float], t: np.ndarray | None = None, h: np.ndarray | float | None = None,
             fusion_coefficients=None) -> np.ndarray:
    """The closed loop with two fmpy instances (fmu.cosim), exchanged as Ecos does (module docstring).

    t: (N,) communication points [s] (default: the recording's times from 0); h: the step sizes [s] (default:
    time to the next sample, the last repeated). Returns (N, len(OUTPUTS)): row k the ImuFusion outputs after
    the step of sample k (the estimate of sample k − ALIGNMENT_STEPS: `aligned`)."""
    from fmu.cosim import Stepper, initialised_fmu, step_sizes
    names, values = traj.sensor_inputs()
    t = traj.t - traj.t[0] if t is None else np.asarray(t, dtype=float)
    h = step_sizes(t, 1.0) if h is None else np.broadcast_to(np.asarray(h, dtype=float), t.shape)
    aux = traj.fusion_aux()
    raw_inputs = list(RAW)
    out = np.empty((t.size, len(OUTPUTS)))
    with initialised_fmu(sensor_fmu, float(t[0]), sensor_params, instance_name=SENSOR_INSTANCE) as sensor, \
            initialised_fmu(fusion_fmu, float(t[0]), fusion_params, instance_name=FUSION_INSTANCE,
                            coefficients=fusion_coefficients) as fusion:
        s = Stepper(sensor, names, RAW)
        f = Stepper(fusion, raw_inputs + list(AUX_INPUTS), OUTPUTS)
        raw = np.full(len(RAW), np.nan)  # nothing sampled before the sensor's first step (FIRST_RAW)
        for k in range(t.size):
            s.set_inputs(values[k])
            f.set_inputs(np.concatenate([raw, aux[k]]))
            s.do_step(t[k], h[k])
            f.do_step(t[k], h[k])
            raw = s.get_outputs()
            out[k] = f.get_outputs()
    return out


def run_ecospy(sensor_fmu: str | Path, fusion_fmu: str | Path, traj: Trajectory, sensor_params: dict[str, float],
               fusion_params: dict[str, float], step: float | None = None) -> np.ndarray:
    """The closed loop co-simulated by Ecos (training/sensor/ecos_loop.py in a subprocess with the environment's
    lib folder on LD_LIBRARY_PATH) at the fixed step `step` [s] (default: `fixed_step` of the recording).
    Returns (N, len(OUTPUTS)) as `run_fmpy`; ClosedLoopError with ecospy's last lines when it fails."""
    step = fixed_step(traj.t, traj.rate_hz) if step is None else float(step)
    names, values = traj.sensor_inputs()
    with tempfile.TemporaryDirectory(prefix="imufusion-ecos-") as tmp:
        job, result = Path(tmp) / "loop.npz", Path(tmp) / "out.npy"
        np.savez(job, sensor_fmu=str(Path(sensor_fmu).resolve()), fusion_fmu=str(Path(fusion_fmu).resolve()),
                 step=step, names=np.array(names), values=values, aux=traj.fusion_aux(),
                 sensor_params=_typed(sensor_params, SENSOR_VARIABLES), fusion_params=_typed(fusion_params, None))
        env = dict(os.environ)
        env["LD_LIBRARY_PATH"] = os.pathsep.join(filter(None, [str(Path(sys.prefix) / "lib"),
                                                               env.get("LD_LIBRARY_PATH")]))
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(Path(__file__).resolve().parents[2]),
                                                          env.get("PYTHONPATH")]))
        try:
            done = subprocess.run([sys.executable, "-m", "training.sensor.ecos_loop", str(job), str(result)], env=env,
                                  stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                  timeout=60 + ECOSPY_TIMEOUT_PER_SAMPLE_S * len(traj.t))
        except subprocess.TimeoutExpired:
            raise ClosedLoopError(f"ecospy did not finish {len(traj.t)} steps in time") from None
        if done.returncode != 0 or not result.is_file():
            tail = " | ".join(line for line in done.stdout.strip().splitlines()[-3:])
            raise ClosedLoopError(f"ecospy failed (exit status {done.returncode}): {one_line(tail) or 'no output'}")
        return np.load(result)


def _typed(parameters: dict[str, float], table) -> np.ndarray:
    """Parameters as rows (name, type, value) for the ecospy program: the type ('Real', 'Integer', 'Boolean')
    from the sensor's table, or the ImuFusion FMU's (table None)."""
    from contract.variables import by_name
    lookup = {v.name: v for v in table} if table is not None else None
    rows = []
    for name, value in parameters.items():
        try:
            kind = (lookup[name] if lookup is not None else by_name(name)).type
        except KeyError:
            raise ClosedLoopError(f"'{name}' is not a parameter of the "
                                  f"{'sensor' if table is not None else 'ImuFusion'} FMU") from None
        rows.append((name, kind, repr(float(value))))
    return np.array(rows, dtype=str).reshape(len(rows), 3)


def aligned(out: np.ndarray, steps: int = ALIGNMENT_STEPS) -> np.ndarray:
    """(N, K) outputs row k = the estimate of sample k: `out` moved up by `steps` rows (`steps` < 0: down), the
    rows with no estimate NaN."""
    result = np.full_like(out, np.nan)
    n = len(out)
    if steps >= 0:
        result[:n - steps] = out[steps:]
    else:
        result[-steps:] = out[:n + steps]
    return result


def alignment_scan(out: np.ndarray, body: ImuData, shifts: Sequence[int] = (0, 1, 2, 3)) -> dict[int, float]:
    """The corrected rate error [°/s] (training.evaluate) of `out` (row k after the step of sample k) aligned by
    each shift: the shift where it is smallest is the loop's delay (ALIGNMENT_STEPS)."""
    from training.evaluate import compute_metrics
    return {s: compute_metrics(aligned(out, s), body).rate_dps for s in shifts}


@dataclass
class ClosedLoopResult:
    """One closed-loop run: the ImuFusion outputs aligned to the samples (row k = estimate of sample k, the last
    ALIGNMENT_STEPS rows NaN), as they came (`stepped`), the errors against truth (training.evaluate metrics,
    the main job's), and how it ran."""

    t: np.ndarray
    outputs: np.ndarray
    stepped: np.ndarray
    metrics: dict[str, float]
    importer: str
    seed: int
    step_s: float | None
    sensor_parameters: dict[str, float] = field(default_factory=dict)
    name: str = "recording"
    body: ImuData | None = field(default=None, repr=False)  # the truth in body axes the errors are against


def closed_loop(sensor_fmu: str | Path, fusion_fmu: str | Path, data: ImuData | str | Path, seed: int = 0,
                importer: str = "ecospy", sensor_overrides: dict[str, float] | None = None) -> ClosedLoopResult:
    """The recording's truth through the sensor FMU (noise seed `seed`, `sensor_overrides` on its parameters)
    and the ImuFusion FMU with `importer` ('ecospy': fixed step, Ecos's grid; 'fmpy': the recording's times);
    the outputs aligned to the samples and their errors against the truth (the main job's metrics)."""
    from training.data.io import read_imu_csv
    from training.evaluate import compute_metrics
    if importer not in IMPORTERS:
        raise ClosedLoopError(f"unknown importer '{importer}' (one of {', '.join(IMPORTERS)})")
    check_sensor_fmu(sensor_fmu)
    check_fusion_fmu(fusion_fmu)
    if not isinstance(data, ImuData):
        data = read_imu_csv(data)
    traj = trajectory(data, fusion_fmu)
    sensor_params = sensor_parameters(seed, traj.sensor_parameters, sensor_overrides)
    step = None
    if importer == "ecospy":
        step = fixed_step(traj.t, traj.rate_hz)
        stepped = run_ecospy(sensor_fmu, fusion_fmu, traj, sensor_params, traj.fusion_parameters, step)
    else:
        stepped = run_fmpy(sensor_fmu, fusion_fmu, traj, sensor_params, traj.fusion_parameters)
    outputs = aligned(stepped)
    return ClosedLoopResult(traj.t, outputs, stepped, compute_metrics(outputs, traj.body).as_dict(), importer, seed,
                            step, sensor_params, data.name, traj.body)


#: The files `write_closed_loop` writes into its folder.
OUTPUT_FILES = ("outputs.csv", "closed_loop.png", "closed_loop.json")


def summary_lines(result: ClosedLoopResult, sensor_fmu: str | Path, fusion_fmu: str | Path) -> list[str]:
    """What `imufmu closed-loop` prints: how the loop ran, then a Markdown table of the errors against truth with
    their units (the main job's metrics and labels, training.reports.report.ROWS)."""
    from training.reports.report import ROWS
    step = f"{result.step_s:g} s fixed steps" if result.step_s else "the recording's steps"
    noise = "noise on" if result.sensor_parameters.get("noise", 1.0) else "noise off"
    lines = [f"closed loop: the truth of {result.name} ({len(result.t)} samples, {step}) -> {Path(sensor_fmu).name} "
             f"(seed {result.seed}, {noise}) -> {Path(fusion_fmu).name}, co-simulated by {result.importer}; outputs "
             f"aligned {ALIGNMENT_STEPS} step back (the exchange's delay)", "",
             "| error against truth | closed loop |", "|---|---:|"]
    lines += [f"| {label} | {_number(result.metrics[key])} |" for key, label in ROWS]
    return lines


def _number(v: float) -> str:
    """4 significant digits, '—' where there is no value."""
    return f"{v:.4g}" if v is not None and np.isfinite(v) else "—"


def _plot(result: ClosedLoopResult, path: Path) -> Path:
    """PNG: the attitude errors [°] over time (roll, pitch, yaw; inclination and heading)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from training.evaluate import attitude_errors, tilt_heading_errors
    euler = np.rad2deg(attitude_errors(result.outputs, result.body))
    tilt = np.rad2deg(tilt_heading_errors(result.outputs, result.body))
    fig, axes = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    for k, name in enumerate(("roll", "pitch", "yaw")):
        axes[0].plot(result.t, euler[:, k], lw=0.7, label=name)
    for k, name in enumerate(("inclination", "heading")):
        axes[1].plot(result.t, tilt[:, k], lw=0.7, label=name)
    axes[0].set_ylabel("Euler error [°]")
    axes[1].set_ylabel("attitude error [°]")
    axes[1].set_xlabel("t [s]")
    axes[0].set_title(f"closed loop ({result.importer}, seed {result.seed}): {result.name}")
    for ax in axes:
        ax.legend(loc="upper right", fontsize=8)
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def write_closed_loop(result: ClosedLoopResult, sensor_fmu: str | Path, fusion_fmu: str | Path,
                      out_dir: str | Path) -> list[Path]:
    """Write into out_dir: outputs.csv (t and the ImuFusion outputs aligned to the samples, as `imufmu run`
    writes them), closed_loop.png (`_plot`) and closed_loop.json (how it ran and the errors); returns the paths."""
    import json
    from training.main_job import write_outputs_csv
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    csv = write_outputs_csv(out_dir / OUTPUT_FILES[0], result.t, result.outputs)
    png = _plot(result, out_dir / OUTPUT_FILES[1])
    doc = {"data": result.name, "sensor_fmu": str(sensor_fmu), "fusion_fmu": str(fusion_fmu),
           "importer": result.importer, "seed": result.seed, "step_s": result.step_s, "samples": len(result.t),
           "alignment_steps": ALIGNMENT_STEPS, "sensor_parameters": result.sensor_parameters,
           "metrics": {k: (float(v) if np.isfinite(v) else None) for k, v in result.metrics.items()}}
    path = out_dir / OUTPUT_FILES[2]
    path.write_text(json.dumps(doc, indent=1) + "\n")
    return [csv, png, path]


def closed_loop_to_folder(sensor_fmu: str | Path, fusion_fmu: str | Path, data_path: str | Path, out_dir: str | Path,
                          seed: int = 0, importer: str = "ecospy") -> tuple[ClosedLoopResult, list[Path], list[str]]:
    """`imufmu closed-loop`: `closed_loop` on the recording at data_path, its files written into out_dir; returns
    (the result, the paths written, the summary lines)."""
    result = closed_loop(sensor_fmu, fusion_fmu, data_path, seed=seed, importer=importer)
    paths = write_closed_loop(result, sensor_fmu, fusion_fmu, out_dir)
    return result, paths, summary_lines(result, sensor_fmu, fusion_fmu)
