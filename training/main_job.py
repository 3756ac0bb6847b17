"""The main job: simulate calibration data -> train -> build FMU -> validate -> co-simulate -> report.

Each step is one library call; `imufmu pipeline` calls `run_main_job`.
"""
from __future__ import annotations

import json
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from contract.errors import ImuFusionError
from contract.mounting import array_codes
from training.data.dataset import ImuData, recording_parameters
from training.evaluate import (ACCEPTANCE, absent_outputs, compute_metrics, max_abs_difference,
                               raw_sensor_metrics)
from training.mounting import body_references

SCENARIO_DIR = Path(__file__).resolve().parents[1] / "scenarios"
DEFAULT_CALIBRATION = "calibration.toml"
DEFAULT_EVALUATIONS = ("eval_handheld.toml", "eval_figure8.toml", "eval_rotations.toml")


@dataclass
class ScenarioResult:
    """Outcome of one evaluation scenario co-simulated through the FMU."""

    name: str
    samples: int
    corrected: dict[str, float]
    raw: dict[str, float]
    fmu_vs_batch_max_diff: float
    outputs_csv: str
    data: ImuData = field(repr=False)           # the recording (for plots)
    out: np.ndarray = field(repr=False)         # (N, len(OUTPUTS)) FMU outputs
    out_raw: np.ndarray = field(repr=False)     # (N, len(OUTPUTS)) runtime outputs without compensation
    absent: dict[str, int] = field(default_factory=dict)  # NaN triads of an absent sensor: samples (evaluate.absent_outputs)

    def as_dict(self) -> dict:
        """JSON-ready figures (no arrays)."""
        return {"name": self.name, "samples": self.samples, "corrected": self.corrected,
                "raw": self.raw, "fmu_vs_batch_max_diff": self.fmu_vs_batch_max_diff,
                "outputs_csv": self.outputs_csv, "absent_outputs": self.absent, "passed": self.passed()}

    def passed(self) -> bool:
        """True when every acceptance figure is met."""
        return all(self.corrected[k] <= v for k, v in ACCEPTANCE.items())


@dataclass
class MainJobSummary:
    """Everything the main job produced, for the table, the report and tests."""

    out_dir: str
    model_path: str
    fmu_path: str
    validation_problems: list[str]
    scenarios: list[ScenarioResult] = field(default_factory=list)
    timings_s: dict[str, float] = field(default_factory=dict)

    def passed(self) -> bool:
        """True when the FMU validated and every scenario met its bounds."""
        return not self.validation_problems and all(s.passed() for s in self.scenarios)


def uncompensated_settings(settings: np.ndarray) -> np.ndarray:
    """A copy of the flat settings with the temperature/gain/bias model switched off."""
    from contract.layout import SETTINGS
    s = np.array(settings, dtype=float)
    s[[n for n, _ in SETTINGS].index("enable_thermal")] = 0.0
    return s


def evaluate_recording(fmu_path: Path, coefficients: np.ndarray, settings: np.ndarray,
                       data: ImuData, out_csv: Path, aux_columns: Sequence[str] = ()) -> ScenarioResult:
    """Co-simulate `data` through the FMU, compare with the batch runtime and with truth;
    aux_columns: the model's auxiliary-input columns (`[a["column"] for a in artefact.aux_inputs]`)."""
    from fmu.cosim import run_fmu
    from training.runtime import run_batch
    params = recording_parameters(data)
    s = settings_with(settings, params)
    inputs = data.inputs(aux_columns)
    out_fmu = run_fmu(fmu_path, data.t, inputs, parameters=params, progress=True)
    out_batch = run_batch(coefficients, s, data.t, inputs)
    diff = max_abs_difference(out_fmu, out_batch)  # an absent sensor's NaN outputs match
    raw_out = run_batch(coefficients, uncompensated_settings(s), data.t, inputs)
    raw = raw_sensor_metrics(data)
    body = body_references(data, array_codes(s))  # the outputs are in body axes
    raw_att = compute_metrics(raw_out, body)
    raw.update({k: v for k, v in raw_att.as_dict().items() if k.endswith("_deg")})
    write_outputs_csv(out_csv, data.t, out_fmu)
    return ScenarioResult(data.name, len(data), compute_metrics(out_fmu, body).as_dict(), raw,
                          diff, str(out_csv), data, out_fmu, raw_out, absent_outputs(out_fmu))


def settings_with(settings: np.ndarray, overrides: dict[str, float]) -> np.ndarray:
    """Flat settings array with named overrides applied."""
    from contract.layout import SETTINGS
    names = [n for n, _ in SETTINGS]
    s = np.array(settings, dtype=float)
    for k, v in overrides.items():
        s[names.index(k)] = float(v)
    return s


def write_outputs_csv(path: Path, t: np.ndarray, out: np.ndarray) -> Path:
    """Write runtime outputs as CSV: t then the OUTPUTS columns, exact float formatting."""
    from contract.layout import OUTPUTS
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    table = np.column_stack([t, out])
    np.savetxt(path, table, delimiter=",", header=",".join(("t",) + OUTPUTS), comments="",
               fmt="%.17g")
    return path


def outputs_sidecar(path: str | Path) -> Path:
    """The sidecar JSON of an outputs CSV (the frame of its outputs): 'OUT.csv[.gz]' -> 'OUT.json' ('OUT.json.json'
    for an outputs file named OUT.json)."""
    from training.data.io import sidecar_path
    side = sidecar_path(path)
    return side if side != Path(path) else Path(path).with_name(Path(path).name + ".json")


@dataclass
class RecordingRun:
    """What `run_recording` wrote and what `imufmu run` prints."""

    path: Path             # the outputs CSV
    samples: int
    log: list[str]         # the FMU's log messages
    notes: list[str]       # training.reports.run_summary.run_notes of the outputs
    frame: list[str] = field(default_factory=list)  # training.reports.run_summary.frame_lines of the run
    sidecar: Path | None = None  # the outputs' sidecar JSON (their frame, training.reports.run_summary.frame_record)


def run_recording(fmu_path: Path, data_path: Path, out_csv: str | Path,
                  overrides: dict[str, float] | None = None, calibration: Path | None = None,
                  variant: str | None = None) -> RecordingRun:
    """`imufmu run`: co-simulate the recording at `data_path` through the FMU with fmpy, its aux_*
    columns into the auxiliary inputs the FMU's model maps them to, the parameters its sidecar
    fixes (`recording_parameters`) updated by `overrides`; write the outputs to `out_csv`. `calibration`:
    a calibration.ssv (fmu.calibration_file) whose coefficients, settings and auxiliary-input map
    replace the FMU's own (the sidecar's parameters and `overrides` still apply over its settings); `variant`:
    the same from the parameter set of that label embedded in the FMU (fmu.references)."""
    from contract.mounting import MOUNT_SETTINGS, settings_codes
    from fmu.archive import declared_mounting, read_description
    from fmu.cosim import run_fmu
    from fmu.packer import fmu_aux_columns
    from fmu.calibration_file import read_calibration
    from fmu.references import read_embedded
    from training.data.io import read_imu_csv
    from training.reports.run_summary import frame_lines, frame_record, run_notes
    data = read_imu_csv(data_path)
    read_description(fmu_path)  # the archive checks (fmu.archive) before any member is read
    coefficients, settings, aux = (read_calibration(calibration) if calibration is not None
                                   else read_embedded(fmu_path, variant) if variant is not None else (None, {}, []))
    params = settings | recording_parameters(data) | dict(overrides or {})
    inputs = data.inputs(aux_columns=[a["column"] for a in aux] if aux else fmu_aux_columns(fmu_path))
    log: list[str] = []
    out = run_fmu(fmu_path, data.t, inputs, parameters=params, progress=True, log=log, coefficients=coefficients)
    codes = settings_codes({**dict(zip(MOUNT_SETTINGS, declared_mounting(fmu_path))), **params})
    path = write_outputs_csv(out_csv, data.t, out)
    sidecar = outputs_sidecar(path)
    sidecar.write_text(json.dumps(frame_record(codes, Path(fmu_path).name, Path(data_path).name), indent=1,
                                  ensure_ascii=False) + "\n", encoding="utf-8")
    return RecordingRun(path, len(data), log, run_notes(out), frame_lines(codes), sidecar)


def run_main_job(out_dir: Path, seed: int = 0, calibration: str = DEFAULT_CALIBRATION,
                 evaluations: tuple[str, ...] = DEFAULT_EVALUATIONS) -> MainJobSummary:
    """The main job on the bundled scenarios; writes everything under `out_dir`."""
    from contract.layout import settings_array
    from fmu.validator import validate_fmu
    from training.artefact import coefficients_array, settings_dict
    from training.data.io import write_imu_csv
    from training.fmu_build import build_fmu
    from training.reports.report import write_report
    from training.simulator import load_scenario, simulate
    from training.train import train
    from training.noise.characterise import characterise
    from training.noise.kalibr import write_imu_yaml
    from training.noise.report import YAML_NAME as IMU_YAML

    out_dir = Path(out_dir)
    timings: dict[str, float] = {}
    clock = time.perf_counter()

    def lap(name: str) -> None:
        nonlocal clock
        now = time.perf_counter()
        timings[name] = now - clock
        clock = now

    print(f"[1/5] simulating calibration data ({calibration}, seed {seed})")
    cal = simulate(load_scenario(SCENARIO_DIR / calibration), seed=seed)
    write_imu_csv(cal, out_dir / "data" / f"{cal.name}.csv.gz")
    lap("simulate")
    print("[2/5] training the gain/bias temperature model")
    artefact = train([cal], seed=seed)
    artefact.noise = characterise([cal]).block   # as `imufmu train` does: the virtual sensor's noise figures
    model_path = out_dir / "model" / "model.json"
    artefact.save(model_path)
    write_imu_yaml(artefact.noise, model_path.parent / IMU_YAML)
    lap("train")
    print("[3/5] building the FMU")
    coefficients = coefficients_array(artefact)
    settings = settings_dict(artefact)
    fmu_path = build_fmu(coefficients, settings, out_dir / "ImuFusion.fmu",
                         provenance=f"model {model_path.name}, seed {seed}", aux_inputs=artefact.aux_inputs,
                         training_data=artefact.training_data, notes=artefact.notes)
    lap("build")
    print("[4/5] validating the FMU")
    problems = validate_fmu(fmu_path)
    lap("validate")
    summary = MainJobSummary(str(out_dir), str(model_path), str(fmu_path), problems)
    flat = np.asarray(settings_array(settings))
    for k, name in enumerate(evaluations):
        print(f"[5/5] co-simulating {name} ({k + 1}/{len(evaluations)})")
        data = simulate(load_scenario(SCENARIO_DIR / name), seed=seed + 1 + k)
        write_imu_csv(data, out_dir / "data" / f"{data.name}.csv.gz")
        summary.scenarios.append(evaluate_recording(
            fmu_path, coefficients, flat, data, out_dir / "runs" / f"{data.name}.csv",
            [a["column"] for a in artefact.aux_inputs]))
    lap("co-simulate")
    summary.timings_s = timings
    write_report(summary, out_dir)
    (out_dir / "summary.json").write_text(json.dumps(summary_dict(summary), indent=2) + "\n")
    return summary


def summary_dict(summary: MainJobSummary) -> dict:
    """JSON-ready form of the summary (the model and FMU named relative to the folder summary.json is in)."""
    return {"model": os.path.relpath(summary.model_path, summary.out_dir),
            "fmu": os.path.relpath(summary.fmu_path, summary.out_dir),
            "validation_problems": summary.validation_problems,
            "acceptance": ACCEPTANCE, "passed": summary.passed(), "timings_s": summary.timings_s,
            "scenarios": [s.as_dict() for s in summary.scenarios]}


def check_summary(summary: MainJobSummary) -> None:
    """Raise ImuFusionError naming what failed when the main job missed a bound."""
    if summary.validation_problems:
        raise ImuFusionError("FMU validation found problems: " + "; ".join(summary.validation_problems))
    for s in summary.scenarios:
        bad = [f"{k} = {s.corrected[k]:.4g} > {v}" for k, v in ACCEPTANCE.items()
               if not s.corrected[k] <= v]
        if bad:
            raise ImuFusionError(f"scenario {s.name} missed its bounds: " + ", ".join(bad))
