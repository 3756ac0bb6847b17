"""Benchmark of the magnetometer particle filter (docs/magpf.md): prints Markdown tables.

    python benchmarks/bench_magpf.py [--seeds 20] [--no-broad] [--no-sim] [--only-train] [--sensitivity]
                                     [--trials 33 35]

1. Simulated tumbling (60 s at 100 Hz, |h_0| = 60 µT, h_p = [30, 40, 20] µT, soft iron up to
   0.05, uniform + Student-t noise), wide zero prior (magpf.zero_prior): hard-iron error (largest
   axis) at the end and RMS of |h_c| − |h_0| over the last 10 s, for the product's filter
   (Rao-Blackwellised, defaults), the same without Metropolis moves, the 9-state filter with
   splitting and restoration network as its source describes it (magpf.SOURCE_METHOD) and with
   the project's additions (magpf.METHOD_WITH_ADDITIONS), the latter's plain SIR baseline (steps
   5–6 off) and the batch ellipsoid fit (the additions one at a time: benchmarks/magpf_ablation.py); mean and worst over the seeds. The norm error is evaluated on
   the noise-free distorted field (the calibration's error) and on the measured field.
2. Hard-iron jump of 20 µT at 30 s: the same figures 30 s after the jump, plus the filter that
   holds a trained calibration (the truth) until it declares the change.
3. BROAD trials (Laidig et al., Data 6(7) 2021, CC-BY-4.0): spread 100·std/mean of |h_c| over
   eval_mask, raw and filtered (‖h_0‖ from the sidecar), and the heading RMSE of the whole
   runtime (training.bench.bench.run_imufusion, BROAD attitude set) without the filter, with it
   (holding the calibration until a change) and with it adapting from the start.
4. Settings derived from the calibration (train): the chain applies the calibration that
   training on BROAD 01 + 02 gives (stand-in for the self-calibration: batch ellipsoid fit of the
   raw field of 01 + 02 to their sample-weighted sidecar norm, `train_calibration`), attitude_mode 1,
   rest_gyro_threshold 0.035, field norm/dip from each trial's sidecar; the filter is switched on with
   `enable_pf = 1` and the settings `training.models.pf_settings.pf_settings_from_calibration` derives from
   the calibrated 01 + 02 field — nothing else. Norm spread, heading RMSE and declared changes per
   trial without the filter, with the derived settings and, for comparison, with the hand-set
   BROAD_PF on the same chain. `--sensitivity` adds the table of each rule constant varied ±50 %.
       python benchmarks/bench_magpf.py --only-train [--sensitivity]
The cost of the filter: benchmarks/pf_cost.py. --trials limits tables 3 and 4 to those BROAD trials.
"""
from __future__ import annotations

import argparse
import copy
import glob
import sys
from pathlib import Path

import numpy as np

from contract import layout
from training import runtime
from training.bench import bench
from training.data.io import read_imu_csv
from training.models import magpf, pf_settings
from training.models.ellipsoid import apply_ellipsoid, fit_ellipsoid
from training.models.thermal import ThermalModel

BROAD = Path(__file__).resolve().parents[2] / "shared" / "data" / "broad"
TAIL_S = 10.0


def clean_distorted(d: magpf.TumblingData) -> np.ndarray:
    """Noise-free distorted field (N, 3) µT of a simulated record."""
    inv = np.linalg.inv(np.eye(3) + magpf.soft_matrix(d.soft_iron[0]))
    return d.truth @ inv.T + d.hard_iron


def figures(d, est_hp, compensate, end: int, tail_s: float = TAIL_S) -> tuple[float, float, float]:
    """(hard-iron max-axis error at `end` [µT], norm RMS % clean, norm RMS % measured) over the
    tail_s seconds before `end`."""
    tail = slice(end - int(tail_s * d.rate_hz), end)
    herr = float(np.abs(est_hp - d.hard_iron[end - 1]).max())
    out = []
    for field in (clean_distorted(d)[tail], d.mag[tail]):
        n = np.linalg.norm(compensate(field, tail), axis=1)
        out.append(100.0 * float(np.sqrt(np.mean((n - d.field_norm_ut) ** 2))) / d.field_norm_ut)
    return herr, out[0], out[1]


def run_filter(d, s, end, tail_s: float = TAIL_S):
    """`figures` of the C filter with settings s over the record d."""
    r = magpf.run_c(d.mag, s)
    est = np.column_stack([r.hard_iron, r.soft_iron])
    return figures(d, r.hard_iron[end - 1],
                   lambda f, tail: magpf.apply(est[tail], f), end, tail_s)


def run_ellipsoid(d, end, tail_s: float = TAIL_S):
    """`figures` of the batch ellipsoid fit of d's first `end` samples."""
    fit = fit_ellipsoid(d.mag[:end], d.field_norm_ut)
    return figures(d, fit.offset, lambda f, tail: apply_ellipsoid(fit, f), end, tail_s)


def after(d: magpf.TumblingData, start: int) -> magpf.TumblingData:
    """The record d from sample `start` on (the ellipsoid is fitted after a jump only)."""
    return magpf.TumblingData(d.mag[start:], d.truth[start:], d.hard_iron[start:], d.soft_iron[start:],
                              d.rate_hz, d.field_norm_ut)


def table(title: str, rows: dict) -> None:
    print(f"\n### {title}\n")
    print("| method | hard-iron err mean / worst [µT] | norm RMS clean mean / worst [%] "
          "| norm RMS measured mean / worst [%] |")
    print("|---|---|---|---|")
    for name, values in rows.items():
        a = np.array(values)
        print(f"| {name} | {a[:, 0].mean():.3f} / {a[:, 0].max():.3f} | "
              f"{a[:, 1].mean():.3f} / {a[:, 1].max():.3f} | {a[:, 2].mean():.3f} / {a[:, 2].max():.3f} |")


#: Filter variants of the simulated tables: label -> settings overrides (zero prior added).
SIM_VARIANTS = {
    "particle filter, Rao-Blackwellised (defaults)": {},
    "  same, Metropolis moves off": {"enable_move": 0},
    "the source's method (9-state, splitting + network; issue 3 steps 1–8, no additions)": magpf.SOURCE_METHOD,
    "method + project additions (9-state, splitting + network, magpf.METHOD_WITH_ADDITIONS)":
        magpf.METHOD_WITH_ADDITIONS,
    "plain SIR with the additions (9-state, steps 5–6 off)": {**magpf.METHOD_WITH_ADDITIONS, "enable_splitting": 0},
}


HELD = "particle filter, trained calibration (the truth, 0.5 µT / 0.005) held until the change"


def simulated(seeds: int) -> None:
    for title, kwargs, end_s in (("Tumbling, zero prior, end of 60 s", {}, 60.0),
                                 ("Hard-iron jump of 20 µT at 30 s, 30 s later", {
                                     "duration_s": 60.0, "jump_at_s": 30.0}, 60.0)):
        rows = {name: [] for name in SIM_VARIANTS}
        if "jump_at_s" in kwargs:
            rows[HELD] = []
        rows["ellipsoid fit (batch)"] = []
        for seed in range(seeds):
            d = magpf.simulate_tumbling(seed, **kwargs)
            end = int(end_s * d.rate_hz)
            wide = magpf.zero_prior(60.0)
            for name, over in SIM_VARIANTS.items():
                rows[name].append(run_filter(d, magpf.settings(60.0, pf_seed=seed, **{**wide, **over}), end))
            if HELD in rows:
                rows[HELD].append(run_filter(d, magpf.settings(60.0, pf_seed=seed, **magpf.trained_prior(d.hard_iron[0], d.soft_iron[0])), end))
            start = int(kwargs.get("jump_at_s", 0.0) * d.rate_hz)
            rows["ellipsoid fit (batch)"].append(run_ellipsoid(after(d, start), end - start))
        table(f"{title} ({seeds} seeds)", rows)


#: FMU settings of the filter on BROAD. The data set is calibrated, so the prior is the trained
#: calibration (tight around zero: 0.5 µT, 0.005), held until a change is declared (default
#: pf_hold_prior 1); field noise 0.8 µT per axis (the issue's 1.6 % norm noise floor of ~44 µT);
#: at 285.7 Hz the field direction's noise is ~1.4° per sample, so a 6° rotation gate keeps a
#: sensor at rest from feeding noise into the sums; an update every 4th sample and a 15 µT
#: hard-iron spread after a change (an attached magnet's offset is 5-30 µT); the attitude filter
#: ignores the field while the hard-iron cloud is wider than 1 µT (default pf_settle_spread).
BROAD_PF = {"enable_pf": 1.0, "pf_measurement_noise": 0.8, "pf_prior_spread_hard": 0.5,
            "pf_prior_spread_soft": 0.005, "pf_min_rotation": float(np.deg2rad(6.0)),
            "pf_decimation": 4.0, "pf_change_spread_hard": 15.0}
#: BROAD_PF without the switch: the standalone filter's settings (training.models.magpf), for the change count.
BROAD_MAGPF = {name: value for name, value in BROAD_PF.items() if name in magpf.FMU_SETTINGS}
FIELD = [layout.OUTPUTS.index(n) for n in ("field_x", "field_y", "field_z")]
QUATERNION = [layout.OUTPUTS.index(n) for n in ("q_w", "q_x", "q_y", "q_z")]
MAGNET_TRIALS = ("32", "33", "35")


def _run_chain(d, overrides: dict, coefficients=None) -> np.ndarray:
    """All runtime outputs (N, len(OUTPUTS)) for a BROAD recording with the BROAD attitude set
    (coefficients: a trained coefficient array; identity when None)."""
    coefficients = layout.identity_coefficients() if coefficients is None else coefficients
    return runtime.run_batch(coefficients, bench.imufusion_settings(d, overrides),
                             d.t - d.t[0], bench._inputs(d))


def _spread(field: np.ndarray, mask: np.ndarray) -> float:
    norm = np.linalg.norm(field[mask], axis=1)
    return 100.0 * float(np.std(norm) / np.mean(norm))


def broad(trials: list[str] | None = None) -> None:
    print("\n### BROAD: spread 100·std/mean of |h_c| [%] and heading RMSE [°] over eval_mask, "
          f"whole runtime (BROAD attitude set), filter settings {BROAD_PF}\n")
    print("| trial | spread raw | spread with filter | heading without filter | heading with filter | "
          "change | changes declared | heading, filter adapting from the start (pf_hold_prior 0) "
          "| heading, batch ellipsoid fitted on the eval phase |")
    print("|---|---|---|---|---|---|---|---|---|")
    for path in sorted(glob.glob(str(BROAD / "*.csv.gz"))):
        name = Path(path).name.split("_")[0]
        if not (name <= "18" or name in MAGNET_TRIALS) or (trials and name not in trials):
            continue
        d = read_imu_csv(path)
        m = d.eval_mask.astype(bool)
        without, with_pf = _run_chain(d, {}), _run_chain(d, BROAD_PF)
        adapting = _run_chain(d, {**BROAD_PF, "pf_hold_prior": 0.0})
        h0, h1, h2 = (bench.broad_errors(out[:, QUATERNION], d)["heading"] for out in (without, with_pf, adapting))
        changes = magpf.run_c(d.mag, magpf.settings(d.field_norm_ut, **BROAD_MAGPF)).changes
        print(f"| {Path(path).name[:-7]} | {_spread(d.mag, m):.2f} | {_spread(with_pf[:, FIELD], m):.2f} | "
              f"{h0:.2f} | {h1:.2f} | {h1 - h0:+.2f} | {int(changes[-1])} | {h2:.2f} ({h2 - h0:+.2f}) | "
              f"{_ellipsoid_heading(d, m):.2f} |", flush=True)


# ----------------------------------------------------------------------------- settings from train

#: Trials `train` calibrates the magnetometer on (the rest are evaluation trials).
TRAIN_TRIALS = ("01", "02")
#: Attitude settings of the derived-settings table (becoming the FMU defaults).
TRAIN_ATTITUDE = {"attitude_mode": 1.0, "rest_gyro_threshold": 0.035}
UNDISTURBED_TRIALS = ("01", "02", "04", "05", "06", "08", "09", "10", "11", "14", "15", "18")
#: Rule constants of training.models.pf_settings varied by ±50 % in the sensitivity table.
SENSITIVITY = (("update_interval_s", pf_settings.UPDATE_INTERVAL_S, "decimation: update interval T_u [s]"),
               ("gate_sigmas", pf_settings.GATE_SIGMAS, "rotation gate k [σ]"),
               ("change_margin", pf_settings.CHANGE_MARGIN, "change spread κ"),
               ("settle_samples", pf_settings.SETTLE_SAMPLES, "settle floor n_s [samples]"))


def _trial(number: str):
    return read_imu_csv(sorted(glob.glob(str(BROAD / f"{number}_*.csv.gz")))[0])


def train_calibration(trials=TRAIN_TRIALS):
    """What `train` gives on the training trials, standing in for the self-calibration: a batch
    ellipsoid fit of their raw field to the sample-weighted mean of their sidecar norms.
    Returns (fit, field_norm [µT], coefficients for the runtime, calibrated field (N, 3) µT, t (N,) s):
    the magnetometer block is x_c = M (x − offset), the other triads identity."""
    data = [_trial(n) for n in trials]
    norm = float(sum(len(d) * d.meta["earth_field"]["norm_ut"] for d in data) / sum(len(d) for d in data))
    fit = fit_ellipsoid(np.vstack([d.mag for d in data]), norm)
    mag = ThermalModel(True, 25.0, 1.0, 0, A=fit.matrix, g=np.zeros((3, 0)), b=fit.offset.reshape(3, 1))
    identity = ThermalModel.identity().to_block()
    coefficients = layout.pack_coefficients([identity, identity, mag.to_block()])
    return (fit, norm, coefficients, np.vstack([apply_ellipsoid(fit, d.mag) for d in data]),
            np.concatenate([d.t for d in data]))


def _evaluate(d, coefficients, settings: dict) -> tuple[float, float]:
    """(norm spread [%], heading RMSE [°]) of the chain with the BROAD attitude set + settings."""
    out = _run_chain(d, {**TRAIN_ATTITUDE, **settings}, coefficients)
    return _spread(out[:, FIELD], d.eval_mask.astype(bool)), bench.broad_errors(out[:, QUATERNION], d)["heading"]


def _figures(trials: dict, coefficients, settings: dict) -> dict:
    """trial -> (spread [%], heading [°]) for the derived/hand-set settings (empty: filter off)."""
    return {n: _evaluate(d, coefficients, settings) for n, d in trials.items()}


def _summary(off: dict, on: dict) -> str:
    mag = " | ".join(f"{on[n][0]:.2f} / {on[n][1]:.2f}" for n in MAGNET_TRIALS)
    worst = max(UNDISTURBED_TRIALS, key=lambda n: on[n][1] - off[n][1])
    return f"{mag} | {on[worst][1] - off[worst][1]:+.2f} ({worst})"


def broad_train(sensitivity_table: bool = False, trials: list[str] | None = None) -> None:
    fit, norm, coefficients, calibrated, t = train_calibration()
    rate = float(_trial(TRAIN_TRIALS[0]).meta["rate_hz"])
    stats = pf_settings.noise_statistics(calibrated, t, rate, pf_settings.decimation_for(rate))
    derived = pf_settings.pf_settings_from_calibration(calibrated, t, norm, rate)
    shown = {k: round(float(np.rad2deg(v)) if k == "pf_min_rotation" else v, 4) for k, v in derived.items()}
    print(f"\n### BROAD, settings derived from the calibration (train on {' + '.join(TRAIN_TRIALS)})\n")
    print(f"Calibration: ellipsoid fit of the raw 01 + 02 field to |h_0| = {norm:.3f} µT, offset "
          f"{np.round(fit.offset, 3).tolist()} µT, residual {fit.residual:.3f} µT. Calibrated field: "
          f"σ = {stats.sigma:.3f} µT (about the test's running mean), σ_w = {stats.sigma_white:.3f} µT "
          f"(variogram plateau at lag {stats.plateau_lag}), σ_slow = {stats.sigma_slow:.3f} µT. "
          f"Derived (pf_min_rotation in °): {shown}. Chain: {TRAIN_ATTITUDE}, field norm/dip from each "
          "sidecar; 'derived' = only `enable_pf = 1` plus these; 'hand-set' = BROAD_PF (comparison).\n")
    print("| trial | spread raw | spread without filter | spread derived | spread hand-set | heading without "
          "filter | heading derived | change | changes declared | heading hand-set |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    on = {"enable_pf": 1.0, **derived}
    trials = {n: _trial(n) for n in (*UNDISTURBED_TRIALS, *MAGNET_TRIALS) if not trials or n in trials}
    off_figures = {}
    derived_figures = {}
    for n, d in trials.items():
        off_figures[n] = _evaluate(d, coefficients, {})
        derived_figures[n] = _evaluate(d, coefficients, on)
        hand = _evaluate(d, coefficients, BROAD_PF)
        field = apply_ellipsoid(fit, d.mag)
        changes = magpf.run_c(field, magpf.settings(d.field_norm_ut, **derived)).changes
        (s0, h0), (s1, h1) = off_figures[n], derived_figures[n]
        print(f"| {d.name[:36]} | {_spread(d.mag, d.eval_mask.astype(bool)):.2f} | {s0:.2f} | {s1:.2f} | "
              f"{hand[0]:.2f} | {h0:.2f} | {h1:.2f} | {h1 - h0:+.2f} | {int(changes[-1])} | {hand[1]:.2f} |",
              flush=True)
    if not sensitivity_table or set(MAGNET_TRIALS) - set(trials):
        return
    print("\n### Sensitivity: each rule constant of training.models.pf_settings at 0.5× and 1.5× (others as derived)\n")
    print("Cells: magnet trials spread [%] / heading [°] with the filter (without: "
          + ", ".join(f"{n} {off_figures[n][1]:.2f}°" for n in MAGNET_TRIALS)
          + "); last column: largest heading change on the undisturbed trials [°] (trial).\n")
    print("| constant | value | " + " | ".join(MAGNET_TRIALS) + " | worst undisturbed change |")
    print("|---|---|---|---|---|---|")
    print(f"| (derived) | — | {_summary(off_figures, derived_figures)} |", flush=True)
    rows = [(label, value * f, {key: value * f}, None) for key, value, label in SENSITIVITY for f in (0.5, 1.5)]
    rows += [("settle spread S × factor", f, {}, f) for f in (0.5, 1.5)]
    for label, value, constants, settle_factor in rows:
        s = pf_settings.pf_settings_from_calibration(calibrated, t, norm, rate, **constants)
        if settle_factor is not None:
            s["pf_settle_spread"] *= settle_factor
        figures = _figures(trials, coefficients, {"enable_pf": 1.0, **s})
        print(f"| {label} | {value:.4g} | {_summary(off_figures, figures)} |", flush=True)


def _ellipsoid_heading(d, mask: np.ndarray) -> float:
    """Heading RMSE [°] of the runtime on the field calibrated by a batch ellipsoid fitted on the
    trial's own eval phase (an offline oracle: what the norm information in the recording supports)."""
    fit = fit_ellipsoid(d.mag[mask], d.field_norm_ut)
    calibrated = copy.copy(d)
    calibrated.mag = apply_ellipsoid(fit, d.mag)
    return bench.broad_errors(_run_chain(calibrated, {})[:, QUATERNION], d)["heading"]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--seeds", type=int, default=20)
    p.add_argument("--no-broad", action="store_true")
    p.add_argument("--no-sim", action="store_true")
    p.add_argument("--only-train", action="store_true",
                   help="only the table of the settings derived from the calibration (train)")
    p.add_argument("--sensitivity", action="store_true",
                   help="add the table of the rule constants varied by ±50 %%")
    p.add_argument("--trials", nargs="*", default=None, help="BROAD trial numbers (default: all)")
    a = p.parse_args(argv)
    if a.only_train:
        if BROAD.is_dir():
            broad_train(sensitivity_table=a.sensitivity)
        return 0
    if not a.no_sim:
        simulated(a.seeds)
    if not a.no_broad and BROAD.is_dir():
        broad(a.trials)
        broad_train(sensitivity_table=a.sensitivity, trials=a.trials)
    return 0


if __name__ == "__main__":
    sys.exit(main())
