"""Issue 35's acceptance figure: one sensor, one output frame. BROAD trials 01 + 02 (a z-up board) are
trained twice, once as published (with the optical attitude reference ref_q) and once from a copy of
the recordings without the reference columns; both models are built into FMUs and every BROAD trial
runs through both with fmpy. At every rest of every trial (training.selfcal.rest.detect_rest on the
raw signals: no reference needed) the two FMUs' quaternions q_* must agree within AGREEMENT_DEG: they
report the attitude of the same body axes. Before issue 35 the model trained with the reference kept
the sensor axes and the other turned them 180° about x (179° apart at every rest).

The sensor-frame outputs q_sensor_* of each FMU are scored against the trial's own reference (sensor
axes, as BROAD publishes it) with BROAD's total error, with no rotation on the user's side.

benchmarks/frame_agreement.py prints the table for docs/fmu.md (Frames); tests/test_frame_agreement.py
runs the small form.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from contract.layout import OUTPUTS
from contract.mounting import MOUNT_SETTINGS, frame_text
from training.data.dataset import ImuData, recording_parameters
from training.data.io import read_imu_csv, write_imu_csv

#: The two FMUs' attitudes must agree within this at every rest [°] (issue 35's acceptance bound: the
#: 180° of a frame flip is two orders above it; two calibrations of one sensor from different references
#: leave a degree or so of inclination between them).
AGREEMENT_DEG = 2.0
#: The training trials (BROAD's two slow undisturbed rotations, as `imufmu bench broad-trained`).
TRAINING = ("01_undisturbed_slow_rotation_A", "02_undisturbed_slow_rotation_B")
#: The two trainings: label -> whether the reference columns are kept.
TRAININGS = {"with ref_q": True, "without ref_q": False}
Q = [OUTPUTS.index(n) for n in ("q_w", "q_x", "q_y", "q_z")]
Q_SENSOR = [OUTPUTS.index(n) for n in ("q_sensor_w", "q_sensor_x", "q_sensor_y", "q_sensor_z")]
#: The table's header (tests/test_doc_tables.py finds it in docs/fmu.md).
TABLE_HEADER = ("| trial | rests | with vs without ref_q: worst rest (median over the rest) [°] | largest at any rest "
                "sample [°] | old rule (with ref_q at mount 1, 2, 3) vs without: smallest rest [°] | q_sensor_* vs "
                "ref_q, BROAD total RMSE [°]: with / without ref_q |")
#: The mounting the old rule gave a model trained with ref_q (issue 35: 'ref_q present => identity').
OLD_RULE = dict(zip(MOUNT_SETTINGS, (1.0, 2.0, 3.0)))


def without_reference(data: ImuData) -> ImuData:
    """The recording as a user without a reference has it: no ref_q, ref_gyr/acc/mag, sidecar reference 'none'."""
    return replace(data, ref_q=None, ref_gyr=None, ref_acc=None, ref_mag=None,
                   meta={**data.meta, "reference": "none"})


def angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N,) angle [°] between the unit quaternions a and b (N, 4): 2·acos(|a·b|)."""
    return np.rad2deg(2.0 * np.arccos(np.clip(np.abs(np.sum(a * b, axis=1)), 0.0, 1.0)))


@dataclass(frozen=True)
class TrialAgreement:
    """One trial: its rests' worst median angle and largest sample angle between the two FMUs [°], the
    smallest rest median between the FMU trained with ref_q run at the old rule's identity mounting and the
    one trained without [°], and BROAD's total error [°] of each FMU's q_sensor_* against the trial's
    reference (label -> °)."""

    trial: str
    rests: int
    worst_rest_deg: float
    worst_sample_deg: float
    old_rule_deg: float
    sensor_total_deg: dict[str, float]

    def row(self) -> str:
        sensor = " / ".join(f"{self.sensor_total_deg[label]:.2f}" for label in TRAININGS)
        return (f"| {self.trial} | {self.rests} | {self.worst_rest_deg:.3f} | {self.worst_sample_deg:.3f} "
                f"| {self.old_rule_deg:.1f} | {sensor} |")


def train_pair(folder: Path, seconds: float | None = None, seed: int = 0, broad: Path | None = None) -> dict[str, Path]:
    """Train TRAINING with and without the reference (the latter from copies written without the reference
    columns, read back as a user's files are) and build each model's FMU in `folder`; `seconds`: only each
    recording's first seconds; broad: the BROAD folder (training.bench.bench.broad_dir). Returns label -> FMU path."""
    from training.artefact import settings_dict
    from training.bench.bench import broad_dir
    from training.fmu_build import build_fmu_from_model
    from training.train import train
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    originals = [broad_dir(broad) / f"{name}.csv.gz" for name in TRAINING]
    fmus = {}
    for label, keep in TRAININGS.items():
        datasets = []
        for path in originals:
            data = read_imu_csv(path)
            if not keep:
                path = write_imu_csv(without_reference(data), folder / f"no_ref_{path.name}")
                data = read_imu_csv(path)
                assert data.ref_q is None
            if seconds is not None:
                data = data.slice(slice(0, int(np.searchsorted(data.t, data.t[0] + seconds))))
            datasets.append(data)
        artefact = train(datasets, seed=seed, progress=False, allow_identity=seconds is not None)
        model = folder / f"model_{'ref' if keep else 'noref'}.json"
        artefact.save(model)
        codes = tuple(int(settings_dict(artefact)[name]) for name in MOUNT_SETTINGS)
        print(f"{label}: {frame_text(codes)}", flush=True)
        fmus[label] = build_fmu_from_model(model, folder / f"ImuFusion_{'ref' if keep else 'noref'}.fmu")
    return fmus


def trial_agreement(fmus: dict[str, Path], path: Path, seconds: float | None = None) -> TrialAgreement:
    """Run one BROAD trial through every FMU of `fmus` (fmpy) and compare them at its rests."""
    from fmu.cosim import run_fmu
    from training.bench.bench import broad_errors
    from training.selfcal.rest import detect_rest
    data = read_imu_csv(path)
    if seconds is not None:
        data = data.slice(slice(0, int(np.searchsorted(data.t, data.t[0] + seconds))))
    outs = {label: run_fmu(fmu, data.t - data.t[0], data.inputs(), parameters=recording_parameters(data))
            for label, fmu in fmus.items()}
    old = run_fmu(fmus[next(iter(TRAININGS))], data.t - data.t[0], data.inputs(), parameters={**recording_parameters(data), **OLD_RULE})
    a, b = (outs[label][:, Q] for label in TRAININGS)
    angles, old_angles = angle_deg(a, b), angle_deg(old[:, Q], b)
    rests = [w for w in detect_rest(data).windows if w.kind == "rest"]
    medians = [float(np.median(angles[w.start:w.stop])) for w in rests]
    largest = [float(np.max(angles[w.start:w.stop])) for w in rests]
    old_medians = [float(np.median(old_angles[w.start:w.stop])) for w in rests]
    sensor = {label: broad_errors(out[:, Q_SENSOR], data)["total"] for label, out in outs.items()}
    return TrialAgreement(Path(path).name.split(".")[0], len(rests), max(medians, default=float("nan")),
                          max(largest, default=float("nan")), min(old_medians, default=float("nan")), sensor)


def frame_agreement(folder: Path, trials: list[str] | None = None, seconds: float | None = None,
                    train_seconds: float | None = None, broad: Path | None = None) -> list[TrialAgreement]:
    """The acceptance table's rows: the FMU pair trained in `folder` (train_pair) run over `trials` (name
    prefixes such as '01'; all BROAD trials when None), each cut to its first `seconds` when given."""
    from training.bench.bench import trial_paths
    paths = trial_paths(trials, broad)
    fmus = train_pair(folder, seconds=train_seconds, broad=broad)
    return [trial_agreement(fmus, p, seconds) for p in paths]


def print_table(rows: list[TrialAgreement]) -> None:
    """The table of docs/fmu.md (Frames) and its summary line."""
    print(TABLE_HEADER)
    print("|---|---|---|---|---|---|")
    for r in rows:
        print(r.row())
    worst = max(r.worst_rest_deg for r in rows)
    print(f"\n{len(rows)} trials, {sum(r.rests for r in rows)} rests: worst rest {worst:.3f}° "
          f"(bound {AGREEMENT_DEG:g}°), largest rest sample {max(r.worst_sample_deg for r in rows):.3f}°; the old rule: "
          f"at least {min(r.old_rule_deg for r in rows):.1f}° at every rest")
