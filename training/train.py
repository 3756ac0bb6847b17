"""`train`: fit the per-triad gain/bias temperature models and build the model artefact."""
from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm


from contract.errors import ModelError
from contract.layout import TRIAD_ORDER
from training.artefact import ModelArtefact, coefficients_array, settings_dict
from training.completeness import calibration_gaps, is_gap, recorded_triads
from training.data.dataset import ImuData
from training.data.earth import recordings_gravity
from training.data.reference import matched_raw
from training.data.reference_field import field_reference_notes
from training.data.reference_source import TriadReference, choose_reference
from training.display import DISPLAY
from training.models.calibrated_range import range_notes
from training.models.degree import AUTO, ceiling, choose_degree, parse_degree
from training.models.methods import fit_options, method_notes, method_settings
from training.models.prior import TriadPrior, load_prior
from training.models.elm import MIN_GAIN as ELM_MIN_GAIN, ElmModel
from training.models.fit_quality import BIAS_FALLBACK_NOTE, SCALE_FACTOR_CONVENTION, fit_warnings, scale_factors
from training.models.psobp import PsoBpModel
from training.models.thermal import (GainBiasFitter, ThermalFit, ThermalModel, apply_thermal,
                                     normalised_temperature, temperature_clusters, temperature_normalisation)
from training.attitude.field_changes import pf_switch
from training.attitude.replay import CANDIDATES as REPLAYED_SETTINGS
from training.attitude.replay import choose_by_replay, triads_the_reference_improves
from training.recommend import recommended_settings, sidecar_values
from training.selfcal import SelfCalResult, self_calibrate

#: Share of a single calibration recording (its end, in time) held out to decide on the ELM.
ELM_HOLDOUT_FRACTION = 0.25
#: Field directions covering this share of the sphere's cells prove that a recording moved (a
#: still sensor's field stays in one cell whatever its noise).
MOTION_COVERAGE = 0.1
#: Rows of the calibration data the ELM sees (every n-th sample): neighbouring samples at 100 Hz
#: carry the same field direction, so thinning loses nothing but training time.
ELM_STRIDE = 8
#: The chain's ELM: a node cap and a back-tuning budget that train in seconds on the default
#: calibration set (docs/elm.md has the study with larger budgets).
ELM_FITTER = dict(max_hidden=16, tune_steps=60, tune_batch=2048)
#: Fewest compass rows (after ELM_STRIDE) a recording must give the ELM: its held-out quarter must hold a
#: few rows, and 16 hidden nodes need more rows than weights to be more than an interpolation.
ELM_MIN_ROWS = 64

UNITS = {"gyr": "rad/s", "acc": "m/s²", "mag": "µT"}
#: The gains A·G(T) are identifiable only when the reference moves along every axis. This is the
#: least RMS excitation [triad unit] along the weakest direction of the reference (smallest
#: singular value / √N): 0.01 rad/s ≈ 0.6 °/s, 0.1 m/s², 1 µT — well above reference noise, far
#: below any calibration motion. Below it (a static gyro log, one accelerometer position) a fit of
#: A·G would be degenerate — A = 0 reproduces a zero reference exactly — so only the bias B(T) is
#: fitted, by linear least squares, with A = I and G = 1.
MIN_EXCITATION = {"gyr": 0.01, "acc": 0.1, "mag": 1.0}
#: Rows whose derived reference (from ref_q) disagrees with the sensor by more than this many
#: robust σ are left out of the fit: an optical marker glitch or a gap in the motion capture gives
#: rates of hundreds of °/s for a few samples, which least squares would follow; honest sensor
#: errors (bias, 1-5 % gains) stay far inside 5 σ of the residual's spread.
REFERENCE_OUTLIER_SIGMAS = 5.0


def _stage(name: str, steps: int, progress: bool) -> tqdm:
    """The progress bar of one training stage of `steps` steps (a context manager: it is closed, so
    its line is finished, before an error of the stage is printed)."""
    return tqdm(total=steps, desc=name, unit="step", disable=not progress)


@contextmanager
def deterministic(seed: int):
    """Seed torch, force deterministic kernels and run it on TORCH_THREADS threads; restore the
    previous mode and thread count afterwards."""
    previous, threads = torch.are_deterministic_algorithms_enabled(), torch.get_num_threads()
    torch.use_deterministic_algorithms(True)
    torch.manual_seed(seed)
    torch.set_num_threads(TORCH_THREADS)
    try:
        yield
    finally:
        torch.use_deterministic_algorithms(previous)
        torch.set_num_threads(threads)


#: Torch threads of every fit. One, on any machine: the reductions' order, so the trained numbers,
#: depend on the thread count (2 threads move the main job's coefficients by up to 2.8e-10), and the
#: fits' tensors are small enough that a second thread buys nothing (benchmarks/train_time.py: 16.0 s
#: wall on one thread against 18.2 s on torch's default of two; beside a busy process the default
#: took 66.8 s, its threads waiting for each other).
TORCH_THREADS = 1


def _stack(datasets: list[ImuData], name: str) -> np.ndarray:
    """Concatenate attribute `name` ((N, 3) triad) over the datasets; NaN where absent."""
    parts = [getattr(d, name) if getattr(d, name) is not None else np.full((len(d), 3), np.nan)
             for d in datasets]
    return np.concatenate(parts).astype(np.float64)


def _n_parameters(degree: int) -> int:
    """Free coefficients of one triad: 6 of symmetric A, 3P of g, 3(P+1) of b."""
    return 6 + 3 * degree + 3 * (degree + 1)


def _skip_reason(datasets: list[ImuData], triad: str, raw: np.ndarray, ref: np.ndarray,
                 degree: int) -> str | None:
    """Why `triad` cannot be fitted (for the artefact notes), or None when it can."""
    if all(getattr(d, f"ref_{triad}") is None for d in datasets) or not np.isfinite(ref).any():
        return f"{triad}: no reference (ref_{triad}) in the training data"
    if not np.isfinite(raw).any():
        return f"{triad}: raw data are all NaN"
    rows = int(np.sum(np.all(np.isfinite(raw), axis=1) & np.all(np.isfinite(ref), axis=1)))
    if rows < _n_parameters(degree):
        return f"{triad}: only {rows} usable rows for {_n_parameters(degree)} coefficients"
    return None


def _weakest_excitation(ref: np.ndarray) -> float:
    """RMS of the reference along its least-excited direction [triad unit] (finite rows)."""
    r = ref[np.all(np.isfinite(ref), axis=1)]
    return float(np.linalg.svd(r, compute_uv=False)[-1] / np.sqrt(len(r))) if len(r) >= 3 else 0.0


def fit_bias_only(raw: np.ndarray, ref: np.ndarray, temp: np.ndarray, degree: int) -> ThermalModel:
    """Bias polynomial B(T) per axis by least squares on raw − ref (A = I, G = 1); (N, 3) arrays in
    the triad unit, temp (N,) °C. Degree 0 when no temperature is finite."""
    ok = np.all(np.isfinite(raw), axis=1) & np.all(np.isfinite(ref), axis=1)
    norm = temperature_normalisation(temp[ok])
    t0, ts = norm if norm else (25.0, 1.0)
    p = degree if norm else 0
    tn = normalised_temperature(temp[ok], t0, ts)
    design = np.column_stack([tn ** k for k in range(p + 1)])
    b = np.linalg.lstsq(design, raw[ok] - ref[ok], rcond=None)[0].T
    return ThermalModel(True, t0, ts, p, np.eye(3), np.zeros((3, p)), b)


def _fit_notes(triad: str, fit: ThermalFit, degree: int) -> list[str]:
    """Warnings about one completed fit (degree: the degree it was asked for)."""
    notes = []
    if fit.model.degree < degree:
        notes.append(f"{triad}: no finite temperature; fitted degree 0 (constant A, G, B)")
    if not fit.converged:
        notes.append(f"{triad}: fit stopped after {fit.iterations} iterations before "
                     "reaching the tolerance")
    if fit.rows_dropped:
        notes.append(f"{triad}: {fit.rows_dropped} rows with non-finite values dropped")
    return notes


def _fit_stats(fit: ThermalFit) -> dict:
    """JSON-ready statistics of one fit (rms in the triad unit, loss normalised)."""
    return {"unit": fit.unit, "rows_used": fit.rows_used, "rows_dropped": fit.rows_dropped,
            "iterations": fit.iterations, "converged": fit.converged,
            "final_loss": fit.loss_history[-1], "rms_before": fit.rms_before,
            "rms_after": fit.rms_after}


def _calibrated_range(model: ThermalModel, datasets, prior: TriadPrior | None = None) -> ThermalModel:
    """`model` with the temperature range [°C] of the recordings it was calibrated on, widened to
    the fleet's when a fleet prior carried the temperature dependence: the runtime clamps the
    temperature to it (ThermalModel.t_range)."""
    temps = np.concatenate([d.temp for d in datasets] + ([np.asarray(prior.t_range)] if prior else []))
    return model.with_range(temps)


def _compensated(d: ImuData, thermal: dict[str, ThermalModel]) -> ImuData:
    """A copy of d whose raw triads are replaced by the thermally compensated ones."""
    c = d.slice(slice(None))
    c.gyr, c.acc, c.mag = (apply_thermal(thermal[k], getattr(d, k), d.temp) for k in ("gyr", "acc", "mag"))
    return c


def _elm_holdout(sets: list) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """Hold-out folds of the prepared compass sets: each recording once held out against the others
    when there are several (the ELM must carry over to a recording it has not seen); with one, its
    last ELM_HOLDOUT_FRACTION in time against the rest (neighbouring samples of a random split
    share the same field direction and position, and would flatter the model).
    Returns [(train field, train reference, test field, test reference)] (µT)."""
    if len(sets) > 1:
        return [(np.concatenate([s.field for j, s in enumerate(sets) if j != k]),
                 np.concatenate([s.reference for j, s in enumerate(sets) if j != k]),
                 sets[k].field, sets[k].reference) for k in range(len(sets))]
    s = sets[0]
    cut = int(round(len(s.field) * (1.0 - ELM_HOLDOUT_FRACTION)))
    return [(s.field[:cut], s.reference[:cut], s.field[cut:], s.reference[cut:])]


def _usable_for_elm(datasets: list[ImuData]) -> list[ImuData]:
    """The recordings the ELM can learn from: a magnetometer and its reference field and attitude."""
    return [d for d in datasets if d.ref_mag is not None and d.ref_q is not None and d.has("mag")]


def _compass_sets(datasets: list[ImuData], thermal: dict[str, ThermalModel], seed: int) -> list:
    """The ELM's prepared compass sets (training.models.elm.prepare_compass) of the usable
    recordings, thermally compensated by `thermal`."""
    from training.models import elm
    prep = elm.CompassPrep(stride=ELM_STRIDE)
    return [elm.prepare_compass(_compensated(d, thermal), None, prep, seed) for d in _usable_for_elm(datasets)]


def elm_rows(datasets: list[ImuData], thermal: dict[str, ThermalModel], seed: int = 0
             ) -> tuple[np.ndarray, np.ndarray] | None:
    """(calibrated field, reference field) [µT]: the rows a unit's ELM learns from, as `train` prepares
    them for recordings calibrated by `thermal`; None without a magnetometer reference. The fleet ELM
    (training.models.fleet_elm) pools them over units."""
    if not thermal["mag"].enabled:
        return None
    refs = {triad: choose_reference(datasets, triad) for triad in TRIAD_ORDER}
    sets = _compass_sets(_prepared_datasets(datasets, refs), thermal, seed)
    if not sets:
        return None
    return np.concatenate([s.field for s in sets]), np.concatenate([s.reference for s in sets])


def _fleet_elm_choice(fleet_elm: ElmModel, folds: list, errors: list, notes: list[str]) -> bool:
    """Whether the fleet's ELM beats the unit's own on the unit's held-out folds (the fleet ELM never
    saw this unit); a note says which one the unit gets and why."""
    from training.models import elm
    own = float(np.sqrt(np.mean(np.concatenate([e for _, e in errors]))))
    fleet = float(np.sqrt(np.mean(np.concatenate([(elm.elm_apply(fleet_elm, x) - y) ** 2 for _, _, x, y in folds]))))
    chosen = fleet < own
    notes.append(f"elm: the fleet prior's ELM ({fleet_elm.hidden} nodes) leaves {fleet:.3g} µT on this unit's held-out "
                 f"data, its own ELM {own:.3g} µT: the unit gets {'the fleet' if chosen else 'its own'}")
    return chosen


def _elm_stage(datasets: list[ImuData], thermal: dict[str, ThermalModel], seed: int,
               notes: list[str], progress: bool, fleet_elm: ElmModel | None = None, fit: dict | None = None
               ) -> tuple[ElmModel | None, bool, dict]:
    """Fit the field-form ELM on the thermally compensated field against ref_mag.

    Returns (the model or None, enabled, stats). Enabled only when the ELM lowers the field
    error RMS of the held-out data (`_elm_holdout`) by ELM_MIN_GAIN; the block is fitted on all
    the data and kept but off otherwise. With a fleet ELM (`train --prior`), the one of the two with
    the lower held-out error is the unit's. fit: ElmFitter options of a selected form (train --method elm=…:
    its schedule; the fleet ELM is then not considered).
    """
    from training.models import elm
    fitter = elm.ElmFitter(**ELM_FITTER, **(fit or {}))
    fleet_elm = None if fit is not None else fleet_elm
    if not _usable_for_elm(datasets) or not thermal["mag"].enabled:
        notes.append("elm: no magnetometer reference (ref_mag, ref_q) or no fitted magnetometer; "
                     "ELM stage off" + ("; the fleet prior's ELM is not used either (nothing to check it on)"
                                        if fleet_elm is not None else ""))
        return None, False, {}
    sets = [s for s in _compass_sets(datasets, thermal, seed) if len(s.field) >= ELM_MIN_ROWS]
    if not sets:
        notes.append(f"elm: fewer than {ELM_MIN_ROWS} compass rows with a reference (eval_mask, optical gaps); "
                     "ELM stage off")
        return None, False, {}
    errors, folds = [], _elm_holdout(sets)
    with _stage("ELM (held-out folds, final fit)", len(folds) + 1, progress) as bar:
        for train_x, train_y, test_x, test_y in folds:
            fold = fitter.fit(train_x, train_y, seed)
            errors.append(((test_x - test_y) ** 2, (elm.elm_apply(fold, test_x) - test_y) ** 2))
            bar.update()
        from_fleet = fleet_elm is not None and _fleet_elm_choice(fleet_elm, folds, errors, notes)
        if from_fleet:
            model = fleet_elm
            errors = [(before, (elm.elm_apply(fleet_elm, x) - y) ** 2) for (before, _), (_, _, x, y) in zip(errors, folds)]
        else:
            model = fitter.fit(np.concatenate([s.field for s in sets]), np.concatenate([s.reference for s in sets]), seed)
        bar.update()
    before = float(np.sqrt(np.mean(np.concatenate([e for e, _ in errors]))))
    after = float(np.sqrt(np.mean(np.concatenate([e for _, e in errors]))))
    enabled = after <= (1.0 - ELM_MIN_GAIN) * before
    if not enabled:
        notes.append(f"elm: held-out field error {before:.3g} -> {after:.3g} µT is not a "
                     f"{ELM_MIN_GAIN:.0%} gain; ELM stage off")
    stats = {"unit": "µT", "hidden": model.hidden, "folds": len(errors),
             "holdout": "each recording against the others" if len(sets) > 1 else
             f"last {ELM_HOLDOUT_FRACTION:.0%} of the recording in time",
             "rms_before": before, "rms_after": after, "enabled": enabled,
             **({"source": "fleet prior"} if from_fleet else {"train_time_s": model.train_time_s})}
    return model, enabled, stats


def _psobp_stage(datasets: list[ImuData], thermal: dict[str, ThermalModel], seed: int,
                 notes: list[str], progress: bool, fit: dict | None = None) -> tuple[PsoBpModel | None, bool, dict]:
    """Fit the residual PSO-BP gyro bias network on the longest recording with a gyro reference
    and temperature (networks see one continuous series: the temperature rate needs it).

    Returns (the model or None, enabled, stats); enabled by psobp.residual_psobp_wins, which
    fits on the first two thirds and switches the network on only for a held-out gain. fit: PsoBpFitter
    switches of a selected form (train --method psobp=…).
    """
    from training.models import psobp
    usable = [d for d in datasets if d.ref_gyr is not None and d.has("gyr") and np.isfinite(d.temp).any()]
    if not usable or not thermal["gyr"].enabled:
        notes.append("psobp: no gyro reference with temperature or no fitted gyro; PSO-BP stage off")
        return None, False, {}
    d = max(usable, key=len)
    gyr = apply_thermal(thermal["gyr"], d.gyr, d.temp)
    try:
        with _stage("PSO-BP (held-out decision, final fit)", 2, progress) as bar:
            decision = psobp.residual_psobp_wins(d.t, gyr, d.ref_gyr, d.temp, seed, **(fit or {}))
            bar.update()
            fitted = psobp.fit_gyro_residual_psobp(d.t, gyr, d.ref_gyr, d.temp, seed, **(fit or {}))
            bar.update()
    except ValueError as e:  # too few static windows with temperature to fit a network
        notes.append(f"psobp: {e}; PSO-BP stage off")
        return None, False, {}
    if not decision.enable:
        notes.append(f"psobp: held-out residual bias {decision.rms_polynomial:.3g} -> "
                     f"{decision.rms_hybrid:.3g} rad/s is not a {psobp.ENABLE_MIN_GAIN:.0%} gain; stage off")
    stats = {"unit": "rad/s", "recording": d.name, "held_out_windows": decision.windows,
             "rms_polynomial": decision.rms_polynomial, "rms_hybrid": decision.rms_hybrid,
             "enabled": bool(decision.enable)}
    return fitted.model, bool(decision.enable), stats


def gate_outliers(raw: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, int]:
    """target (N, 3) with NaN rows where |raw − target − median| exceeds REFERENCE_OUTLIER_SIGMAS
    robust standard deviations (1.4826 · MAD of the norm); returns it and the count set to NaN."""
    residual = raw - target
    ok = np.all(np.isfinite(residual), axis=1)
    if ok.sum() < 10:
        return target, 0
    r = np.linalg.norm(residual - np.median(residual[ok], axis=0), axis=1)
    scale = 1.4826 * np.median(np.abs(r[ok] - np.median(r[ok])))
    bad = ok & (r > np.median(r[ok]) + REFERENCE_OUTLIER_SIGMAS * scale)
    out = target.copy()
    out[bad] = np.nan
    return out, int(bad.sum())


def _fit_with_reference(ref: TriadReference, degree, seed: int, prior: TriadPrior | None = None,
                        gains: bool = True) -> tuple[ThermalModel, dict, list[str]]:
    """Fit one triad against the reference its recordings carry (columns, derived or static):
    the full gain/bias model when the reference moves along every axis (and `gains`), else the bias
    B(T) only. degree: 'auto' or the largest degree; the degree fitted is chosen from the data
    (training.models.degree.choose_degree) and reported in the stats ('degree_choice') and the notes.
    With a fleet prior the full model is fitted in the population's basis (`_fit_with_prior`)."""
    triad, datasets = ref.triad, list(ref.datasets)
    temp = np.concatenate([d.temp for d in datasets]).astype(np.float64)
    raw, target = _stack(datasets, triad), _stack(datasets, f"ref_{triad}")
    notes = []
    if ref.source == "attitude":
        raw = np.concatenate([matched_raw(d, triad) for d in datasets])
        target, dropped = gate_outliers(raw, target)
        if dropped:
            notes.append(f"{triad}: {dropped} rows whose derived reference disagrees with the sensor by more "
                         f"than {REFERENCE_OUTLIER_SIGMAS:g} robust σ (optical gaps, marker glitches) left out")
    reason = _skip_reason(datasets, triad, raw, target, ceiling(degree))
    if reason:
        return ThermalModel.identity(enabled=False), {}, [f"{reason}; thermal model disabled"]
    if prior is not None and gains:
        return _fit_with_prior(triad, raw, target, temp, seed, prior, notes)
    excitation = _weakest_excitation(target)
    gains = gains and excitation >= MIN_EXCITATION[triad]
    if not gains and ref.source == "static" and triad != "gyr" and temperature_clusters(temp) < 2:
        return ThermalModel.identity(enabled=False), {}, [
            f"{triad}: a static log at one temperature identifies nothing of the {triad} (its bias and "
            "gains need several poses or a reference); thermal model disabled"]
    choice = choose_degree(raw, target, temp, degree, gains, UNITS[triad])
    notes.append(f"{triad}: temperature polynomial {choice.reason}")
    if gains:
        fit = GainBiasFitter(degree=choice.degree).fit(raw, target, temp, seed, UNITS[triad])
        stats = {**_fit_stats(fit), "degree_choice": choice.as_dict()}
        return fit.model, stats, notes + _fit_notes(triad, fit, choice.degree)
    model = fit_bias_only(raw, target, temp, choice.degree)
    stats = {"unit": UNITS[triad], "bias_only": True, "weakest_excitation": excitation,
             "degree_choice": choice.as_dict()}
    if excitation >= MIN_EXCITATION[triad]:
        return model, stats, notes + [f"{triad}: fitted the bias B(T) only (A = I, G = 1)"]
    what = ("the temperature drift of the bias only (the absolute bias and the gains are not "
            "identifiable from a static log)") if ref.source == "static" and triad != "gyr" else "the bias B(T) only"
    return model, stats, notes + [f"{triad}: the reference hardly moves (weakest direction {excitation:.3g} "
                          f"{UNITS[triad]} RMS < {MIN_EXCITATION[triad]}): gains not identifiable, "
                          f"fitted {what} (A = I, G = 1)"]


def _fit_with_prior(triad: str, raw: np.ndarray, target: np.ndarray, temp: np.ndarray, seed: int,
                    prior: TriadPrior, notes: list[str]) -> tuple[ThermalModel, dict, list[str]]:
    """The maximum a posteriori gain/bias model of one triad under the fleet prior: the data pin
    down what they observe, the population the rest (training.models.prior)."""
    fit = GainBiasFitter(degree=prior.degree, prior=prior).fit(raw, target, temp, seed, UNITS[triad])
    stats = {**_fit_stats(fit), "fleet_prior_units": prior.units,
             "posterior_sigma": [float(v) for v in fit.posterior_sigma]}
    lo, hi = prior.t_range
    middle = float(np.median(temp[np.isfinite(temp)])) if np.isfinite(temp).any() else prior.t0
    points = sorted({round(t, 1) for t in (lo, middle, hi)})   # the fleet's range and the recording's median
    bias_sigma = bias_uncertainty(fit.posterior_cov, prior, points)
    stats["bias_sigma"] = {"temp_c": list(points), "sigma": bias_sigma, "unit": UNITS[triad]}
    unit, factor = DISPLAY[triad]
    return fit.model, stats, notes + _fit_notes(triad, fit, prior.degree) + [
        f"{triad}: fitted with the fleet prior of {prior.units} units (degree {prior.degree}, calibrated over "
        f"{lo:.1f} … {hi:.1f} °C): what this recording does not observe comes from the population; the bias is "
        "uncertain by " + ", ".join(f"{factor * v:.2g} {unit} at {t:.1f} °C" for t, v in zip(points, bias_sigma))
        + " (1σ, largest axis, posterior: away from the recording's temperatures it is the fleet's spread)"]


def bias_uncertainty(cov: np.ndarray, prior: TriadPrior, temps) -> list[float]:
    """The largest axis's posterior σ of the bias B(T) [triad unit] at each temperature [°C], from the
    covariance of θ (training.models.prior order: b is the last 3·(degree+1) entries, axis-major)."""
    d = prior.degree
    b = cov[6 + 3 * d:, 6 + 3 * d:]
    out = []
    for t in temps:
        v = ((t - prior.t0) / prior.ts) ** np.arange(d + 1)
        out.append(float(max(np.sqrt(max(v @ b[i * (d + 1):(i + 1) * (d + 1), i * (d + 1):(i + 1) * (d + 1)] @ v, 0.0))
                             for i in range(3))))
    return out


def _unused_prior_notes(refs: dict[str, TriadReference], prior: dict[str, TriadPrior]) -> list[str]:
    """One note per triad the fleet prior could not help: it applies to fits against a reference,
    and a triad without one is self-calibrated as without the prior; or the fleet had no prior for it."""
    notes = []
    for triad in TRIAD_ORDER:
        if not prior:
            break
        if refs[triad].source == "none":
            notes.append(f"{triad}: the fleet prior was not used: the recordings carry no {triad} reference, and the "
                         "prior applies to fits against one (the triad is self-calibrated as without it)")
        elif triad not in prior:
            notes.append(f"{triad}: the fleet prior has no {triad} population (fewer than its minimum of units "
                         "calibrated against a reference); fitted without it")
    return notes


def _prior_pf_spreads(prior: TriadPrior, stats: dict, notes: list[str]) -> dict[str, float]:
    """The particle filter's prior spreads from the fit under the fleet prior: the largest posterior
    σ of the magnetometer bias at the population's centre temperature [µT] (pf_prior_spread_hard)
    and of the calibration matrix's entries [1] (pf_prior_spread_soft) — how far this unit's
    calibration may be from its truth, given its recording and the population."""
    degree, sigma = prior.degree, np.asarray(stats["posterior_sigma"])
    bias = sigma[6 + 3 * degree:].reshape(3, degree + 1)[:, 0]
    spreads = {"pf_prior_spread_hard": float(bias.max()), "pf_prior_spread_soft": float(sigma[:6].max())}
    notes.append(f"mag: particle filter prior spreads from the calibration's posterior under the fleet prior: "
                 f"{spreads['pf_prior_spread_hard']:.3g} µT, {spreads['pf_prior_spread_soft']:.3g}")
    return spreads


def _self_calibrated(datasets: list[ImuData], triads: list[str], degree: int, progress: bool,
                     notes: list[str]) -> SelfCalResult:
    """Self-calibration from invariants of every recording (training.selfcal) for the triads
    without any reference; the field norm from the sidecars when they give one."""
    norms = sidecar_values(datasets, "norm_ut")
    result = self_calibrate(datasets, field_norm=float(np.mean(norms)) if norms else None,
                            degree=degree, gravity=recordings_gravity(datasets)[0], progress=progress)
    for triad in triads:
        notes += [f"{triad}: {n}" for n in result.report.get(triad, {}).get("notes", [])]
    return result


def _prepared_datasets(datasets: list[ImuData], refs: dict[str, TriadReference]) -> list[ImuData]:
    """The recordings with every reference chosen for them filled in (for the ELM and PSO-BP
    stages, which fit against reference columns)."""
    out = []
    for d in datasets:
        fields = {}
        for triad, ref in refs.items():
            if ref.source in ("columns", "attitude"):
                match = next((r for r in ref.datasets if r.name == d.name and len(r) == len(d)), None)
                if match is not None:
                    fields[f"ref_{triad}"] = getattr(match, f"ref_{triad}")
        out.append(replace(d, **fields))
    return out


def _held_out(datasets: list[ImuData], refs: dict[str, TriadReference], degree, seed: int,
              selfcal, notes: list[str], progress: bool, prior: dict[str, TriadPrior]) -> dict[str, dict]:
    """Held-out error per triad (training.models.holdout): the same procedure refitted without the last
    quarter of every recording, scored on it; {} with a note when the recordings are too short."""
    from training.models.holdout import held_out
    norms, gravity = sidecar_values(datasets, "norm_ut"), recordings_gravity(datasets)[0]
    norm = float(np.mean(norms)) if norms else (selfcal.report.get("mag", {}).get("field_norm_ut") if selfcal else None)

    def fit_selfcal(parts):
        return self_calibrate(parts, field_norm=norm, degree=ceiling(degree), gravity=gravity, progress=False).thermal
    try:
        with deterministic(seed), _stage("held-out refit", len(refs) + 1, progress) as bar:
            return held_out(datasets, refs, lambda r: _fit_with_reference(r, degree, seed, prior.get(r.triad))[0], fit_selfcal,
                            norm, gravity, step=bar.update)
    except ValueError as e:
        notes.append(f"held-out error not computed: {e}")
        return {}


#: A held-out error above this share of the raw sensor's is a fit that barely helps: a warning.
BARELY_IMPROVED = 0.9


def _worse_than_raw(thermal: dict[str, ThermalModel], stats: dict, notes: list[str]) -> list[str]:
    """Triads whose calibration is worse than the raw sensor on held-out data (not exported: the
    caller keeps the identity, or the bias alone where `_may_fall_back`), with a loud note each; a
    warning note for a fit that barely helps."""
    worse = []
    for triad in TRIAD_ORDER:
        held = stats.get(triad, {}).get("held_out") or {}
        before, after = held.get("before"), held.get("after")
        if before is None or after is None or not thermal[triad].enabled:
            continue
        metric = held.get("metric", "held-out error")
        if after > before:
            worse.append(triad)
            notes.append(f"{triad}: NOT EXPORTED — the calibration is worse than the raw sensor on held-out data "
                         f"({metric}: raw {before:.4g}, calibrated {after:.4g}); "
                         + ("the bias alone is tried instead" if _may_fall_back(triad, stats) else "the identity is kept")
                         + (" and the PSO-BP stage is off" if triad == "gyr" else "")
                         + (" and the ELM stage is off" if triad == "mag" else ""))
        elif after > BARELY_IMPROVED * before:
            notes.append(f"{triad}: warning: the calibration barely helps on held-out data ({metric}: raw "
                         f"{before:.4g}, calibrated {after:.4g}, {100 * (1 - after / before):.0f} % lower)")
    return worse


#: Triads whose gain/bias calibration, worse than raw on held-out data, falls back to the bias B(T)
#: alone when that beats raw on the same split (`_bias_only_fallback`): the inertial sensors, whose bias
#: is the largest error and is pinned by every rest. Not the magnetometer: its offset is the hard iron
#: of the surroundings, which the particle filter (enable_pf) estimates where the FMU runs.
BIAS_FALLBACK_TRIADS = ("gyr", "acc")


def _may_fall_back(triad: str, stats: dict) -> bool:
    """A triad refused by `_worse_than_raw` gets `_bias_only_fallback`: inertial, against a reference
    (a self-calibration's held-out score is on invariants, which it already fits bias-first), with a
    gain/bias fit to drop."""
    return (triad in BIAS_FALLBACK_TRIADS and stats.get(triad, {}).get("reference", "none") != "none"
            and not stats[triad].get("bias_only"))


def _bias_only_fallback(datasets: list[ImuData], ref: TriadReference, degree, seed: int, stats: dict,
                        notes: list[str]) -> ThermalModel:
    """The bias B(T) alone (A = I, G = 1) of a triad whose gain/bias calibration lost to the raw sensor
    on held-out data, when it beats the raw sensor on the same held-out split; else the identity.
    stats[triad] and the notes say which, with both held-out scores."""
    from training.models.holdout import held_out
    triad, rejected = ref.triad, stats[ref.triad]["held_out"]
    try:
        score = held_out(datasets, {triad: ref}, lambda r: _fit_with_reference(r, degree, seed, gains=False)[0],
                         None, None, recordings_gravity(datasets)[0])[triad]
    except ValueError as e:
        notes.append(f"{triad}: the bias alone could not be scored on held-out data ({e}); the identity is kept")
        return ThermalModel.identity(enabled=False)
    metric, before, after = score.get("metric", "held-out error"), score["before"], score["after"]
    if not after < before:
        notes.append(f"{triad}: the bias alone is no better ({metric}: raw {before:.4g}, bias only {after:.4g}); "
                     "the identity is kept")
        return ThermalModel.identity(enabled=False)
    model, fit_stats, fit_notes = _fit_with_reference(ref, degree, seed, gains=False)
    stats[triad] = {**fit_stats, "reference": ref.source, "held_out": score, "held_out_gain_bias": rejected}
    notes.extend(fit_notes)
    notes.append(f"{triad}: {BIAS_FALLBACK_NOTE}: it beats the raw sensor on the same held-out "
                 f"data ({metric}: raw {before:.4g}, bias only {after:.4g}); the gains stay 1 and the axes as they are")
    return _calibrated_range(model, ref.datasets, None)


def _refuse_identity(thermal: dict[str, ThermalModel], refs: dict[str, TriadReference], selfcal,
                     notes: list[str]) -> None:
    """ModelError naming what is missing when no triad could be calibrated, or when nothing carries a
    reference and the recordings show no motion (`_moved`): a still log calibrates the gyro bias only
    and must then say so with "reference": "static" in its sidecar — a constant rotation could not
    be told from a bias."""
    hint = " — record the protocol of docs/calibration.md, or pass --allow-identity"
    if not any(m.enabled for m in thermal.values()):
        raise ModelError("nothing could be calibrated: " + "; ".join(
            n for n in notes if any(n.startswith(f"{t}:") for t in TRIAD_ORDER)) + hint)
    if all(r.source == "none" for r in refs.values()) and not _moved(selfcal.report):
        names = ", ".join(d.name for d in refs["gyr"].datasets)
        raise ModelError(f"no reference and no motion in {names}: one pose, the field never turns, no "
                         "rotation between rests — only a gyro bias could be fitted; a still log must say "
                         "\"reference\": \"static\" in its sidecar" + hint)


def _reference_fits(refs: dict[str, TriadReference], degree, seed: int, progress: bool,
                    thermal: dict, stats: dict, notes: list[str], prior: dict[str, TriadPrior]) -> None:
    """Fit every triad that has a reference (`_fit_with_reference`, under its fleet prior if
    any), with a progress bar; fills thermal, stats and notes."""
    referenced = [t for t in TRIAD_ORDER if refs[t].source != "none"]
    for triad in tqdm(referenced, desc="reference fit", disable=not progress or not referenced):
        thermal[triad], stats[triad], fit_notes = _fit_with_reference(refs[triad], degree, seed, prior.get(triad))
        notes += list(refs[triad].notes) + fit_notes


def _moved(report: dict) -> bool:
    """True when the self-calibration saw motion: two poses or more, field directions over at least
    MOTION_COVERAGE of the sphere, or a rotation between two rests."""
    return (int(report.get("acc", {}).get("poses") or 0) >= 2
            or float(report.get("mag", {}).get("coverage") or 0.0) >= MOTION_COVERAGE
            or int(report.get("gyr", {}).get("segments") or 0) >= 1)


def train(datasets: list[ImuData], seed: int = 0, degree: int | str = AUTO,
          progress: bool = True, allow_identity: bool = False,
          prior: dict[str, TriadPrior] | None = None, fleet_elm: ElmModel | None = None,
          methods: dict[str, str] | None = None, mounting=None) -> ModelArtefact:
    """Fit the gain/bias temperature model of every triad and return the model artefact.

    When a triad's reference is derived from an attitude reference (ref_q only), the recordings are
    also calibrated as if they had none for those triads, and a triad keeps its reference-derived
    calibration only when that brings every recording's replayed attitude closer to the reference
    (training.attitude.replay.triads_the_reference_improves): a derived reference carries the
    reference system's own errors (timing, lever arm, marker alignment), and it must never give a
    worse filter than the recordings alone.

    datasets: calibration recordings. Per triad the best reference any recording offers is used
    (training.data.reference_source: reference columns, an attitude reference, a static log); a triad
    without any is self-calibrated from invariants (training.selfcal). degree: 'auto' (default) or
    the largest polynomial degree (0..MAX_DEGREE) of G(T) and B(T); the degree fitted per triad is
    chosen from the data (training.models.degree: no more than the distinct temperatures pin down, the
    simplest that holds on held-out data; self-calibrated triads cap it by their rest temperatures).
    prior: {triad: TriadPrior} from a fleet (training.models.prior.load_prior): referenced triads
    with a prior are fitted as the population's maximum a posteriori model. fleet_elm: the fleet's
    ELM (training.models.fleet_elm), which the unit gets instead of its own when it leaves less on
    the unit's held-out data. methods: source-method forms selected by `train --method`
    (training.models.methods: method -> form), their stages switched on and their settings written.
    mounting: the codes (mount_x, mount_y, mount_z) `train --mounting` declares; without them the sidecars'
    "mounting", else the data decide, whatever references the recordings carry (training.mounting).
    Deterministic given `seed`. Raises ModelError when `datasets` is empty,
    and when no triad can be calibrated unless allow_identity (then an identity model is returned).
    """
    artefact = _fit(datasets, seed, degree, progress, allow_identity, prior, fleet_elm, methods or {}, mounting=mounting)
    derived = tuple(t for t in TRIAD_ORDER if artefact.fit_stats.get(t, {}).get("reference") == "attitude")
    if not derived:
        return artefact
    try:
        blind = _fit(datasets, seed, degree, progress, allow_identity, prior, fleet_elm, methods or {}, withheld=derived,
                     mounting=mounting)
    except ModelError:
        return artefact
    kept, notes = triads_the_reference_improves(artefact, blind, datasets)
    if kept != derived:
        withheld = tuple(t for t in derived if t not in kept)
        artefact = blind if not kept else _fit(datasets, seed, degree, progress, allow_identity, prior, fleet_elm, methods or {},
                                               withheld=withheld, mounting=mounting)
    artefact.notes[0:0] = notes
    return artefact


def _fit(datasets: list[ImuData], seed: int, degree: int | str, progress: bool, allow_identity: bool,
         prior: dict[str, TriadPrior] | None, fleet_elm: ElmModel | None, methods: dict[str, str],
         withheld: tuple[str, ...] = (), mounting=None) -> ModelArtefact:
    """train's fit of every triad from the references the recordings offer (arguments as train's),
    except the `withheld` triads, which are self-calibrated as if no recording had a reference for
    them; the filter settings are chosen by replaying the recordings."""
    if not datasets:
        raise ModelError("train: no training data given")
    try:
        degree = parse_degree(degree)
    except ValueError as e:
        raise ModelError(f"train: {e}") from None
    refs = {triad: (TriadReference(triad, "none", tuple(datasets)) if triad in withheld
                     else choose_reference(datasets, triad)) for triad in TRIAD_ORDER}
    thermal, stats, notes = {}, {}, [recordings_gravity(datasets)[1]] + [n for d in datasets for n in field_reference_notes(d)]
    with deterministic(seed):
        _reference_fits(refs, degree, seed, progress, thermal, stats, notes, prior or {})
        notes += _unused_prior_notes(refs, prior or {})
        blind = [t for t in TRIAD_ORDER if refs[t].source == "none"]
        selfcal = _self_calibrated(datasets, blind, ceiling(degree), progress, notes) if blind else None
        for triad in blind:
            thermal[triad], stats[triad] = selfcal.thermal[triad], selfcal.report.get(triad, {})
        thermal = {triad: _calibrated_range(thermal[triad], refs[triad].datasets,
                                            (prior or {}).get(triad) if refs[triad].source != "none" else None)
                   for triad in TRIAD_ORDER}
        for triad in TRIAD_ORDER:
            stats.setdefault(triad, {})["reference"] = refs[triad].source
        prepared = _prepared_datasets(datasets, refs)
        elm_model, elm_on, stats["elm"] = _elm_stage(prepared, thermal, seed, notes, progress, fleet_elm,
                                                     fit_options(methods, "elm") if "elm" in methods else None)
        psobp_model, psobp_on, stats["psobp"] = _psobp_stage(prepared, thermal, seed, notes, progress,
                                                             fit_options(methods, "psobp") if "psobp" in methods else None)
        _refuse_unfitted_methods(methods, {"elm": elm_model, "psobp": psobp_model}, notes)
    if not allow_identity:
        _refuse_identity(thermal, refs, selfcal, notes)
    for triad, score in _held_out(datasets, refs, degree, seed, selfcal, notes, progress, prior or {}).items():
        stats[triad]["held_out"] = score
    for triad in _worse_than_raw(thermal, stats, notes):
        thermal[triad] = (_bias_only_fallback(datasets, refs[triad], degree, seed, stats, notes)
                          if _may_fall_back(triad, stats) else ThermalModel.identity(enabled=False))
        elm_on, psobp_on = elm_on and triad != "mag", psobp_on and triad != "gyr"
        psobp_model = psobp_model if psobp_on else None
    stats = {k: v for k, v in stats.items() if v}
    for triad in TRIAD_ORDER:
        if thermal[triad].enabled:
            stats.setdefault(triad, {}).update(scale_factors=[float(v) for v in scale_factors(thermal[triad])],
                                               scale_factor_convention=SCALE_FACTOR_CONVENTION)
    settings = recommended_settings(datasets, refs, thermal, selfcal, notes, mounting)
    if prior and "mag" in prior and "posterior_sigma" in stats.get("mag", {}):
        settings.update(_prior_pf_spreads(prior["mag"], stats["mag"], notes))
    notes += fit_warnings(thermal, settings, {t: refs[t].source for t in TRIAD_ORDER})
    if selfcal is not None:
        stats["protocol"] = selfcal.report["protocol"]
    notes += [gap.text() for gap in calibration_gaps(thermal, stats, notes, recorded_triads(datasets))]
    settings["enable_elm"] = float(elm_on)
    settings["enable_psobp"] = float(psobp_on)
    notes += range_notes(thermal, elm_model, psobp_model, settings)
    artefact = ModelArtefact(seed=seed, thermal=thermal, settings=settings, fit_stats=stats,
                             training_data=[_training_record(d) for d in datasets],
                             notes=notes, elm=elm_model, psobp=psobp_model)
    chosen = choose_by_replay(coefficients_array(artefact), settings_dict(artefact), datasets, artefact.notes)
    artefact.settings.update({name: chosen[name] for name in REPLAYED_SETTINGS})
    artefact.settings.update(pf_switch(coefficients_array(artefact), settings_dict(artefact), datasets, artefact.notes))
    artefact.notes += method_notes(methods, settings_dict(artefact))
    artefact.settings.update(method_settings(methods))
    artefact.methods = dict(methods)
    return artefact


def _refuse_unfitted_methods(methods: dict[str, str], models: dict, notes: list[str]) -> None:
    """ModelError when a stage `train --method` selected could not be fitted, with the stage's own reason."""
    for method, model in models.items():
        if method in methods and model is None:
            reason = next((n for n in reversed(notes) if n.startswith(f"{method}:")), f"{method}: not fitted")
            raise ModelError(f"train --method {method}={methods[method]}: the stage cannot be fitted on these "
                             f"recordings ({reason})")


def _training_record(data: ImuData) -> dict:
    """A calibration recording as the artefact lists it: name, samples and (with two samples or more) its
    nominal rate [Hz], 1 / the median sample step, which sets the FMU's default experiment step."""
    record = {"name": data.name, "samples": len(data)}
    if len(data) > 1 and np.median(np.diff(data.t)) > 0:
        record["rate_hz"] = float(1.0 / np.median(np.diff(data.t)))
    return record


@dataclass
class TrainedFolder:
    """What `train_to_folder` wrote and what `imufmu train` prints, with what it was made from."""

    model: Path            # OUT/model.json
    calibration: Path      # OUT/calibration.ssv: the FMU parameter values (fmu.calibration_file)
    report: Path           # OUT/calibration.md
    notes: list[str]       # the artefact's notes
    summary: str           # the calibration summary (plain text)
    gaps: list[str]        # the notes of recorded triads not fully calibrated (training.completeness)
    artefact: ModelArtefact = field(repr=False)        # what OUT/model.json holds
    datasets: list[ImuData] = field(repr=False)        # the recordings it was trained on


def train_to_folder(paths: list[Path], out_dir: str | Path, seed: int = 0, degree: int | str = AUTO,
                    allow_identity: bool = False, progress: bool = True,
                    prior_path: str | Path | None = None, name: str | None = None,
                    methods: dict[str, str] | None = None, mounting=None) -> TrainedFolder:
    """`imufmu train`: read the recordings at `paths`, `train` on them (under the fleet prior of
    `prior_path`, a fleet.json, if given), write OUT/model.json (with the noise characterisation of the
    recordings' still data under "noise", training.noise), OUT/imu.yaml (Kalibr), the FMU parameter values OUT/calibration.ssv
    (its set named `name`: the unit's, default out_dir's name — pass the final one when out_dir is a
    staging folder) and the calibration report OUT/calibration.md; progress: the stages' progress bars;
    methods: train's `methods` (`--method`); mounting: train's `mounting` (`--mounting`)."""
    from fmu.calibration_file import FILE_NAME as CALIBRATION_FILE, write_calibration
    from training.data.io import read_imu_csv
    from training.noise.characterise import characterise
    from training.noise.kalibr import write_imu_yaml
    from training.noise.report import YAML_NAME as IMU_YAML
    from training.reports.calibration_report import summary_text, write_calibration_report
    datasets = [read_imu_csv(p) for p in paths]
    from training.models.fleet_elm import load_fleet_elm
    prior = load_prior(prior_path) if prior_path is not None else None
    fleet_elm = load_fleet_elm(prior_path) if prior_path is not None else None
    artefact = train(datasets, seed=seed, degree=degree, allow_identity=allow_identity, progress=progress,
                     prior=prior, fleet_elm=fleet_elm, methods=methods, mounting=mounting)
    artefact.noise = characterise(datasets).block
    model = Path(out_dir) / "model.json"
    artefact.save(model)
    write_imu_yaml(artefact.noise, Path(out_dir) / IMU_YAML)
    calibration = write_calibration(Path(out_dir) / CALIBRATION_FILE, coefficients_array(artefact),
                                    settings_dict(artefact), artefact.aux_inputs,
                                    name=name or Path(out_dir).resolve().name,
                                    description=f"ImuFusion calibration trained on {', '.join(Path(p).name for p in paths)}")
    report = write_calibration_report(artefact, datasets, out_dir)
    return TrainedFolder(model, calibration, report, list(artefact.notes), summary_text(artefact, datasets),
                         [n for n in artefact.notes if is_gap(n)], artefact, datasets)
