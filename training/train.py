"""`train`: fit the per-triad gain/bias temperature models and build the model artefact."""
from __future__ import annotations

from contextlib import contextmanager
from dataclasses import replace

import numpy as np
import torch
from tqdm import tqdm

from .artefact import ModelArtefact
from .dataset import ImuData
from .errors import ModelError
from .layout import TRIAD_ORDER, settings_defaults
from .reference import matched_raw
from .reference_source import TriadReference, choose_reference
from .selfcal import SelfCalResult, self_calibrate
from .thermal import (GainBiasFitter, ThermalFit, ThermalModel, apply_thermal, normalised_temperature,
                      temperature_clusters,
                      temperature_normalisation)

#: The ELM stage is switched on only when it lowers the held-out field error RMS of the
#: calibration data by at least this fraction: a smaller gain is within what a different random
#: split moves, and an ELM that does not clearly help is not worth its risk on other data.
ELM_MIN_GAIN = 0.10
#: Share of a single calibration recording (its end, in time) held out to decide on the ELM.
ELM_HOLDOUT_FRACTION = 0.25
#: Rows of the calibration data the ELM sees (every n-th sample): neighbouring samples at 100 Hz
#: carry the same field direction, so thinning loses nothing but training time.
ELM_STRIDE = 8
#: The chain's ELM: a node cap and a back-tuning budget that train in seconds on the default
#: calibration set (docs/elm.md has the study with larger budgets).
ELM_FITTER = dict(max_hidden=16, tune_steps=60, tune_batch=2048)

UNITS = {"gyr": "rad/s", "acc": "m/s²", "mag": "µT"}
#: The gains A·G(T) are identifiable only when the reference moves along every axis. This is the
#: least RMS excitation [triad unit] along the weakest direction of the reference (smallest
#: singular value / √N): 0.01 rad/s ≈ 0.6 °/s, 0.1 m/s², 1 µT — well above reference noise, far
#: below any calibration motion. Below it (a static gyro log, one accelerometer position) a fit of
#: A·G would be degenerate — A = 0 reproduces a zero reference exactly — so only the bias B(T) is
#: fitted, by linear least squares, with A = I and G = 1.
MIN_EXCITATION = {"gyr": 0.01, "acc": 0.1, "mag": 1.0}
#: A sample counts as static for the gyro bias residual when the true rate is below this
#: [rad/s] (0.3 °/s: far above the reference noise of a rate table, far below any motion).
STATIC_RATE = 0.005
#: Lower bound of the recommended gyro_bias_residual [rad/s]: 1e-5 rad/s ≈ 2 °/h, the bias
#: instability of a good consumer MEMS gyro. A fit to simulated data leaves a near-zero mean
#: residual, but run-to-run bias changes that no calibration captures remain in the field.
GYRO_BIAS_RESIDUAL_FLOOR = 1e-5
#: Rows whose derived reference (from ref_q) disagrees with the sensor by more than this many
#: robust σ are left out of the fit: an optical marker glitch or a gap in the motion capture gives
#: rates of hundreds of °/s for a few samples, which least squares would follow; honest sensor
#: errors (bias, 1-5 % gains) stay far inside 5 σ of the residual's spread.
REFERENCE_OUTLIER_SIGMAS = 5.0
#: Shortest rest run [samples] whose statistics count: 20 samples give a std within ~16 %.
MIN_REST_RUN = 20
#: rest_gyro_threshold ≥ this many σ of the per-sample gyro noise: the runtime's detector needs
#: every sample of 1.5 s within the threshold of the low-passed rate; at 5σ a still sensor at
#: 300 Hz passes with > 99 % probability (at 4σ, ~97 %).
REST_NOISE_SIGMAS = 5.0
#: rest_gyro_threshold ≥ this many times the largest bias the calibration leaves at rest (run
#: means, between and within recordings): the detector also requires the low-passed rate inside
#: the threshold, so a residual bias at half of it is still accepted.
REST_BIAS_MARGIN = 2.0
#: Sidecar earth-field magnitudes of the training sets may differ by this much [µT] before
#: the artefact warns that their mean is a poor single field_norm.
FIELD_NORM_SPREAD = 1.0


@contextmanager
def _deterministic(seed: int):
    """Seed torch and force deterministic kernels; restore the previous mode afterwards."""
    previous = torch.are_deterministic_algorithms_enabled()
    torch.use_deterministic_algorithms(True)
    torch.manual_seed(seed)
    try:
        yield
    finally:
        torch.use_deterministic_algorithms(previous)


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
    """Warnings about one completed fit."""
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


def _sidecar_values(datasets: list[ImuData], key: str) -> list[float]:
    """earth_field[key] (norm_ut, dip_deg, declination_deg) of every dataset whose sidecar gives it,
    else of the IGRF field at the sidecar's site (training.geomag.site_field) when it gives one."""
    from .geomag import site_field
    values = []
    for d in datasets:
        value = (d.meta.get("earth_field") or {}).get(key)
        if value is None:
            try:
                field = site_field(d.meta)
            except ValueError as e:
                raise ModelError(f"{d.name}: {e}") from None
            value = getattr(field, key) if field is not None else None
        if value is not None:
            values.append(float(value))
    return values


def _rate_hz(data: ImuData) -> float:
    """Sample rate [Hz]: sidecar rate_hz, else 1 / median time step."""
    rate = data.meta.get("rate_hz")
    return float(rate) if rate else float(1.0 / np.median(np.diff(data.t)))


def _rest_masks(refs: dict[str, TriadReference], selfcal) -> list[tuple[ImuData, np.ndarray, np.ndarray]]:
    """[(recording, true rate (N, 3) rad/s, rest mask (N,))] of the recordings that show the gyro at
    rest: where the reference rate is below STATIC_RATE, or the self-calibration's rest windows."""
    ref = refs["gyr"]
    if ref.source != "none":
        return [(d, d.ref_gyr, np.all(np.isfinite(d.ref_gyr), axis=1)
                 & (np.linalg.norm(np.nan_to_num(d.ref_gyr, nan=np.inf), axis=1) < STATIC_RATE))
                for d in ref.datasets]
    return [(d, np.zeros_like(d.gyr), mask) for d, mask in zip(ref.datasets, selfcal.rest_masks)]


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) of the True runs of a boolean array at least MIN_REST_RUN samples long."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(int), [0]])))
    return [(a, b) for a, b in zip(edges[::2], edges[1::2]) if b - a >= MIN_REST_RUN]


def _rest_residuals(recordings, model: ThermalModel):
    """[(per-run mean residual (3,), per-run variance (3,), rate_hz)] over the rest runs; residual =
    compensated gyro − true rate [rad/s], finite rows."""
    out = []
    for d, truth, mask in recordings:
        residual = apply_thermal(model, d.gyr, d.temp) - truth
        for a, b in _runs(mask & np.all(np.isfinite(residual), axis=1)):
            out.append((residual[a:b].mean(axis=0), residual[a:b].var(axis=0), _rate_hz(d), b - a))
    return out


def gyro_rest_settings(runs) -> dict[str, float]:
    """gyro_noise, gyro_bias_residual and rest_gyro_threshold from the gyro at rest after calibration.

    runs: [(mean residual (3,), variance (3,), rate_hz, samples)] per rest run. gyro_noise
    [rad/s/√Hz] = σ / √f_s (IEEE Std 952), σ the per-sample std within the runs (RMS over axes);
    gyro_bias_residual [rad/s] = largest |mean| of the residual over all rest samples per axis (not
    below GYRO_BIAS_RESIDUAL_FLOOR); rest_gyro_threshold [rad/s] = max(REST_NOISE_SIGMAS · σ of the
    noisiest axis, REST_BIAS_MARGIN · largest |run mean|): the runtime's rest detector must accept
    every sample of a still sensor (noise) and the bias the calibration leaves (it checks the
    low-passed rate against the threshold too), and no more — a larger threshold takes a slow turn
    for a bias.
    """
    weights = np.array([n for *_, n in runs], dtype=float)
    means = np.array([m for m, *_ in runs])
    variances = np.array([v for _, v, *_ in runs])
    sigma_axis = np.sqrt(np.average(variances, axis=0, weights=weights))
    density = [np.sqrt(np.mean(v)) / np.sqrt(f) for _, v, f, _ in runs]
    bias = np.abs(np.average(means, axis=0, weights=weights))
    return {"gyro_noise": float(np.average(density, weights=weights)),
            "gyro_bias_residual": float(max(bias.max(), GYRO_BIAS_RESIDUAL_FLOOR)),
            "rest_gyro_threshold": float(max(REST_NOISE_SIGMAS * sigma_axis.max(),
                                             REST_BIAS_MARGIN * np.abs(means).max()))}


def _field_settings(datasets: list[ImuData], selfcal, notes: list[str]) -> dict[str, float]:
    """field_norm [µT], field_dip [rad] and declination [rad]: from the sidecars, else from the
    self-calibration of the magnetometer, else the defaults (with a note)."""
    settings, mag = {}, (selfcal.report.get("mag", {}) if selfcal else {})
    norms, dips = _sidecar_values(datasets, "norm_ut"), _sidecar_values(datasets, "dip_deg")
    if norms:
        settings["field_norm"] = float(np.mean(norms))
        if max(norms) - min(norms) > FIELD_NORM_SPREAD:
            notes.append(f"field_norm: sidecar values {norms} µT differ; using their mean")
    elif mag.get("field_norm_ut"):
        settings["field_norm"] = float(mag["field_norm_ut"])
        notes.append(f"field_norm: {settings['field_norm']:.2f} µT from the magnetometer calibration "
                     f"({mag.get('field_norm_source', 'self-calibration')})")
    else:
        notes.append("field_norm: no earth_field.norm_ut in the sidecars and no magnetometer "
                     "calibration; default kept")
    if dips:
        settings["field_dip"] = float(np.deg2rad(np.mean(dips)))
    elif mag.get("dip_deg") is not None:
        settings["field_dip"] = float(np.deg2rad(mag["dip_deg"]))
        notes.append(f"field_dip: {mag['dip_deg']:.2f}° estimated at the rest poses")
    declinations = _sidecar_values(datasets, "declination_deg")
    if declinations:
        settings["declination"] = float(np.deg2rad(np.mean(declinations)))
    return settings


def _pf_settings(datasets: list[ImuData], model: ThermalModel, field_norm: float,
                 notes: list[str]) -> dict[str, float]:
    """Particle-filter settings from the calibrated field of the recordings (training.pf_settings):
    what the filter will see at run time, so that switching it on declares no change that is noise."""
    from .pf_settings import pf_settings_from_calibration
    usable = [d for d in datasets if d.has("mag")]
    if not usable or not model.enabled:
        notes.append("pf_*: no calibrated magnetometer; particle-filter defaults kept")
        return {}
    field = np.concatenate([apply_thermal(model, d.mag, d.temp) for d in usable])
    t = np.concatenate([d.t for d in usable])
    try:
        return pf_settings_from_calibration(field, t, field_norm, float(np.median([_rate_hz(d) for d in usable])))
    except ValueError as e:
        notes.append(f"pf_*: {e}; particle-filter defaults kept")
        return {}


def recommended_settings(datasets: list[ImuData], refs: dict[str, TriadReference],
                         thermal: dict[str, ThermalModel], selfcal, notes: list[str]) -> dict[str, float]:
    """FMU parameter values from the sidecars, the calibration and the sensor at rest (defaults
    otherwise); appends a note for each value left at its default or taken from inconsistent data."""
    settings = settings_defaults()
    settings.update(_field_settings(datasets, selfcal, notes))
    runs = _rest_residuals(_rest_masks(refs, selfcal), thermal["gyr"]) if thermal["gyr"].enabled else []
    if runs:
        settings.update(gyro_rest_settings(runs))
        if len({id(d) for d, *_ in _rest_masks(refs, selfcal)}) < 2:
            notes.append("rest_gyro_threshold: one recording shows only this power-up's bias; record a "
                         "second session (power-cycled) so that train sees the run-to-run bias change")
    else:
        notes.append("gyro_noise, gyro_bias_residual, rest_gyro_threshold: no gyro at rest after "
                     "calibration; defaults kept")
    settings.update(_pf_settings(datasets, thermal["mag"], settings["field_norm"], notes))
    return settings


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


def _elm_stage(datasets: list[ImuData], thermal: dict[str, ThermalModel], seed: int,
               notes: list[str]) -> tuple[dict[str, list[float]], bool, dict]:
    """Fit the field-form ELM on the thermally compensated field against ref_mag.

    Returns ({'elm': block} or {}, enabled, stats). Enabled only when the ELM lowers the field
    error RMS of the held-out data (`_elm_holdout`) by ELM_MIN_GAIN; the block is fitted on all
    the data and kept but off otherwise.
    """
    from . import elm
    usable = [d for d in datasets if d.ref_mag is not None and d.ref_q is not None and d.has("mag")]
    if not usable or not thermal["mag"].enabled:
        notes.append("elm: no magnetometer reference (ref_mag, ref_q) or no fitted magnetometer; "
                     "ELM stage off")
        return {}, False, {}
    prep = elm.CompassPrep(stride=ELM_STRIDE)
    sets = [elm.prepare_compass(_compensated(d, thermal), None, prep, seed) for d in usable]
    errors = []
    for train_x, train_y, test_x, test_y in _elm_holdout(sets):
        fold = elm.ElmFitter(**ELM_FITTER).fit(train_x, train_y, seed)
        errors.append(((test_x - test_y) ** 2, (elm.elm_apply(fold, test_x) - test_y) ** 2))
    before = float(np.sqrt(np.mean(np.concatenate([e for e, _ in errors]))))
    after = float(np.sqrt(np.mean(np.concatenate([e for _, e in errors]))))
    model = elm.ElmFitter(**ELM_FITTER).fit(np.concatenate([s.field for s in sets]),
                                           np.concatenate([s.reference for s in sets]), seed)
    enabled = after <= (1.0 - ELM_MIN_GAIN) * before
    if not enabled:
        notes.append(f"elm: held-out field error {before:.3g} -> {after:.3g} µT is not a "
                     f"{ELM_MIN_GAIN:.0%} gain; ELM stage off")
    stats = {"unit": "µT", "hidden": model.hidden, "folds": len(errors),
             "holdout": "each recording against the others" if len(sets) > 1 else
             f"last {ELM_HOLDOUT_FRACTION:.0%} of the recording in time",
             "rms_before": before, "rms_after": after, "enabled": enabled, "train_time_s": model.train_time_s}
    return {"elm": [float(v) for v in elm.to_block(model)]}, enabled, stats


def _psobp_stage(datasets: list[ImuData], thermal: dict[str, ThermalModel], seed: int,
                 notes: list[str]) -> tuple[dict[str, list[float]], bool, dict]:
    """Fit the residual PSO-BP gyro bias network on the longest recording with a gyro reference
    and temperature (networks see one continuous series: the temperature rate needs it).

    Returns ({'psobp': block} or {}, enabled, stats); enabled by psobp.residual_psobp_wins, which
    fits on the first two thirds and switches the network on only for a held-out gain.
    """
    from . import psobp
    usable = [d for d in datasets if d.ref_gyr is not None and d.has("gyr") and np.isfinite(d.temp).any()]
    if not usable or not thermal["gyr"].enabled:
        notes.append("psobp: no gyro reference with temperature or no fitted gyro; PSO-BP stage off")
        return {}, False, {}
    d = max(usable, key=len)
    gyr = apply_thermal(thermal["gyr"], d.gyr, d.temp)
    try:
        decision = psobp.residual_psobp_wins(d.t, gyr, d.ref_gyr, d.temp, seed)
        fit = psobp.fit_gyro_residual_psobp(d.t, gyr, d.ref_gyr, d.temp, seed)
    except ValueError as e:  # too few static windows with temperature to fit a network
        notes.append(f"psobp: {e}; PSO-BP stage off")
        return {}, False, {}
    if not decision.enable:
        notes.append(f"psobp: held-out residual bias {decision.rms_polynomial:.3g} -> "
                     f"{decision.rms_hybrid:.3g} rad/s is not a {psobp.ENABLE_MIN_GAIN:.0%} gain; stage off")
    stats = {"unit": "rad/s", "recording": d.name, "held_out_windows": decision.windows,
             "rms_polynomial": decision.rms_polynomial, "rms_hybrid": decision.rms_hybrid,
             "enabled": bool(decision.enable)}
    return {"psobp": [float(v) for v in fit.model.to_block()]}, bool(decision.enable), stats


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


def _fit_with_reference(ref: TriadReference, degree: int, seed: int) -> tuple[ThermalModel, dict, list[str]]:
    """Fit one triad against the reference its recordings carry (columns, derived or static):
    the full gain/bias model when the reference moves along every axis, else the bias B(T) only."""
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
    reason = _skip_reason(datasets, triad, raw, target, degree)
    if reason:
        return ThermalModel.identity(enabled=False), {}, [f"{reason}; thermal model disabled"]
    excitation = _weakest_excitation(target)
    if excitation >= MIN_EXCITATION[triad]:
        fit = GainBiasFitter(degree=degree).fit(raw, target, temp, seed, UNITS[triad])
        return fit.model, _fit_stats(fit), notes + _fit_notes(triad, fit, degree)
    if ref.source == "static" and triad != "gyr" and temperature_clusters(temp) < 2:
        return ThermalModel.identity(enabled=False), {}, [
            f"{triad}: a static log at one temperature identifies nothing of the {triad} (its bias and "
            "gains need several poses or a reference); thermal model disabled"]
    model = fit_bias_only(raw, target, temp, min(degree, max(temperature_clusters(temp) - 1, 0)))
    stats = {"unit": UNITS[triad], "bias_only": True, "weakest_excitation": excitation}
    what = ("the temperature drift of the bias only (the absolute bias and the gains are not "
            "identifiable from a static log)") if ref.source == "static" and triad != "gyr" else "the bias B(T) only"
    return model, stats, notes + [f"{triad}: the reference hardly moves (weakest direction {excitation:.3g} "
                          f"{UNITS[triad]} RMS < {MIN_EXCITATION[triad]}): gains not identifiable, "
                          f"fitted {what} (A = I, G = 1)"]


def _self_calibrated(datasets: list[ImuData], triads: list[str], degree: int, progress: bool,
                     notes: list[str]) -> SelfCalResult:
    """Self-calibration from invariants of every recording (training.selfcal) for the triads
    without any reference; the field norm from the sidecars when they give one."""
    norms = _sidecar_values(datasets, "norm_ut")
    result = self_calibrate(datasets, field_norm=float(np.mean(norms)) if norms else None,
                            degree=degree, progress=progress)
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


def _held_out(datasets: list[ImuData], refs: dict[str, TriadReference], degree: int, seed: int,
              selfcal, notes: list[str]) -> dict[str, dict]:
    """Held-out error per triad (training.holdout): the same procedure refitted without the last
    quarter of every recording, scored on it; {} with a note when the recordings are too short."""
    from .holdout import held_out
    from .simulator.earth import STANDARD_GRAVITY
    norms = _sidecar_values(datasets, "norm_ut")
    norm = float(np.mean(norms)) if norms else (selfcal.report.get("mag", {}).get("field_norm_ut") if selfcal else None)

    def fit_selfcal(parts):
        return self_calibrate(parts, field_norm=norm, degree=degree, progress=False).thermal
    try:
        with _deterministic(seed):
            return held_out(datasets, refs, lambda r: _fit_with_reference(r, degree, seed)[0], fit_selfcal,
                            norm, STANDARD_GRAVITY)
    except ValueError as e:
        notes.append(f"held-out error not computed: {e}")
        return {}


def _refuse_identity(thermal: dict[str, ThermalModel], refs: dict[str, TriadReference], selfcal,
                     notes: list[str]) -> None:
    """ModelError naming what is missing when no triad could be calibrated, or when nothing carries a
    reference and the self-calibration identified only the gyro bias at rest (no accelerometer poses,
    no field ellipsoid, no rotation: no motion — a still log, which calibrates the gyro bias only and
    must then say so with "reference": "static" in its sidecar)."""
    hint = " — record the protocol of docs/calibration.md, or pass --allow-identity"
    if not any(m.enabled for m in thermal.values()):
        raise ModelError("nothing could be calibrated: " + "; ".join(
            n for n in notes if any(n.startswith(f"{t}:") for t in TRIAD_ORDER)) + hint)
    moved = thermal["acc"].enabled or thermal["mag"].enabled or not np.array_equal(thermal["gyr"].A, np.eye(3))
    if all(r.source == "none" for r in refs.values()) and not moved:
        names = ", ".join(d.name for d in refs["gyr"].datasets)
        raise ModelError(f"no reference and too little motion in {names}: only the gyro bias at rest is "
                         "identifiable (no accelerometer poses, no field ellipsoid, no rotation between "
                         "rests); a still log must say \"reference\": \"static\" in its sidecar" + hint)


def train(datasets: list[ImuData], seed: int = 0, degree: int = 2,
          progress: bool = True, allow_identity: bool = False) -> ModelArtefact:
    """Fit the gain/bias temperature model of every triad and return the model artefact.

    datasets: calibration recordings. Per triad the best reference any recording offers is used
    (training.reference_source: reference columns, an attitude reference, a static log); a triad
    without any is self-calibrated from invariants (training.selfcal). degree: largest polynomial
    degree (0..MAX_DEGREE). Deterministic given `seed`. Raises ModelError when `datasets` is empty,
    and when no triad can be calibrated unless allow_identity (then an identity model is returned).
    """
    if not datasets:
        raise ModelError("train: no training data given")
    refs = {triad: choose_reference(datasets, triad) for triad in TRIAD_ORDER}
    thermal, stats, notes = {}, {}, []
    with _deterministic(seed):
        referenced = [t for t in TRIAD_ORDER if refs[t].source != "none"]
        for triad in tqdm(referenced, desc="reference fit", disable=not progress or not referenced):
            thermal[triad], stats[triad], fit_notes = _fit_with_reference(refs[triad], degree, seed)
            notes += list(refs[triad].notes) + fit_notes
        blind = [t for t in TRIAD_ORDER if refs[t].source == "none"]
        selfcal = _self_calibrated(datasets, blind, degree, progress, notes) if blind else None
        for triad in blind:
            thermal[triad], stats[triad] = selfcal.thermal[triad], selfcal.report.get(triad, {})
        for triad in TRIAD_ORDER:
            stats.setdefault(triad, {})["reference"] = refs[triad].source
        prepared = _prepared_datasets(datasets, refs)
        blocks, elm_on, stats["elm"] = _elm_stage(prepared, thermal, seed, notes)
        psobp_block, psobp_on, stats["psobp"] = _psobp_stage(prepared, thermal, seed, notes)
    if not allow_identity:
        _refuse_identity(thermal, refs, selfcal, notes)
    for triad, score in _held_out(datasets, refs, degree, seed, selfcal, notes).items():
        stats[triad]["held_out"] = score
    blocks.update(psobp_block)
    stats = {k: v for k, v in stats.items() if v}
    settings = recommended_settings(datasets, refs, thermal, selfcal, notes)
    settings["enable_elm"] = float(elm_on)
    settings["enable_psobp"] = float(psobp_on)
    return ModelArtefact(seed=seed, thermal=thermal, settings=settings, fit_stats=stats,
                         training_data=[{"name": d.name, "samples": len(d)} for d in datasets],
                         notes=notes, blocks=blocks)
