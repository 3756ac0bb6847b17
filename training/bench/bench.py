"""Benchmarks that print tables: attitude accuracy on BROAD against open filters, and speed.

BROAD data: D. Laidig, M. Caruso, A. Cereatti, T. Seel, "BROAD — A Benchmark for Robust Inertial
Orientation Estimation", Data 6(7), 2021, doi:10.3390/data6070072 (CC-BY-4.0).

Every filter runs causally on the raw recording of one trial; none sees the reference. Their
quaternions are converted to body -> magnetic NED and scored with BROAD's error metric
(q_err = q_est ⊗ q_ref⁻¹: total 2·acos|w|, heading 2·atan|z/w|, inclination 2·acos√(w²+z²);
RMSE in degrees over eval_mask samples with a finite reference, no heading-offset alignment).
"""
from __future__ import annotations

import csv
import time
from pathlib import Path

import numpy as np

from contract import layout
from training.data.dataset import ImuData
from training.data.io import read_imu_csv
from training.data.reference import reference_quaternion_magnetic
from training.evaluate import tilt_heading_errors
from training.frames import quat_multiply

BROAD_CITATION = ("D. Laidig, M. Caruso, A. Cereatti, T. Seel, BROAD — A Benchmark for Robust Inertial "
                  "Orientation Estimation, Data 6(7), 2021, doi:10.3390/data6070072, CC-BY-4.0")
#: Trial-number ranges of BROAD's groups (inclusive).
GROUPS = {"undisturbed": (1, 21), "disturbed": (24, 35), "all": (1, 39)}
#: Settings of ImuFusion on BROAD: one set for every trial; field_norm/field_dip come from the sidecar.
BROAD_SETTINGS = {"attitude_mode": 1.0, "rest_gyro_threshold": 0.035}
#: Madgwick gain β [rad/s] prescribed for the comparison.
MADGWICK_BETA = 0.12
#: Trials also run through the FMU with fmpy to show that it equals the batch library.
FMU_TRIALS = 1
_Q_COLS = [layout.OUTPUTS.index(n) for n in ("q_w", "q_x", "q_y", "q_z")]
#: body -> ENU to body -> NED: 180° about (x + y)/√2 (x_ned = y_enu, y_ned = x_enu, z_ned = -z_enu).
_ENU_TO_NED = np.array([0.0, np.sqrt(0.5), np.sqrt(0.5), 0.0])


def broad_dir(data_dir: str | Path | None = None) -> Path:
    """Folder of the BROAD trials: data_dir, or <repo parent>/shared/data/broad."""
    if data_dir is not None:
        return Path(data_dir)
    return Path(__file__).resolve().parents[3] / "shared" / "data" / "broad"


def trial_paths(trials: list[str] | None, data_dir: str | Path | None = None) -> list[Path]:
    """Recordings of the trials whose name starts with one of `trials` (all when None)."""
    folder = broad_dir(data_dir)
    paths = sorted(folder.glob("*.csv.gz"))
    if not paths:
        raise FileNotFoundError(f"no BROAD trials (*.csv.gz) in {folder}")
    if trials:
        paths = [p for p in paths if any(p.name.startswith(t) for t in trials)]
        if not paths:
            raise FileNotFoundError(f"no BROAD trial in {folder} matches {trials}")
    return paths


def trial_number(data: ImuData) -> int:
    """BROAD trial number from the recording name ('28_disturbed_...' -> 28)."""
    return int(data.name.split("_", 1)[0])


def imufusion_settings(data: ImuData, overrides: dict | None = None) -> list[float]:
    """Flat settings array for one trial: BROAD_SETTINGS, the sidecar's field norm and dip, overrides."""
    ef = data.meta.get("earth_field") or {}
    values = {"field_norm": float(ef["norm_ut"]), "field_dip": float(np.deg2rad(ef["dip_deg"])),
              **BROAD_SETTINGS, **(overrides or {})}
    return layout.settings_array(values)


def _inputs(data: ImuData) -> np.ndarray:
    """(N, len(INPUTS)) runtime inputs of a BROAD trial: its triads and temperature, no auxiliary
    signals (benchmarks/bench_magpf.py runs the chain on the same inputs)."""
    return data.inputs()


def run_imufusion(data: ImuData, overrides: dict | None = None) -> np.ndarray:
    """(N, 4) body -> magnetic NED quaternion of the ImuFusion batch runtime (identity coefficients).
    overrides: settings over BROAD_SETTINGS."""
    from training.runtime import run_batch
    out = run_batch(layout.identity_coefficients(), imufusion_settings(data, dict(overrides or {})),
                    data.t - data.t[0], _inputs(data))
    return out[:, _Q_COLS]


def _nwu_to_ned(q: np.ndarray) -> np.ndarray:
    """(N, 4) body -> NWU quaternions to body -> NED: 180° about x (y_ned = -y_nwu, z_ned = -z_nwu)."""
    return quat_multiply(np.tile([0.0, 1.0, 0.0, 0.0], (len(q), 1)), q)


def run_vqf(data: ImuData) -> np.ndarray:
    """(N, 4) body -> NED quaternion of VQF 9D, default parameters, causal (offline=False)."""
    from vqf import VQF
    ts = float(np.median(np.diff(data.t)))
    filt = VQF(ts)
    out = filt.updateBatch(np.ascontiguousarray(data.gyr), np.ascontiguousarray(data.acc),
                           np.ascontiguousarray(data.mag))
    return quat_multiply(np.tile(_ENU_TO_NED, (len(data), 1)), out["quat9D"])


def run_xio_fusion(data: ImuData) -> np.ndarray:
    """(N, 4) body -> NED quaternion of x-io Fusion (package imufusion), README-recommended settings:
    gain 0.5, gyroscope range 2000 °/s, acceleration and magnetic rejection 10°, recovery 5 s,
    gyroscope bias compensation (Bias, default settings)."""
    import imufusion
    rate = float(data.meta.get("rate_hz") or 1.0 / np.median(np.diff(data.t)))
    bias = imufusion.Bias()
    bias.set_settings(imufusion.BiasSettings(rate))
    ahrs = imufusion.Ahrs()
    ahrs.set_settings(imufusion.AhrsSettings(rate, imufusion.CONVENTION_NWU, 0.5, 2000.0, 10.0, 10.0, 5.0))
    gyr = np.rad2deg(data.gyr)
    acc = data.acc / 9.80665
    q = np.empty((len(data), 4))
    for k in range(len(data)):
        ahrs.update(bias.update(gyr[k]), acc[k], data.mag[k])
        q[k] = ahrs.get_quaternion()
    return _nwu_to_ned(q)


def run_madgwick(data: ImuData) -> np.ndarray:
    """(N, 4) body -> NED quaternion of Madgwick's MARG filter (package ahrs), β = MADGWICK_BETA."""
    from ahrs.filters import Madgwick
    rate = float(data.meta.get("rate_hz") or 1.0 / np.median(np.diff(data.t)))
    q = Madgwick(gyr=data.gyr, acc=data.acc, mag=data.mag, frequency=rate, gain=MADGWICK_BETA).Q
    return _nwu_to_ned(q)


#: Filters of the comparison: name -> function (ImuData -> (N, 4) body -> NED quaternion).
FILTERS = {"ImuFusion": run_imufusion, "VQF 9D": run_vqf, "x-io Fusion": run_xio_fusion,
           "Madgwick": run_madgwick}


def broad_errors(q_est: np.ndarray, data: ImuData) -> dict[str, float]:
    """BROAD RMSE [°] of total, heading and inclination error over eval_mask samples with a finite reference."""
    out = np.zeros((len(data), len(layout.OUTPUTS)))
    out[:, _Q_COLS] = q_est
    tilt, heading = tilt_heading_errors(out, data).T
    q_ref_inv = reference_quaternion_magnetic(data) * np.array([1.0, -1.0, -1.0, -1.0])
    total = 2.0 * np.arccos(np.clip(np.abs(quat_multiply(q_est, q_ref_inv)[:, 0]), 0.0, 1.0))
    mask = np.isfinite(data.ref_q).all(axis=1)
    if data.eval_mask is not None:
        mask &= data.eval_mask.astype(bool)

    def rmse(e):
        return float(np.rad2deg(np.sqrt(np.mean(e[mask] ** 2))))
    return {"total": rmse(total), "heading": rmse(heading), "inclination": rmse(tilt)}


#: The setting that selects the Euler fusion's additions (a sum of the bits below).
EULER_SWITCH = "euler_additions"
#: The project's additions to the Euler fusion in the order they are ablated (the first three
#: came with the first runtime, the last three with issue 15's recovery from transients):
#: row label -> its bit of euler_additions (sources/ImuAttitude.h ImuEulerAddition; their sum is
#: training.runtime.euler_all_additions(), checked by tests/test_euler_additions.py).
EULER_ADDITIONS = {
    "trapezoidal propagation": 1,
    "floor angle_noise on R": 2,
    "R terms for the norms of f and m off g and field_norm": 4,
    "integration-error bound in P": 8,
    "tilt variance in yaw's R": 16,
    "restart after a transient = method + project additions (attitude_mode 0)": 32,
}


def _euler_ablation() -> dict[str, dict[str, float]]:
    """The Euler fusion without rest bias in the source's pure form (issue 2), then with each of
    EULER_ADDITIONS added cumulatively; the last row is today's attitude_mode 0 with instantaneous rate
    samples (gyro_hold 0, so that the trapezoid addition acts)."""
    euler = {"attitude_mode": 0.0, "rest_gyro_threshold": 0.0, "gyro_hold": 0.0}
    rows = {"Euler adaptive gains, the source's form (issue 2), no bias": {**euler, EULER_SWITCH: 0}}
    bits = 0
    for label, bit in EULER_ADDITIONS.items():
        bits |= bit
        rows[f"  + {label}, no bias"] = {**euler, EULER_SWITCH: bits}
    return rows


#: Ablation of the attitude chain on BROAD: name -> settings overrides of BROAD_SETTINGS.
ABLATION = {
    **_euler_ablation(),
    "Euler adaptive gains + rest bias": {"attitude_mode": 0.0, "rest_gyro_threshold": 0.035},
    "quaternion, no rest bias, no rejection": {"rest_gyro_threshold": 0.0, "mag_reject_time": 0.0},
    "quaternion + rest bias, no rejection": {"mag_reject_time": 0.0},
    "quaternion + rest bias + field rejection, trapezoid (gyro_hold 0)": {"gyro_hold": 0.0},
    "quaternion + rest bias + field rejection (BROAD set)": {},
    "  same, tau_acc 1.5 s": {"tau_acc": 1.5},
    "  same, tau_mag 20 s": {"tau_mag": 20.0},
}


def _group_of(number: int) -> list[str]:
    """Groups a BROAD trial number belongs to."""
    return [g for g, (lo, hi) in GROUPS.items() if lo <= number <= hi]


def _group_means(rows: list[dict], key: str) -> dict[str, dict[str, float]]:
    """Mean over trials of each metric, per (key value, group): {name: {group: {metric: mean}}}."""
    out: dict = {}
    for name in dict.fromkeys(r[key] for r in rows):
        out[name] = {}
        for group in GROUPS:
            sel = [r for r in rows if r[key] == name and group in _group_of(r["trial"])]
            if sel:
                out[name][group] = {m: float(np.mean([r[m] for r in sel])) for m in ("total", "heading", "inclination")}
                out[name][group]["n_trials"] = len(sel)
    return out


def _fmu_identity(datas: list[ImuData], work: Path) -> dict:
    """Run the first FMU_TRIALS trials through the FMU (fmpy) and compare with the batch library."""
    from fmu.cosim import run_fmu
    from training.fmu_build import build_fmu
    fmu_path = build_fmu(np.array(layout.identity_coefficients()), {}, work / "ImuFusion.fmu")
    result = {}
    for data in datas[:FMU_TRIALS]:
        params = dict(zip((n for n, _ in layout.SETTINGS), imufusion_settings(data)))
        params["enable_thermal"] = bool(params["enable_thermal"])
        out = run_fmu(fmu_path, data.t - data.t[0], _inputs(data), params)
        diff = np.abs(out[:, _Q_COLS] - run_imufusion(data))
        result[data.name] = {"samples": len(data), "max_abs_q_difference": float(np.nanmax(diff))}
    return result


def _markdown(groups: dict, rows: list[dict], ablation: dict, fmu: dict) -> str:
    """The Markdown report of bench_broad."""
    lines = [f"BROAD data: {BROAD_CITATION}.", "",
             "Mean over trials of the per-trial RMSE [°] (total / heading / inclination):", "",
             "| filter | " + " | ".join(GROUPS) + " |", "|---|" + "---|" * len(GROUPS)]
    for name, g in groups.items():
        cells = [f"{g[k]['total']:.2f} / {g[k]['heading']:.2f} / {g[k]['inclination']:.2f} (n={g[k]['n_trials']})"
                 if k in g else "–" for k in GROUPS]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    lines += ["", "Total RMSE [°] per trial:", "", "| trial | " + " | ".join(FILTERS) + " |",
              "|---|" + "---|" * len(FILTERS)]
    for trial in dict.fromkeys(r["name"] for r in rows):
        vals = {r["filter"]: r["total"] for r in rows if r["name"] == trial}
        lines.append(f"| {trial} | " + " | ".join(f"{vals[f]:.2f}" for f in FILTERS) + " |")
    lines += ["", "Ablation of the ImuFusion attitude chain (mean total RMSE [°]):", "",
              "| variant | " + " | ".join(GROUPS) + " |", "|---|" + "---|" * len(GROUPS)]
    for name, g in ablation.items():
        lines.append(f"| {name} | " + " | ".join(f"{g[k]['total']:.2f}" if k in g else "–" for k in GROUPS) + " |")
    lines += ["", "FMU (fmpy) against the batch library, max |Δq|:", ""]
    lines += [f"- {name}: {v['max_abs_q_difference']:.3g} over {v['samples']} samples" for name, v in fmu.items()]
    return "\n".join(lines) + "\n"


def _plot(rows: list[dict], out_dir: Path) -> Path:
    """Bar chart of the total RMSE per trial and filter -> broad_total_rmse.png."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    trials = list(dict.fromkeys(r["name"] for r in rows))
    fig, ax = plt.subplots(figsize=(12, 4.5))
    width = 0.8 / len(FILTERS)
    for i, name in enumerate(FILTERS):
        vals = [next(r["total"] for r in rows if r["name"] == t and r["filter"] == name) for t in trials]
        ax.bar(np.arange(len(trials)) + (i - (len(FILTERS) - 1) / 2) * width, vals, width, label=name)
    ax.set_xticks(np.arange(len(trials)), [t.split("_", 1)[0] for t in trials])
    ax.set_xlabel("BROAD trial")
    ax.set_ylabel("total RMSE [°]")
    ax.set_yscale("log")
    ax.legend()
    ax.set_title("Attitude error on BROAD (Laidig et al. 2021, CC-BY-4.0)")
    fig.tight_layout()
    path = out_dir / "broad_total_rmse.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def bench_broad(trials: list[str] | None, out_dir: str | Path, data_dir: str | Path | None = None,
                samples: int | None = None) -> dict:
    """Run ImuFusion (batch runtime, BROAD_SETTINGS), VQF 9D, x-io Fusion and Madgwick on BROAD trials.

    trials: name prefixes ('01', '28_disturbed', ...) or None for every trial in the folder;
    data_dir: folder of the imu-csv/1 trials (default <repo parent>/shared/data/broad); samples: use
    only the first `samples` samples of each trial (all when None: the benchmark). Writes
    broad.md, broad.csv and broad_total_rmse.png to out_dir and prints the Markdown table.
    Returns {"trials": [per-trial rows], "groups": {filter: {group: {total, heading, inclination,
    n_trials}}}, "ablation": {variant: {group: ...}}, "fmu": {trial: max |Δq|}, "files": [...]}.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    datas = [read_imu_csv(p) for p in trial_paths(trials, data_dir)]
    if samples is not None:
        datas = [d.slice(slice(0, samples)) for d in datas]
    rows, ablation_rows = [], []
    for data in datas:
        for name, run in FILTERS.items():
            rows.append({"name": data.name, "trial": trial_number(data), "filter": name,
                         **broad_errors(run(data), data)})
        for name, overrides in ABLATION.items():
            ablation_rows.append({"name": data.name, "trial": trial_number(data), "variant": name,
                                  **broad_errors(run_imufusion(data, overrides), data)})
    groups = _group_means(rows, "filter")
    ablation = _group_means(ablation_rows, "variant")
    fmu = _fmu_identity(datas, out_dir)
    (out_dir / "ImuFusion.fmu").unlink(missing_ok=True)
    text = _markdown(groups, rows, ablation, fmu)
    (out_dir / "broad.md").write_text(text)
    with open(out_dir / "broad.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=["name", "trial", "filter", "total", "heading", "inclination"])
        writer.writeheader()
        writer.writerows(rows)
    plot = _plot(rows, out_dir)
    print(text)
    return {"trials": rows, "groups": groups, "ablation": ablation, "fmu": fmu,
            "files": [str(out_dir / "broad.md"), str(out_dir / "broad.csv"), str(plot)]}


def _best_times(fns: dict, repeats: int = 3) -> dict[str, float]:
    """Shortest wall time [s] of `repeats` calls of each fn, the calls interleaved (a, b, a, b, …)
    so that a change of the machine's load hits every fn alike."""
    best = dict.fromkeys(fns, float("inf"))
    for _ in range(repeats):
        for name, fn in fns.items():
            start = time.perf_counter()
            fn()
            best[name] = min(best[name], time.perf_counter() - start)
    return best


def _stage_switches() -> list[str]:
    """The settings that switch one stage of the chain on (1) or off (0): every enable_* setting."""
    return [n for n, _ in layout.SETTINGS if n.startswith("enable_")]


#: Stage rows of the speed table beyond the enable_* switches: name -> settings of the "on" run
#: (the "off" run is the same with enable_pf 0). At train's settings the particle filter holds the
#: trained calibration until it declares a change (pf_hold_prior 1), so on an undisturbed recording
#: it mostly runs its change test; this row times it adapting from the first sample.
STAGE_VARIANTS = {"enable_pf, adapting from the start (pf_hold_prior 0)": {"enable_pf": 1.0, "pf_hold_prior": 0.0}}


def _stage_runs() -> dict[str, tuple[dict, dict]]:
    """Stage rows of the speed table: name -> (overrides with the stage on, with it off)."""
    runs = {stage: ({stage: 1.0}, {stage: 0.0}) for stage in _stage_switches()}
    runs.update({name: (on, {**on, "enable_pf": 0.0}) for name, on in STAGE_VARIANTS.items()})
    return runs


def _speed_model(model: str | Path | None, scenario_dir: Path, calibration: str):
    """(artefact, training wall time [s] or None, training samples or None): the artefact at
    `model`, else training.train.train on the simulated calibration set (seed 0), timed. The
    artefact must carry ELM and PSO-BP coefficients: their stage-on timings need them."""
    from training.artefact import load_artefact
    from contract.errors import ModelError
    from training.simulator import load_scenario, simulate
    from training.train import train
    if model is not None:
        artefact, train_s, samples = load_artefact(model), None, None
    else:
        data = simulate(load_scenario(scenario_dir / calibration), seed=0)
        start = time.perf_counter()
        artefact = train([data], seed=0, progress=False)
        train_s, samples = time.perf_counter() - start, len(data)
    missing = [name for name in ("elm", "psobp") if getattr(artefact, name) is None]
    if missing:
        raise ModelError(f"bench speed: {model or calibration}: the model has no {' and no '.join(missing)} "
                         "coefficients; timing a stage switched on needs them")
    return artefact, train_s, samples


def bench_speed(out_dir: str | Path, model: str | Path | None = None, samples: int | None = None,
                fmu_samples: int = 20000) -> dict:
    """Per-sample cost of the runtime [µs/sample] and VQF's batch cost in the same run: each stage
    (every enable_* setting) switched on and off on a trained model (ELM and PSO-BP coefficients,
    train's settings, the particle filter at train's noise settings), the whole chain with identity
    coefficients at the defaults and at the BROAD set; FMU doStep cost through fmpy; memory of the
    runtime structs; training time on the simulated calibration set.

    model: a model.json to time instead of training one (then no training time is reported);
    samples: use only the first `samples` samples of the recording (all when None); fmu_samples:
    samples stepped through the FMU. Writes speed.md to out_dir, prints it and returns the numbers.
    """
    from vqf import VQF
    from fmu.cosim import run_fmu
    from training.artefact import coefficients_array, settings_dict
    from training.fmu_build import build_fmu
    from training.main_job import DEFAULT_CALIBRATION, SCENARIO_DIR
    from training.runtime import run_batch, runtime_sizes
    from training.simulator import load_scenario, simulate
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    artefact, train_s, train_samples = _speed_model(model, SCENARIO_DIR, DEFAULT_CALIBRATION)
    data = simulate(load_scenario(SCENARIO_DIR / "eval_handheld.toml"), seed=1)
    if samples is not None:
        data = data.slice(slice(0, samples))
    t, x, n = data.t - data.t[0], _inputs(data), len(data)
    identity, trained = layout.identity_coefficients(), coefficients_array(artefact)
    trained_settings = settings_dict(artefact)

    def timed(coefficients, settings: dict):
        array = layout.settings_array(settings)
        return lambda: run_batch(coefficients, array, t, x)
    gyr, acc, mag = (np.ascontiguousarray(a) for a in (data.gyr, data.acc, data.mag))
    ts = float(np.median(np.diff(data.t)))
    runs = {"VQF": lambda: VQF(ts).updateBatch(gyr, acc, mag)}
    stages = _stage_runs()
    for stage, (on, off) in stages.items():
        runs[(stage, "on")] = timed(trained, {**trained_settings, **on})
        runs[(stage, "off")] = timed(trained, {**trained_settings, **off})
    chain = {"whole chain, identity coefficients (defaults)": {},
             "identity coefficients, BROAD set (attitude_mode 1, rest bias)": BROAD_SETTINGS,
             "identity coefficients, BROAD set, rest bias off": {**BROAD_SETTINGS, "rest_gyro_threshold": 0.0},
             "identity coefficients, BROAD set, field rejection off": {**BROAD_SETTINGS, "mag_reject_time": 0.0}}
    runs.update({name: timed(identity, overrides) for name, overrides in chain.items()})
    us = {key: 1e6 * s / n for key, s in _best_times(runs).items()}
    fmu_path = build_fmu(np.array(identity), {}, out_dir / "ImuFusion.fmu")
    m = min(n, fmu_samples)
    fmu_us = 1e6 * _best_times({"fmu": lambda: run_fmu(fmu_path, t[:m], x[:m])}, repeats=1)["fmu"] / m
    fmu_path.unlink()
    result = {"samples": n, "vqf_batch_us": us["VQF"],
              "stages_us": {stage: {"on": us[(stage, "on")], "off": us[(stage, "off")]} for stage in stages},
              "trained_settings_enabled": [s for s in _stage_switches() if trained_settings[s]],
              "runtime_us": {name: us[name] for name in chain},
              "fmu_step_us": fmu_us, "sizes_bytes": runtime_sizes(),
              "train_s": train_s, "train_samples": train_samples}
    text = _speed_markdown(result)
    (out_dir / "speed.md").write_text(text)
    print(text)
    return result


def _speed_markdown(r: dict) -> str:
    """The Markdown report of bench_speed."""
    vqf = r["vqf_batch_us"]
    lines = [f"Per-sample cost on the simulated handheld scenario ({r['samples']} samples, best of 3, every row "
             "and VQF timed in the same run, interleaved):", "",
             "Each stage switched on and off on the trained model (its ELM and PSO-BP coefficients, train's "
             f"settings otherwise: {', '.join(r['trained_settings_enabled']) or 'no stage'} on as trained; "
             "the particle filter at train's noise settings):", "",
             "| stage | on [µs/sample] | off [µs/sample] | on − off [µs/sample] | on × VQF | off × VQF |",
             "|---|---|---|---|---|---|"]
    for stage, v in r["stages_us"].items():
        lines.append(f"| {stage} | {v['on']:.3f} | {v['off']:.3f} | {v['on'] - v['off']:+.3f} | "
                     f"{v['on'] / vqf:.2f} | {v['off'] / vqf:.2f} |")
    lines += ["", "| what | µs/sample | × VQF batch |", "|---|---|---|"]
    lines += [f"| ImuFusion runtime (batch), {name} | {us:.3f} | {us / vqf:.2f} |" for name, us in r["runtime_us"].items()]
    lines += [f"| VQF 9D (vqf.VQF.updateBatch) | {vqf:.3f} | 1.00 |",
              f"| ImuFusion FMU doStep through fmpy (set inputs, doStep, get outputs) | {r['fmu_step_us']:.1f} | "
              f"{r['fmu_step_us'] / vqf:.0f} |", "",
              "Memory (sizeof, from ImuBatchSizes() in the runtime library):", ""]
    lines += [f"- {k}: {v} bytes" for k, v in r["sizes_bytes"].items()]
    if r["train_s"] is not None:
        lines += ["", f"Training (training.train.train on the simulated {r['train_samples']}-sample calibration set, "
                      f"seed 0): {r['train_s']:.1f} s"]
    return "\n".join(lines) + "\n"
