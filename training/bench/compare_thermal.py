"""Gyro temperature compensation compared as the PSO-BP papers compare it.

Models, all trained on the static training part of each recording and judged on the rest:
  uncompensated        b = 0
  single polynomial    the gain/bias model's bias term B(Tn) (training/models/thermal.py), degree P
  piecewise polynomial, 3 equal-width bands
                       independent degree-P polynomials on PIECEWISE_SEGMENTS equal-width
                       temperature bands of the training range
  BP                   2-H-1 networks per axis from uniform random weights (training/models/psobp.py),
                       the product's fit (window targets, Rprop, patience stop, inputs clamped)
  PSO-BP, the source's form (issue 4)
                       the same networks from the particle-swarm start, whole bias from T and
                       dT/dt (MODE_FULL), every switch in its source form (psobp.SOURCE_FORM)
  + ...                the product's additions one at a time, cumulative (psobp.ADDITIONS);
                       rows that differ only in clamp_inputs share one fit (and its time)
  PSO-BP (a): + ...    the last addition: (a) is MODE_FULL with the fitter's defaults
  poly + PSO-BP (b) without the shrinkage
                       the single polynomial plus a PSO-BP network trained on the bias left
                       after it (MODE_RESIDUAL), output not shrunk
  poly + PSO-BP (b)    the product's hybrid: as above, its output shrunk by an inner
                       validation on the training rows (fit_gyro_residual_psobp)

Metrics on the validation rows, residual e = gyr - ref_gyr - b_hat (per axis, then averaged):
  residual bias RMS [°/s]     RMS of the `window_s` window means of e (white noise averaged out)
  100 s variance [(°/s)²]      variance of the non-overlapping 100 s means of e
  bias stability [°/h]         the standard zero-bias stability (GJB 2426-2004, IEEE Std 952
                               static drift test): sample standard deviation of the 10 s means
                               of e; the acceptance figure (it sees the thermal drift the
                               models remove, over the whole held-out temperature range)
  Allan minimum [°/h]          minimum over tau of the overlapping Allan deviation of e
                               (IEEE Std 952 "bias instability" read-off; samples taken as
                               uniformly spaced at the median step); white noise and the bias
                               walk set it at short tau, so thermal models barely move it
  training time [s]            process CPU time of the fit (time.process_time, insensitive to
                               other processes' load), mean, standard deviation, CV = sd/mean;
                               for (b) polynomial + inner validation + final network
  output shrinkage (b)         per-axis scale s in [0, 1] folded into (b)'s output layer
Repeated `runs` times with seeds seed, seed+1, ...; the polynomials are deterministic (their
spread is timing only).

`as_written=True` gives the PSO-BP paper's comparison as written (issue 33 item 5) beside the
product's variant of each comparator (AS_WRITTEN_MODELS):
  piecewise polynomial as written   one segment per temperature point: WRITTEN_SEGMENTS bands of
                                    equal window count (edges at the quantiles of the training
                                    temperatures; on the protocol one band per training plateau)
  BP as written                     plain BP from uniform random weights in the source's form of
                                    every switch (psobp.SOURCE_FORM: single-sample targets, plain
                                    gradient descent over the whole budget, inputs not clamped)
  PSO-BP, the source's form         as in the product table
next to the single polynomial, the 3-band piecewise polynomial, the product's BP, (a) and (b).
"""
from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from contract.errors import DataError
from training.data.io import read_imu_csv
from training.models.psobp import (MODE_RESIDUAL, PsoBpFitter, apply_psobp, bias_targets, cumulative_forms,
                                   fit_gyro_residual_psobp, temperature_rate)
from training.models.thermal import (ThermalModel, apply_thermal, normalised_temperature,
                                     temperature_normalisation)

DPS = 180.0 / np.pi
#: Averaging time of the paper's "100 s variance" [s].
VARIANCE_WINDOW_S = 100.0
#: Averaging time of the standard bias-stability figure (GJB 2426 / IEEE Std 952: 10 s) [s].
STABILITY_WINDOW_S = 10.0
#: The row of the source's form, and the row of the product's MODE_FULL fit.
SOURCE = "PSO-BP, the source's form (issue 4)"
FULL = "PSO-BP (a)"
#: Rows from the source's form to (a), one per `cumulative_forms` entry, each naming what it adds
#: to the row above.
FORM_ROWS = tuple(SOURCE if not added else f"+ {added}" if k < len(cumulative_forms()) - 1
                  else f"{FULL}: + {added}" for k, (added, _, _) in enumerate(cumulative_forms()))
UNSHRUNK = "poly + PSO-BP (b) without the shrinkage"
HYBRID = "poly + PSO-BP (b)"
#: Bands of the product's piecewise polynomial, and of the paper's (one per training temperature
#: point: the four training plateaus of the protocol).
PIECEWISE_SEGMENTS = 3
WRITTEN_SEGMENTS = 4
#: Band rules of `fit_piecewise`: equal width over the training range, or equal window count
#: (edges at the quantiles of the training temperatures).
BAND_RULES = ("width", "count")
PIECEWISE = f"piecewise polynomial, {PIECEWISE_SEGMENTS} equal-width bands"
PIECEWISE_WRITTEN = f"piecewise polynomial as written: {WRITTEN_SEGMENTS} bands, one per temperature point"
BP_WRITTEN = "BP as written: gradient descent on single samples, whole budget, inputs not clamped"
#: The product table (the source-form ablation) and the paper's table as written.
MODELS = ("uncompensated", "single polynomial", PIECEWISE, "BP", *FORM_ROWS, UNSHRUNK, HYBRID)
AS_WRITTEN_MODELS = ("uncompensated", "single polynomial", PIECEWISE, PIECEWISE_WRITTEN, "BP", BP_WRITTEN,
                     SOURCE, FORM_ROWS[-1], HYBRID)


# ----------------------------------------------------------------------------- metrics


def window_means(t: np.ndarray, x: np.ndarray, window_s: float) -> np.ndarray:
    """Means (M, ...) of x (N, ...) over non-overlapping windows [t0 + k w, t0 + (k+1) w)."""
    bins = np.floor((t - t[0]) / window_s).astype(np.int64)
    _, index, counts = np.unique(bins, return_inverse=True, return_counts=True)
    x2 = x.reshape(x.shape[0], -1)
    out = np.column_stack([np.bincount(index, weights=x2[:, k]) / counts for k in range(x2.shape[1])])
    return out.reshape((counts.shape[0],) + x.shape[1:])


def allan_deviation(x: np.ndarray, dt: float, points: int = 40) -> tuple[np.ndarray, np.ndarray]:
    """Overlapping Allan deviation of a rate series x (N,) sampled every dt [s].

    sigma²(m dt) = sum_k (theta_{k+2m} - 2 theta_{k+m} + theta_k)² / (2 (m dt)² (N - 2m)),
    theta = cumulative sum of x dt (IEEE Std 952-1997, annex C). m on a log grid up to N/3.
    Returns (tau (K,) [s], adev (K,) in x's unit).
    """
    theta = np.concatenate([[0.0], np.cumsum(x) * dt])
    n = x.shape[0]
    ms = np.unique(np.logspace(0, np.log10(max(n // 3, 1)), points).astype(np.int64))
    adev = np.array([np.sqrt(np.sum((theta[2 * m:] - 2 * theta[m:-m] + theta[:-2 * m]) ** 2)
                             / (2.0 * (m * dt) ** 2 * (n + 1 - 2 * m))) for m in ms])
    return ms * dt, adev


def bias_stability(t: np.ndarray, e: np.ndarray, window_s: float = STABILITY_WINDOW_S) -> np.ndarray:
    """Zero-bias stability per axis (3,) in e's unit: B_s = sqrt(sum_i (F_i - F_mean)² / (n - 1))
    over the n non-overlapping window_s means F_i of the static residual e (N, 3) at t (N,) [s]
    (GJB 2426-2004 §5.8; IEEE Std 952 static drift, 10 s averaging)."""
    return np.std(window_means(t, e, window_s), axis=0, ddof=1)


def residual_metrics(t: np.ndarray, e: np.ndarray, window_s: float) -> dict:
    """Metrics of a residual e (N, 3) [rad/s] at times t (N,) [s] (see the module docstring)."""
    e_dps = e * DPS
    w = window_means(t, e_dps, window_s)
    v = window_means(t, e_dps, VARIANCE_WINDOW_S)
    dt = float(np.median(np.diff(t)))
    allan = [float(np.min(allan_deviation(e_dps[:, i], dt)[1])) * 3600.0 for i in range(3)]
    stability = (bias_stability(t, e_dps) * 3600.0).tolist()
    return {"rms_dps": float(np.sqrt(np.mean(w ** 2))),
            "rms_dps_axis": [float(np.sqrt(np.mean(w[:, i] ** 2))) for i in range(3)],
            "var100_dps2": float(np.mean(np.var(v, axis=0))),
            "stability_dph": float(np.mean(stability)), "stability_dph_axis": stability,
            "allan_min_dph": float(np.mean(allan)), "allan_min_dph_axis": allan}


# ----------------------------------------------------------------------------- polynomials


@dataclass(frozen=True)
class PiecewisePolynomial:
    """Independent polynomials b(T) per temperature band: edges (K+1,) [°C], per band a
    ThermalModel bias polynomial (A = I, g = 0). Outside the edges the end bands extrapolate."""

    edges: np.ndarray
    bands: tuple[ThermalModel, ...]

    def bias(self, temp: np.ndarray) -> np.ndarray:
        """Bias (N, 3) [rad/s] at temperatures (N,) [°C]."""
        k = np.clip(np.searchsorted(self.edges, temp, side="right") - 1, 0, len(self.bands) - 1)
        out = np.empty((temp.shape[0], 3))
        for j, band in enumerate(self.bands):
            sel = k == j
            out[sel] = polynomial_bias(band, temp[sel])
        return out


def fit_bias_polynomial(temp: np.ndarray, bias: np.ndarray, degree: int) -> ThermalModel:
    """Least-squares bias polynomial B(Tn) of the gain/bias model (training/models/thermal.py) with
    A = I and G = 1, on static targets: temp (M,) [°C], bias (M, 3) [rad/s].

    With ref_gyr = 0 the full gain/bias fit is degenerate (A = 0 fits a zero reference), so
    only its bias term is fitted, in its own normalisation Tn = (T - t0) / ts."""
    t0, ts = temperature_normalisation(temp)
    degree = min(degree, max(temp.shape[0] - 1, 0))
    tn = normalised_temperature(temp, t0, ts)
    vand = np.stack([tn ** k for k in range(degree + 1)], axis=1)
    b = np.linalg.lstsq(vand, bias, rcond=None)[0].T
    return ThermalModel(True, t0, ts, degree, np.eye(3), np.zeros((3, degree)), b)


def polynomial_bias(model: ThermalModel, temp: np.ndarray) -> np.ndarray:
    """B(Tn) (N, 3): with A = I and G = 1, apply_thermal(model, 0, T) = -B(Tn)."""
    return -apply_thermal(model, np.zeros((temp.shape[0], 3)), temp)


def fit_piecewise(temp: np.ndarray, bias: np.ndarray, degree: int, segments: int,
                  bands: str = "width") -> PiecewisePolynomial:
    """One degree-`degree` polynomial per temperature band, on static targets temp (M,) [°C], bias
    (M, 3) [rad/s]. bands "width": `segments` equal-width bands over the training range; "count":
    bands of equal target count (edges at the k/segments quantiles of temp) -- on a plateau
    protocol with `segments` training plateaus of equal duration, one band per plateau."""
    if bands not in BAND_RULES:
        raise ValueError(f"band rule {bands!r} is not one of {BAND_RULES}")
    cuts = np.linspace(0.0, 1.0, segments + 1)
    edges = (np.linspace(temp.min(), temp.max(), segments + 1) if bands == "width"
             else np.quantile(temp, cuts))
    k = np.clip(np.searchsorted(edges, temp, side="right") - 1, 0, segments - 1)
    return PiecewisePolynomial(edges, tuple(fit_bias_polynomial(temp[k == j], bias[k == j], degree)
                                            for j in range(segments)))


# ----------------------------------------------------------------------------- harness


def _split(t: np.ndarray, fraction: float) -> np.ndarray:
    """Boolean training mask: t < t0 + fraction (t_last - t0 + median step)."""
    span = t[-1] - t[0] + float(np.median(np.diff(t)))
    return t < t[0] + fraction * span


@dataclass(frozen=True)
class _Run:
    """What every row of one run shares: the recording, its training mask (N,), the settings and
    the causally held temperature (N,) [°C] at which the polynomials are evaluated."""

    data: object
    train: np.ndarray
    settings: dict
    held: np.ndarray

    @classmethod
    def prepare(cls, data, train, settings: dict) -> "_Run":
        """Hold the temperature (NaN -> last finite value)."""
        held = temperature_rate(data.t, data.temp, settings["tau_s"], float(np.nanmean(data.temp)))[0]
        return cls(data, train, settings, held)

    def forms(self) -> list[tuple[str, dict, bool]]:
        """`psobp.cumulative_forms` at this run's window: the source's form first, (a) last."""
        return cumulative_forms(window_s=self.settings["window_s"])

    def common(self) -> dict:
        """PsoBpFitter arguments every network row shares."""
        s = self.settings
        return dict(hidden=s["hidden"], tau_s=s["tau_s"], window_s=s["window_s"], rest_rad_s=s["rest_rad_s"],
                    epochs=s["bp_epochs"])

    def network(self, seed: int, clamp: bool, gyr=None, **fitter) -> tuple:
        """(predicted bias (N, 3) [rad/s], CPU s, PsoBpFit) of one PsoBpFitter fitted on the training
        rows of `gyr` (default the raw gyro) and run over the whole recording."""
        d, tr = self.data, self.train
        gyr = d.gyr if gyr is None else gyr
        fit = PsoBpFitter(**{**self.common(), **fitter}).fit(d.t[tr], gyr[tr], d.ref_gyr[tr], d.temp[tr], seed)
        return apply_psobp(fit.model, d.t, d.temp, clamp_inputs=clamp), fit.cpu_seconds, fit


def _polynomial(run: _Run) -> tuple:
    """(bias (N, 3) [rad/s], CPU s of targets and fit, None): the single polynomial."""
    start = time.process_time()
    d, tr, s = run.data, run.train, run.settings
    tw, _, bw = bias_targets(d.t[tr], d.gyr[tr], d.ref_gyr[tr], d.temp[tr], s["tau_s"], s["window_s"],
                             s["rest_rad_s"])
    poly = polynomial_bias(fit_bias_polynomial(tw, bw, s["degree"]), run.held)
    return poly, time.process_time() - start, None


def _piecewise(run: _Run, segments: int, bands: str) -> tuple:
    """(bias (N, 3) [rad/s], CPU s of targets and fit, None): a piecewise polynomial."""
    start = time.process_time()
    d, tr, s = run.data, run.train, run.settings
    tw, _, bw = bias_targets(d.t[tr], d.gyr[tr], d.ref_gyr[tr], d.temp[tr], s["tau_s"], s["window_s"],
                             s["rest_rad_s"])
    piece = fit_piecewise(tw, bw, s["degree"], segments, bands)
    return piece.bias(run.held), time.process_time() - start, None


def _unshrunk(run: _Run, poly: tuple, seed: int) -> tuple:
    """(b) without the shrinkage: the residual network on the gyro after the polynomial `poly` (as
    `_polynomial` returns it); the time includes the polynomial's."""
    bias, seconds, fit = run.network(seed, True, gyr=run.data.gyr - poly[0], mode=MODE_RESIDUAL)
    return poly[0] + bias, poly[1] + seconds, fit


def _hybrid(run: _Run, poly: tuple, seed: int) -> tuple:
    """(b): as `_unshrunk`, the output shrunk by the inner validation (fit_gyro_residual_psobp)."""
    d, tr = run.data, run.train
    compensated = d.gyr - poly[0]
    fit = fit_gyro_residual_psobp(d.t[tr], compensated[tr], d.ref_gyr[tr], d.temp[tr], seed, **run.common())
    return poly[0] + apply_psobp(fit.model, d.t, d.temp), poly[1] + fit.cpu_seconds, fit


def _one_run(data, train, settings: dict, seed: int) -> dict:
    """Fit every model of MODELS on the training rows: per model (predicted bias (N, 3) [rad/s], CPU
    seconds of the fit, PsoBpFit or None)."""
    run = _Run.prepare(data, train, settings)
    poly = _polynomial(run)
    out = {"uncompensated": (np.zeros_like(data.gyr), 0.0, None), "single polynomial": poly,
           PIECEWISE: _piecewise(run, PIECEWISE_SEGMENTS, "width"), "BP": run.network(seed, True, use_pso=False)}
    fits = {}
    for name, (_, switches, clamp) in zip(FORM_ROWS, run.forms()):
        key = tuple(sorted(switches.items()))
        if key not in fits:  # rows that differ only in clamp_inputs share one fit
            fits[key] = run.network(seed, clamp, **switches)[2]
        fit = fits[key]
        out[name] = (apply_psobp(fit.model, data.t, data.temp, clamp_inputs=clamp), fit.cpu_seconds, fit)
    out[UNSHRUNK] = _unshrunk(run, poly, seed)
    out[HYBRID] = _hybrid(run, poly, seed)
    return out


def _as_written_run(data, train, settings: dict, seed: int) -> dict:
    """Fit every model of AS_WRITTEN_MODELS on the training rows (as `_one_run`): the paper's
    comparators as written beside the product's variant of each."""
    run = _Run.prepare(data, train, settings)
    poly = _polynomial(run)
    forms = run.forms()
    (_, source, source_clamp), (_, product, product_clamp) = forms[0], forms[-1]
    return {"uncompensated": (np.zeros_like(data.gyr), 0.0, None), "single polynomial": poly,
            PIECEWISE: _piecewise(run, PIECEWISE_SEGMENTS, "width"),
            PIECEWISE_WRITTEN: _piecewise(run, WRITTEN_SEGMENTS, "count"),
            "BP": run.network(seed, True, use_pso=False),
            BP_WRITTEN: run.network(seed, source_clamp, use_pso=False, **source),
            SOURCE: run.network(seed, source_clamp, **source),
            FORM_ROWS[-1]: run.network(seed, product_clamp, **product),
            HYBRID: _hybrid(run, poly, seed)}


def _summary(values: list[float]) -> dict:
    """Mean, standard deviation, min and max of a list."""
    a = np.asarray(values, dtype=np.float64)
    return {"mean": float(a.mean()), "std": float(a.std()), "min": float(a.min()),
            "max": float(a.max()), "cv": float(a.std() / a.mean()) if a.mean() else 0.0}


def _compare_one(path: Path, out_dir: Path, runs: int, seed: int, settings: dict,
                 progress: bool) -> dict:
    """Monte-Carlo comparison on one recording; writes its plots; returns its results."""
    from tqdm import tqdm
    data = read_imu_csv(path)
    if data.ref_gyr is None:
        if data.meta.get("reference") != "static":
            raise DataError(path, "no ref_gyr columns and the sidecar does not say \"reference\": \"static\"; "
                                  "compare-thermal needs the true rate of the gyro")
        data.ref_gyr = np.zeros_like(data.gyr)
    train = _split(data.t, settings["train_fraction"])
    valid = ~train & np.all(np.isfinite(data.gyr - data.ref_gyr), axis=1)
    models, one_run = (AS_WRITTEN_MODELS, _as_written_run) if settings["as_written"] else (MODELS, _one_run)
    trained = models[1:]
    metrics = {m: [] for m in models}
    times = {m: [] for m in trained}
    epochs = {}
    shrinkage = []
    first = None
    for run in tqdm(range(runs), desc=f"compare-thermal {data.name}", disable=not progress):
        result = one_run(data, train, settings, seed + run)
        first = first or result
        for m in models:
            e = data.gyr[valid] - data.ref_gyr[valid] - result[m][0][valid]
            metrics[m].append(residual_metrics(data.t[valid], e, settings["window_s"]))
        for m in trained:
            times[m].append(result[m][1])
            if result[m][2] is not None:  # a network row
                epochs.setdefault(m, []).append(float(result[m][2].epochs))
        shrinkage.append(result[HYBRID][2].shrinkage)
    summary = {}
    for m in models:
        summary[m] = {k: _summary([r[k] for r in metrics[m]])
                      for k in ("rms_dps", "var100_dps2", "stability_dph", "allan_min_dph")}
        summary[m]["rms_dps_axis"] = np.mean([r["rms_dps_axis"] for r in metrics[m]], axis=0).tolist()
        for k in ("stability_dph", "allan_min_dph"):
            summary[m][k.replace("_dph", "_improvement_pct")] = 100.0 * (
                1.0 - summary[m][k]["mean"] / summary["uncompensated"][k]["mean"])
        if m in times:
            summary[m]["train_seconds"] = _summary(times[m])
        if m in epochs:
            summary[m]["bp_epochs"] = _summary(epochs[m])
    summary[HYBRID]["output_shrinkage"] = {"mean": np.mean(shrinkage, axis=0).tolist(),
                                           "std": np.std(shrinkage, axis=0).tolist()}
    plots = _plots(data, train, valid, first, times, settings, out_dir)
    return {"recording": str(path), "name": data.name, "samples": len(data),
            "train_samples": int(train.sum()), "validation_samples": int(valid.sum()),
            "train_temp_c": [float(np.nanmin(data.temp[train])), float(np.nanmax(data.temp[train]))],
            "validation_temp_c": [float(np.nanmin(data.temp[valid])), float(np.nanmax(data.temp[valid]))],
            "models": summary, "plots": plots}


def _plots(data, train, valid, first: dict, times: dict, settings: dict, out_dir: Path) -> list[str]:
    """Bias vs temperature, validation residuals over time, Allan deviation, training times."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    names = []
    w = settings["window_s"]
    t, measured = data.t, (data.gyr - data.ref_gyr) * DPS
    fig, axes = plt.subplots(3, 1, figsize=(8, 9), sharex=True)
    tm = window_means(t, np.column_stack([data.temp, measured]), w)
    for i, ax in enumerate(axes):
        ax.plot(tm[:, 0], tm[:, 1 + i], ".", ms=2, color="0.6", label="measured (window means)")
        for m in first:
            if m == "uncompensated":
                continue
            pm = window_means(t, np.column_stack([data.temp, first[m][0][:, i] * DPS]), w)
            ax.plot(pm[:, 0], pm[:, 1], ".", ms=2, label=m)
        ax.set_ylabel(f"bias {'xyz'[i]} [°/s]")
    axes[-1].set_xlabel("temperature [°C]")
    axes[0].legend(fontsize=7, markerscale=4)
    names.append(_save(fig, out_dir, f"{data.name}_bias_vs_temperature.png"))
    fig, axes = plt.subplots(3, 1, figsize=(8, 9), sharex=True)
    for i, ax in enumerate(axes):
        for m in first:
            e = window_means(t[valid], measured[valid, i] - first[m][0][valid, i] * DPS, w)
            ax.plot(window_means(t[valid], t[valid], w), e, lw=0.8, label=m)
        ax.set_ylabel(f"residual {'xyz'[i]} [°/s]")
    axes[-1].set_xlabel("time [s] (validation part)")
    axes[0].legend(fontsize=7)
    names.append(_save(fig, out_dir, f"{data.name}_residuals.png"))
    fig, ax = plt.subplots(figsize=(7, 5))
    dt = float(np.median(np.diff(t[valid])))
    for m in first:
        curves = [allan_deviation(measured[valid, i] - first[m][0][valid, i] * DPS, dt) for i in range(3)]
        ax.loglog(curves[0][0], np.mean([c[1] for c in curves], axis=0) * 3600.0, label=m)
    ax.set_xlabel("τ [s]")
    ax.set_ylabel("overlapping Allan deviation, mean of axes [°/h]")
    ax.grid(True, which="both", lw=0.3)
    ax.legend(fontsize=7)
    names.append(_save(fig, out_dir, f"{data.name}_allan.png"))
    fig, ax = plt.subplots(figsize=(8, 5))
    networks = [m for m in first if first[m][2] is not None]
    ax.boxplot([times[m] for m in networks])
    ax.set_xticks(range(1, len(networks) + 1), networks, rotation=30, ha="right", fontsize=7)
    ax.set_ylabel("training CPU time [s]")
    names.append(_save(fig, out_dir, f"{data.name}_training_time.png"))
    return names


def _save(fig, out_dir: Path, name: str) -> str:
    """Save and close a figure; return its file name."""
    fig.tight_layout()
    fig.savefig(out_dir / name, dpi=110)
    import matplotlib.pyplot as plt
    plt.close(fig)
    return name


def _markdown(results: dict) -> str:
    """The human report."""
    s = results["settings"]
    lines = ["# Gyro temperature compensation: PSO-BP vs polynomial models", "",
             f"{results['runs']} Monte-Carlo runs (seeds {results['seed']}..{results['seed'] + results['runs'] - 1}); "
             f"training = first {s['train_fraction']:.4g} of each recording by time, validation = the rest. "
             f"Networks 2-{s['hidden']}-1 per axis, rate low-pass τ = {s['tau_s']} s, BP budget "
             f"{s['bp_epochs']} epochs; polynomials degree {s['degree']}, piecewise in {s['segments']} "
             f"equal-width temperature bands"
             + (f" and, as written, in {s['written_segments']} equal-count bands (one per temperature point)"
                if s["as_written"] else "") + f". Residual RMS on {s['window_s']} s window means; bias stability = "
             f"standard deviation of the {STABILITY_WINDOW_S:g} s means (GJB 2426 / IEEE Std 952, the "
             "acceptance figure), Allan min = minimum of the overlapping Allan deviation, both °/h, "
             "mean of the three axes; training time = process CPU seconds (CV = sd / mean).", ""]
    for rec in results["recordings"]:
        lines += [f"## {rec['name']}", "",
                  f"`{rec['recording']}`: {rec['samples']} samples, training {rec['train_samples']} "
                  f"({rec['train_temp_c'][0]:.1f}..{rec['train_temp_c'][1]:.1f} °C), validation "
                  f"{rec['validation_samples']} ({rec['validation_temp_c'][0]:.1f}.."
                  f"{rec['validation_temp_c'][1]:.1f} °C).", "",
                  "| model | residual RMS [°/s] | RMS x / y / z [°/s] | 100 s variance [(°/s)²] | "
                  "bias stability [°/h] (vs uncomp.) | Allan min [°/h] (vs uncomp.) | "
                  "training CPU [s] (CV) | BP epochs (CV) |",
                  "|---|---|---|---|---|---|---|---|"]
        for m, r in rec["models"].items():
            tt, ep = r.get("train_seconds"), r.get("bp_epochs")
            lines.append(
                f"| {m} | {r['rms_dps']['mean']:.5f} ± {r['rms_dps']['std']:.5f} | "
                + " / ".join(f"{v:.5f}" for v in r["rms_dps_axis"])
                + f" | {r['var100_dps2']['mean']:.3g} | {r['stability_dph']['mean']:.2f} "
                f"({r['stability_improvement_pct']:+.1f} %) | {r['allan_min_dph']['mean']:.2f} "
                f"({r['allan_min_improvement_pct']:+.1f} %) | "
                + (f"{tt['mean']:.3f} ± {tt['std']:.3f} ({tt['cv']:.2f})" if tt else "—") + " | "
                + (f"{ep['mean']:.0f} ± {ep['std']:.0f} ({ep['cv']:.2f})" if ep else "—") + " |")
        s_out = rec["models"][HYBRID]["output_shrinkage"]
        lines += ["", f"{HYBRID}: output shrinkage s (inner validation on the training part) "
                  "x / y / z, mean ± sd over the runs: "
                  + " / ".join(f"{m:.3f} ± {d:.3f}" for m, d in zip(s_out["mean"], s_out["std"]))]
        lines += [""] + [f"![{p}]({p})" for p in rec["plots"]] + [""]
    return "\n".join(lines)


def compare_thermal(paths: list[Path], out_dir: Path, runs: int = 50, seed: int = 0,
                    train_fraction: float = 0.6, hidden: int = 4, tau_s: float = 10.0,
                    window_s: float = 10.0, degree: int = 2, as_written: bool = False,
                    rest_rad_s: float = 1e-3, bp_epochs: int = 3000, progress: bool = True) -> dict:
    """Compare the gyro temperature models on static recordings (`imufmu compare-thermal`).

    paths: imu-csv/1 recordings of a static unit (ref_gyr, or a 'static' sidecar -> 0);
    each is split by time: training = first `train_fraction`, validation = the rest.
    Writes `out_dir/compare_thermal.md`, `compare_thermal.json` and PNG plots; returns the
    JSON content. runs: Monte-Carlo repetitions (seeds seed .. seed + runs - 1). hidden, tau_s
    [s]: network size and rate low-pass; window_s [s]: target/residual averaging window;
    degree: polynomial degree; as_written: the PSO-BP paper's comparison as written
    (AS_WRITTEN_MODELS) instead of the product table with the source-form ablation (MODELS);
    rest_rad_s: static-row bound on |ref_gyr|; bp_epochs: BP budget (same for BP, (a) and (b)); progress: tqdm bar over the runs.
    """
    if runs < 1 or not 0.0 < train_fraction < 1.0:
        raise ValueError("need runs >= 1 and 0 < train_fraction < 1")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(1)
    settings = {"train_fraction": train_fraction, "hidden": hidden, "tau_s": tau_s,
                "window_s": window_s, "degree": degree, "segments": PIECEWISE_SEGMENTS,
                "written_segments": WRITTEN_SEGMENTS, "as_written": as_written,
                "rest_rad_s": rest_rad_s, "bp_epochs": bp_epochs}
    results = {"runs": runs, "seed": seed, "settings": settings, "units": {
        "rms_dps": "°/s", "var100_dps2": "(°/s)²", "stability_dph": "°/h", "allan_min_dph": "°/h",
        "train_seconds": "s (process CPU)"},
        "recordings": [_compare_one(Path(p), out_dir, runs, seed, settings, progress) for p in paths]}
    (out_dir / "compare_thermal.json").write_text(json.dumps(results, indent=1))
    (out_dir / "compare_thermal.md").write_text(_markdown(results))
    return results
