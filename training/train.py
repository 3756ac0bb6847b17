"""`train`: fit the per-triad gain/bias temperature models and build the model artefact."""
from __future__ import annotations

from contextlib import contextmanager

import numpy as np
import torch
from tqdm import tqdm

from .artefact import ModelArtefact
from .dataset import ImuData
from .errors import ModelError
from .layout import TRIAD_ORDER, settings_defaults
from .thermal import (GainBiasFitter, ThermalFit, ThermalModel, apply_thermal, normalised_temperature,
                      temperature_normalisation)

#: The ELM stage is switched on only when it lowers the held-out field error RMS of the
#: calibration data by at least this fraction: a smaller gain is within what a different random
#: split moves, and an ELM that does not clearly help is not worth its risk on other data.
ELM_MIN_GAIN = 0.10
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
    """earth_field[key] of every dataset whose sidecar gives it."""
    values = [(d.meta.get("earth_field") or {}).get(key) for d in datasets]
    return [float(v) for v in values if v is not None]


def _rate_hz(data: ImuData) -> float:
    """Sample rate [Hz]: sidecar rate_hz, else 1 / median time step."""
    rate = data.meta.get("rate_hz")
    return float(rate) if rate else float(1.0 / np.median(np.diff(data.t)))


def _gyro_residuals(datasets: list[ImuData], model: ThermalModel):
    """[(residual (M, 3) rad/s, true rate (M, 3) rad/s, rate_hz)] per dataset with gyro
    reference, finite rows only; residual = corrected gyro - true rate."""
    out = []
    for d in datasets:
        if d.ref_gyr is None or len(d) < 2:
            continue
        res = apply_thermal(model, d.gyr, d.temp) - d.ref_gyr
        ok = np.all(np.isfinite(res), axis=1)
        if ok.any():
            out.append((res[ok], d.ref_gyr[ok], _rate_hz(d)))
    return out


def _gyro_settings(residuals) -> dict[str, float]:
    """gyro_noise and gyro_bias_residual from the gyro fit residuals.

    gyro_noise [rad/s/√Hz]: white-noise density N = σ / √f_s (σ per-sample std at rate f_s,
    IEEE Std 952 convention), σ = RMS over axes of the residual std, row-weighted mean over
    the datasets. gyro_bias_residual [rad/s]: largest per-axis |mean residual| over static
    rows (all rows when none is static), not below GYRO_BIAS_RESIDUAL_FLOOR.
    """
    rows = np.array([len(r) for r, _, _ in residuals], dtype=float)
    density = [np.sqrt(np.mean(np.var(r, axis=0))) / np.sqrt(f) for r, _, f in residuals]
    res = np.concatenate([r for r, _, _ in residuals])
    ref = np.concatenate([w for _, w, _ in residuals])
    static = np.linalg.norm(ref, axis=1) < STATIC_RATE
    bias = np.max(np.abs(np.mean(res[static] if static.any() else res, axis=0)))
    return {"gyro_noise": float(np.average(density, weights=rows)),
            "gyro_bias_residual": float(max(bias, GYRO_BIAS_RESIDUAL_FLOOR))}


def recommended_settings(datasets: list[ImuData], thermal: dict[str, ThermalModel],
                         notes: list[str]) -> dict[str, float]:
    """FMU parameter values from the data's sidecars and the gyro fit (defaults otherwise);
    appends a note for each value left at its default or taken from inconsistent data."""
    settings = settings_defaults()
    norms = _sidecar_values(datasets, "norm_ut")
    if norms:
        settings["field_norm"] = float(np.mean(norms))
        if max(norms) - min(norms) > FIELD_NORM_SPREAD:
            notes.append(f"field_norm: sidecar values {norms} µT differ; using their mean")
    else:
        notes.append("field_norm: no earth_field.norm_ut in the sidecars; default kept")
    declinations = _sidecar_values(datasets, "declination_deg")
    if declinations:
        settings["declination"] = float(np.deg2rad(np.mean(declinations)))
    residuals = _gyro_residuals(datasets, thermal["gyr"]) if thermal["gyr"].enabled else []
    if residuals:
        settings.update(_gyro_settings(residuals))
    else:
        notes.append("gyro_noise, gyro_bias_residual: no fitted gyro; defaults kept")
    return settings


def _compensated(d: ImuData, thermal: dict[str, ThermalModel]) -> ImuData:
    """A copy of d whose raw triads are replaced by the thermally compensated ones."""
    c = d.slice(slice(None))
    c.gyr, c.acc, c.mag = (apply_thermal(thermal[k], getattr(d, k), d.temp) for k in ("gyr", "acc", "mag"))
    return c


def _elm_stage(datasets: list[ImuData], thermal: dict[str, ThermalModel], seed: int,
               notes: list[str]) -> tuple[dict[str, list[float]], bool, dict]:
    """Fit the field-form ELM on the thermally compensated field against ref_mag.

    Returns ({'elm': block} or {}, enabled, stats). Enabled only when the ELM lowers the
    held-out (10 %) field error RMS by ELM_MIN_GAIN; otherwise the block is kept but off.
    """
    from . import elm
    usable = [d for d in datasets if d.ref_mag is not None and d.ref_q is not None and d.has("mag")]
    if not usable or not thermal["mag"].enabled:
        notes.append("elm: no magnetometer reference (ref_mag, ref_q) or no fitted magnetometer; "
                     "ELM stage off")
        return {}, False, {}
    prep = elm.CompassPrep(stride=ELM_STRIDE)
    sets = [elm.prepare_compass(_compensated(d, thermal), None, prep, seed) for d in usable]
    field = np.concatenate([s.field for s in sets])
    ref = np.concatenate([s.reference for s in sets])
    train = np.concatenate([s.train + o for s, o in zip(sets, np.cumsum([0] + [len(s.field) for s in sets]))])
    test = np.setdiff1d(np.arange(len(field)), train)
    model = elm.ElmFitter(**ELM_FITTER).fit(field[train], ref[train], seed)
    before = float(np.sqrt(np.mean((field[test] - ref[test]) ** 2)))
    after = float(np.sqrt(np.mean((elm.elm_apply(model, field[test]) - ref[test]) ** 2)))
    enabled = after <= (1.0 - ELM_MIN_GAIN) * before
    if not enabled:
        notes.append(f"elm: held-out field error {before:.3g} -> {after:.3g} µT is not a "
                     f"{ELM_MIN_GAIN:.0%} gain; ELM stage off")
    stats = {"unit": "µT", "hidden": model.hidden, "rows_train": int(len(train)),
             "rows_test": int(len(test)), "rms_before": before, "rms_after": after,
             "enabled": enabled, "train_time_s": model.train_time_s}
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


def train(datasets: list[ImuData], seed: int = 0, degree: int = 2,
          progress: bool = True) -> ModelArtefact:
    """Fit the gain/bias temperature model of every triad and return the model artefact.

    datasets: calibration recordings with references (ref_gyr / ref_acc / ref_mag); they
    are concatenated. A triad without reference, with all-NaN raw data or with too few rows
    gets a disabled identity model and a note. degree: polynomial degree (0..MAX_DEGREE).
    Deterministic given `seed`. Raises ModelError when `datasets` is empty.
    """
    if not datasets:
        raise ModelError("train: no training data given")
    temp = np.concatenate([d.temp for d in datasets]).astype(np.float64)
    thermal, stats, notes = {}, {}, []
    with _deterministic(seed):
        for triad in tqdm(TRIAD_ORDER, desc="thermal fit", disable=not progress):
            raw, ref = _stack(datasets, triad), _stack(datasets, f"ref_{triad}")
            reason = _skip_reason(datasets, triad, raw, ref, degree)
            if reason:
                notes.append(f"{reason}; thermal model disabled")
                thermal[triad] = ThermalModel.identity(enabled=False)
                continue
            excitation = _weakest_excitation(ref)
            if excitation < MIN_EXCITATION[triad]:
                thermal[triad] = fit_bias_only(raw, ref, temp, degree)
                stats[triad] = {"unit": UNITS[triad], "bias_only": True, "weakest_excitation": excitation}
                notes.append(f"{triad}: the reference hardly moves (weakest direction {excitation:.3g} "
                             f"{UNITS[triad]} RMS < {MIN_EXCITATION[triad]}): gains not identifiable, "
                             "fitted the bias B(T) only (A = I, G = 1)")
                continue
            fit = GainBiasFitter(degree=degree).fit(raw, ref, temp, seed, UNITS[triad])
            thermal[triad], stats[triad] = fit.model, _fit_stats(fit)
            notes += _fit_notes(triad, fit, degree)
        blocks, elm_on, stats["elm"] = _elm_stage(datasets, thermal, seed, notes)
        psobp_block, psobp_on, stats["psobp"] = _psobp_stage(datasets, thermal, seed, notes)
    blocks.update(psobp_block)
    stats = {k: v for k, v in stats.items() if v}
    settings = recommended_settings(datasets, thermal, notes)
    settings["enable_elm"] = float(elm_on)
    settings["enable_psobp"] = float(psobp_on)
    return ModelArtefact(seed=seed, thermal=thermal, settings=settings, fit_stats=stats,
                         training_data=[{"name": d.name, "samples": len(d)} for d in datasets],
                         notes=notes, blocks=blocks)
