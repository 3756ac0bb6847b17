"""`imufmu bench methods DATA... --out DIR [--eval EVAL...] [--seed N]` (issue 33 item 1): every form of the four
source methods (training.models.methods.METHODS) beside the product's form, through the FMU, on a user's data.

Each row is the unit as `train` calibrates it with one method in one form:

- a **training-time form** (the ELM's back-tuning schedule, the PSO-BP fit) is trained as `imufmu train --method
  NAME=FORM` does it: `training.train.train(methods={NAME: FORM})`, one training per form, the method selected alone;
- a **runtime form** (the particle filter's, the attitude filter's) is a switch of the FMU: the training without
  `--method` (train's own choice) with the FMU parameters of that form (`method_settings`) on top;
- per method, one more row: train's own choice, without `--method`.

Every row runs through the FMU with fmpy, as `imufmu run GENERIC.fmu EVAL --calibration UNIT.ssv
--param …` does: the generic FMU (`build_fmu_from_model(None, …)`: compiled once, or the prebuilt one without a
compiler) with the training's coefficients and settings set as parameters (fmu.cosim.run_fmu), the sidecar's
declination and field norm on top (recording_parameters), then the form's parameters. One generic FMU serves every
training: its coefficients are parameters, so no FMU is compiled per row (tests/test_calibration_file.py: the generic FMU with a
unit's calibration equals that unit's compiled FMU bit for bit).

Figures: the ones the method affects (FIGURES), RMS over each evaluation recording's eval_mask samples, averaged over
the evaluation recordings, against the best reference the recording offers (reference columns, or derived from
ref_q; the true zero rate of a static log); where it offers none, the RMS difference from the product form's
output, said so in the row. Evaluation data: `--eval` recordings, else the last HOLDOUT_FRACTION (in time) of each
calibration recording, the rest training. Training CPU time: `time.process_time()` around `train` (the whole call;
the runtime forms share train's own training).
"""
from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from contract import layout
from contract.errors import ModelError
from contract.mounting import array_codes
from training.data.dataset import ImuData, recording_parameters
from training.data.reference_source import choose_reference
from training.evaluate import compute_metrics
from training.frames import wrap_angle
from training.models.methods import FITTED, METHODS, method_settings

#: Share of each calibration recording (its end, in time) evaluated on when no --eval recording is given; the
#: first 1 − HOLDOUT_FRACTION trains (the ELM's held-out share in train, training.train.ELM_HOLDOUT_FRACTION).
HOLDOUT_FRACTION = 0.25
#: Reference sources (training.data.reference_source.SOURCES) that count as truth when evaluating a triad: a
#: static log's zero rate is the gyro's truth, its mean field is not the magnetometer's.
EVAL_REFERENCES = {"gyr": ("columns", "attitude", "static"), "mag": ("columns", "attitude")}
#: What each sensor is called in a row that cannot run.
SENSOR_NAMES = {"gyr": "gyroscope", "acc": "accelerometer", "mag": "magnetometer", "temp": "temperature"}


@dataclass(frozen=True)
class Figure:
    """What a method's rows show: the quantity and its unit, the ImuData reference it is measured against and the
    training.evaluate.Metrics fields it gives, the output columns compared with the product form's without one, their
    factor to the unit, whether they are angles (their differences wrapped), and the sensors the method needs in the
    evaluation data."""

    quantity: str
    unit: str
    reference: str
    metrics: tuple[str, ...]
    outputs: tuple[str, ...]
    factor: float
    angles: bool
    sensors: tuple[str, ...]

    @property
    def label(self) -> str:
        """The figure against a reference, with its unit."""
        return f"{self.quantity} error RMS [{self.unit}]"


_FIELD = Figure("field", "µT", "ref_mag", ("field_ut",), ("field_x", "field_y", "field_z"), 1.0, False, ("mag",))
#: method -> the figure its rows show (the keys are METHODS').
FIGURES = {
    "elm": _FIELD,
    "pf": _FIELD,
    "psobp": Figure("gyro rate", "°/s", "ref_gyr", ("rate_dps",), ("rate_x", "rate_y", "rate_z"), float(np.rad2deg(1.0)), False,
                    ("gyr", "temp")),
    "attitude": Figure("roll / pitch / yaw", "°", "ref_q", ("roll_deg", "pitch_deg", "yaw_deg"), ("roll", "pitch", "yaw"),
                       float(np.rad2deg(1.0)), True, ("gyr", "acc")),
}
#: The form column of train's own choice (no --method).
OWN = "train's own"
#: The header of the printed table.
TABLE_HEADER = "| method | form | how it runs | figure | value | training CPU [s] |"


@dataclass
class Training:
    """One `train` call: its label (the command), the artefact (None when train refused), CPU time [s], refusal."""

    label: str
    artefact: object | None
    cpu_s: float
    error: str = ""


@dataclass
class Row:
    """One row of the table: method, form (or "train's own: …"), whether it is the product's form, how it runs, the
    figure's values (FIGURES, in its unit; None when the row cannot run), whether they are against a reference,
    training CPU [s] and why the row cannot run ('' when it can)."""

    method: str
    form: str
    product: bool
    how: str
    values: list[float] | None
    referenced: bool
    cpu_s: float | None
    cannot_run: str = ""


def product_form(method: str) -> str:
    """The product's form of `method`: the one fitted by its fitter's defaults whose FMU settings (but the stage's
    enable switch) are the FMU parameters' defaults."""
    defaults = dict(layout.SETTINGS)
    return next(name for name, form in METHODS[method].items() if not form.fit and all(
        defaults[k] == v for k, v in form.settings.items() if not k.startswith("enable_")))


def own_choice(method: str, settings: dict[str, float]) -> str:
    """What train chose for `method` without --method: "off" when its stage switch is 0, else the form whose FMU
    settings it wrote (a fitted method's: the product's)."""
    forms = METHODS[method]
    switch = next((k for k in next(iter(forms.values())).settings if k.startswith("enable_")), None)
    if switch is not None and settings.get(switch, 0.0) == 0.0:
        return "off"
    return next((name for name, form in forms.items() if not form.fit and all(
        settings.get(k) == v for k, v in form.settings.items())), "another setting")


def split_holdout(datasets: list[ImuData]) -> tuple[list[ImuData], list[ImuData]]:
    """(training parts, evaluation parts): each recording's first 1 − HOLDOUT_FRACTION and last HOLDOUT_FRACTION of
    its samples (in time)."""
    cuts = [int(round(len(d) * (1.0 - HOLDOUT_FRACTION))) for d in datasets]
    return ([d.slice(slice(0, k)) for d, k in zip(datasets, cuts)],
            [d.slice(slice(k, None)) for d, k in zip(datasets, cuts)])


def evaluation_recording(data: ImuData) -> ImuData:
    """`data` with ref_gyr and ref_mag filled from the best reference it offers that counts as truth
    (EVAL_REFERENCES; training.data.reference_source.choose_reference)."""
    fields = {}
    for triad, sources in EVAL_REFERENCES.items():
        ref = choose_reference([data], triad)
        if ref.source in sources:
            fields[f"ref_{triad}"] = getattr(ref.datasets[0], f"ref_{triad}")
    return replace(data, **fields)


def _has(data: ImuData, sensor: str) -> bool:
    """True when the recording has a finite sample of `sensor` (a triad name or 'temp')."""
    return bool(np.isfinite(data.temp).any()) if sensor == "temp" else data.has(sensor)


def _missing_sensor(method: str, datas: list[ImuData]) -> str:
    """Why `method` cannot run on the evaluation recordings for want of a sensor, or ''."""
    missing = [s for s in FIGURES[method].sensors if not any(_has(d, s) for d in datas)]
    return f"no {' and no '.join(SENSOR_NAMES[s] for s in missing)} in the evaluation recordings" if missing else ""


def _train(datasets: list[ImuData], seed: int, methods: dict[str, str]) -> Training:
    """`train` with the selection `methods` (as `imufmu train --method` passes it), timed in CPU seconds; a refusal
    (ModelError) is kept as the training's error."""
    from training.train import train
    label = "train" + "".join(f" --method {m}={f}" for m, f in methods.items())
    start = time.process_time()
    try:
        artefact = train(datasets, seed=seed, progress=False, methods=methods)
    except ModelError as e:
        return Training(label, None, time.process_time() - start, str(e))
    return Training(label, artefact, time.process_time() - start)


def run_through_fmu(fmu: Path, artefact, overrides: dict[str, float], data: ImuData) -> np.ndarray:
    """(N, len(OUTPUTS)) outputs of the generic FMU `fmu` with the artefact's coefficients and settings as parameters,
    the recording's sidecar parameters and `overrides` on top, as `imufmu run FMU DATA --calibration` runs it (from
    t = 0: fmpy matches times relative to the start)."""
    from fmu.cosim import run_fmu
    from training.artefact import coefficients_array, settings_dict
    params = settings_dict(artefact) | recording_parameters(data) | overrides
    inputs = data.inputs([a["column"] for a in artefact.aux_inputs])
    return run_fmu(fmu, data.t - data.t[0], inputs, parameters=params, coefficients=coefficients_array(artefact))


def _against_reference(figure: Figure, out: np.ndarray, data: ImuData, settings: dict[str, float]) -> list[float]:
    """The figure's Metrics of `out` against the recording's reference, in the body axes of the mounting settings."""
    from training.mounting import body_references
    metrics = compute_metrics(out, body_references(data, array_codes(layout.settings_array(settings))))
    return [float(getattr(metrics, name)) for name in figure.metrics]


def _against_product(figure: Figure, out: np.ndarray, product: np.ndarray) -> list[float]:
    """RMS difference [label unit] of the figure's outputs from the product form's: per angle, or over the triad."""
    cols = [layout.OUTPUTS.index(name) for name in figure.outputs]
    diff = out[:, cols] - product[:, cols]
    if figure.angles:
        return [float(np.sqrt(np.nanmean(wrap_angle(diff[:, k]) ** 2)) * figure.factor) for k in range(len(cols))]
    return [float(np.sqrt(np.nanmean(diff ** 2)) * figure.factor)]


def _figures(figure: Figure, outs: list[np.ndarray], products: list[np.ndarray] | None, datas: list[ImuData],
             settings: dict[str, float]) -> tuple[list[float] | None, bool]:
    """(values averaged over the evaluation recordings, against a reference): against the reference when every
    recording offers one (NaN where a recording has no eval_mask sample with it), else the difference from the product
    form's outputs (None when those did not run)."""
    if all(getattr(d, figure.reference) is not None for d in datas):
        referenced = [_against_reference(figure, out, d, settings) for out, d in zip(outs, datas)]
        return [float(v) for v in np.mean(referenced, axis=0)], True
    if products is None:
        return None, False
    return [float(v) for v in np.mean([_against_product(figure, o, p) for o, p in zip(outs, products)], axis=0)], False


@dataclass(frozen=True)
class Plan:
    """One row to run: method, form ('' for train's own choice), the training it runs on, the FMU parameters set on
    top of it, how it runs (text) and why it cannot ('' when it can)."""

    method: str
    form: str
    training: Training
    overrides: dict[str, float]
    how: str
    cannot_run: str = ""


def _fitted_plans(method: str, calibration: list[ImuData], seed: int, progress) -> list[Plan]:
    """A fitted method's rows: one `train --method` per form; a refusal (the stage cannot be fitted on these
    recordings) is the row's reason."""
    plans = []
    for form in METHODS[method]:
        progress.set_description(f"train --method {method}={form}")
        training = _train(calibration, seed, {method: form})
        progress.update()
        plans.append(Plan(method, form, training, {}, f"`{training.label}`", training.error))
    return plans


def _plans(calibration: list[ImuData], seed: int, datas: list[ImuData], progress) -> list[Plan]:
    """The rows to run, train's own choice last for each method; progress advances once per training."""
    progress.set_description("train")
    own = _train(calibration, seed, {})
    progress.update()
    if own.artefact is None:
        raise ModelError(f"bench methods: train cannot calibrate these recordings: {own.error}")
    plans = []
    for method, forms in METHODS.items():
        plans += (_fitted_plans(method, calibration, seed, progress) if method in FITTED else
                  [Plan(method, form, own, method_settings({method: form}), f"`train`, FMU parameters of `{method}={form}`")
                   for form in forms])
        plans.append(Plan(method, "", own, {}, "`train`"))
    missing = {method: _missing_sensor(method, datas) for method in METHODS}
    return [replace(p, cannot_run=p.cannot_run or missing[p.method]) for p in plans]


def _row(plan: Plan, outs: dict[tuple[str, str], list[np.ndarray] | None], datas: list[ImuData]) -> Row:
    """The table row of a plan run (outs: (method, form) -> its outputs per evaluation recording, None: not run)."""
    from training.artefact import settings_dict
    figure = FIGURES[plan.method]
    form = plan.form or f"{OWN}: {own_choice(plan.method, plan.training.artefact.settings)}"
    row = Row(plan.method, form, plan.form == product_form(plan.method), plan.how, None, False,
              plan.training.cpu_s)
    if plan.cannot_run:
        return replace(row, cannot_run=plan.cannot_run, cpu_s=None if plan.training.artefact is None else row.cpu_s)
    settings = settings_dict(plan.training.artefact) | plan.overrides
    values, referenced = _figures(figure, outs[(plan.method, plan.form)],
                                  outs.get((plan.method, product_form(plan.method))), datas, settings)
    if values is None:
        return replace(row, cannot_run="no reference in the evaluation recordings and the product's form did not run")
    return replace(row, values=values, referenced=referenced)


def bench_rows(calibration: list[ImuData], evaluation: list[ImuData], fmu: Path, seed: int = 0) -> list[Row]:
    """Train and run every method form (module docstring) on `calibration`, evaluate on `evaluation` through the
    generic FMU at `fmu`, with a progress bar (stderr) over the trainings and FMU runs."""
    from tqdm import tqdm
    datas = [evaluation_recording(d) for d in evaluation]
    with tqdm(total=1 + sum(len(METHODS[m]) for m in FITTED), unit="step") as progress:
        plans = _plans(calibration, seed, datas, progress)
        progress.total += len(plans)
        outs = {}
        for plan in plans:
            progress.set_description(f"FMU: {plan.method} {plan.form or OWN}")
            outs[(plan.method, plan.form)] = None if plan.cannot_run else [
                run_through_fmu(fmu, plan.training.artefact, plan.overrides, d) for d in datas]
            progress.update()
    return [_row(p, outs, datas) for p in plans]


def _figure_text(row: Row) -> str:
    """The figure column: the figure against the reference, or what is shown instead."""
    figure = FIGURES[row.method]
    if row.values is None or row.referenced:
        return figure.label
    return f"no reference: {figure.quantity} RMS difference from `{product_form(row.method)}`'s output [{figure.unit}]"


def _row_text(row: Row) -> str:
    """One Markdown row of the table."""
    form = row.form if row.form.startswith(OWN) else f"`{row.form}`" + (" (product)" if row.product else "")
    value = f"cannot run: {row.cannot_run}" if row.cannot_run else " / ".join(f"{v:.3g}" for v in row.values)
    cpu = "–" if row.cpu_s is None else f"{row.cpu_s:.1f}"
    return f"| `{row.method}` | {form} | {row.how} | {_figure_text(row)} | {value} | {cpu} |"


def table(rows: list[Row]) -> str:
    """The side-by-side table of every row."""
    return "\n".join([TABLE_HEADER, "|---|---|---|---|---|---|", *map(_row_text, rows)])


def _names(datas: list[ImuData]) -> str:
    """'name (N samples), …' of recordings."""
    return ", ".join(f"{d.name} ({len(d)} samples)" for d in datas)


def _first(data: ImuData, samples: int | None) -> ImuData:
    """The recording's first `samples` samples (all when None)."""
    return data if samples is None else data.slice(slice(0, samples))


def bench_methods(paths: list[Path], out_dir: str | Path, eval_paths: list[Path] = (), seed: int = 0,
                  samples: int | None = None) -> list[Row]:
    """`imufmu bench methods`: read the calibration recordings `paths` (and the evaluation recordings `eval_paths`;
    without them, the held-out split of split_holdout, said loudly), build the generic FMU, run every method form
    (bench_rows), print the table and write OUT/methods.md and OUT/methods.json; returns the rows. samples: only the
    first `samples` samples of each recording (the small form of the doc tables)."""
    from training.data.io import read_imu_csv
    from training.fmu_build import build_fmu_from_model
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    recordings = [_first(read_imu_csv(p), samples) for p in paths]
    evaluation = [_first(read_imu_csv(p), samples) for p in eval_paths]
    if evaluation:
        calibration, split = recordings, f"evaluated on {_names(evaluation)}"
    else:
        calibration, evaluation = split_holdout(recordings)
        split = (f"NO --eval RECORDING: trained on the first {1 - HOLDOUT_FRACTION:.0%} of each calibration recording "
                 f"and evaluated on its last {HOLDOUT_FRACTION:.0%} (in time)")
        print(f"note: {split}", flush=True)
    fmu = build_fmu_from_model(None, out_dir / "ImuFusion.fmu")
    rows = bench_rows(calibration, evaluation, fmu, seed)
    text = "\n".join([f"Calibration: {_names(calibration)}; {split}; seed {seed}, one run.", "",
                      "Each row through the FMU (fmpy): the generic FMU with its training's coefficients and settings "
                      "as parameters, the form's FMU parameters on top; figures: RMS over each evaluation recording's "
                      f"eval_mask samples, mean over the {len(evaluation)} evaluation recording(s); training CPU: "
                      "process time of the whole `train` call (the runtime forms share train's own).", "",
                      table(rows)]) + "\n"
    (out_dir / "methods.md").write_text(text)
    (out_dir / "methods.json").write_text(json.dumps(
        {"calibration": [d.name for d in calibration], "evaluation": [d.name for d in evaluation], "split": split,
         "seed": seed, "rows": [asdict(r) | {"figure": _figure_text(r)} for r in rows]}, indent=2) + "\n")
    print(text)
    return rows
