"""`imufmu diagnose`: find the effect a trained model lacks, add it as correction terms, report.

1. Run the model through the batch runtime (the FMU's C code) and form residuals of the
   compensated triads against the reference the data has (ref_gyr/acc/mag, or derived from ref_q
   by training.reference), or against an invariant without a reference: the field norm (sidecar
   norm, else the median on the training part) and the gravity norm at rest.
2. Fit every candidate of training.candidates on the first part of each recording in time
   (least squares with a per-component offset) and rank by the share of the held-out residual it
   explains beyond an offset-only fit. Significance is a one-sided batch-means test of predictive
   accuracy (Diebold & Mariano 1995, J. Bus. Econ. Stat. 13(3); batch means: Schmeiser 1982,
   Oper. Res. 30(3)): the held-out rows of each recording are cut into BATCHES contiguous batches,
   d_b = mean over the batch of (e_offset² − e_candidate²), and t = mean(d)/(sd(d)/√K) has a
   Student t distribution with K − 1 degrees of freedom when the candidate does not predict
   better. Batches tens of seconds long are nearly independent even when the residual varies
   slowly, so the test neither inflates significance for autocorrelated noise nor collapses for
   a slow drift (an AR(1) effective-sample-size correction does the latter: ρ → 1 gives n_eff → 1).
   Bonferroni over the candidates. Norm invariants are linearised: |x − δ| − n ≈ r − u·δ, u = x/|x|.
3. Add the best significant candidate that the FMU can carry as terms of the artefact and refit:
   the term coefficients and the offset by least squares on the training part; the offset goes
   into the constant bias coefficient b[:, 0] of the triad's thermal model (as A⁻¹·c, exact where
   the gain polynomial G = 1, within |G − 1| ≈ 10⁻³ elsewhere; the runtime rerun measures the
   result). The thermal gains and temperature polynomials are not refitted. Rerun the runtime,
   measure before/after on the held-out part, iterate.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from scipy import stats

from .artefact import ModelArtefact, coefficients_array, load_artefact, settings_dict
from .thermal import ThermalModel
from .candidates import Candidate, build_candidates, regressor_matrix
from .dataset import ImuData
from .io import read_imu_csv
from .layout import TERM_SIGNALS, TERMS_MAX, TRIAD_ORDER, settings_array
from .pipeline import recording_parameters
from .reference import derive_references
from .runtime import run_batch, term_signals

#: Share of each recording (the end, in time) held out for ranking and for before/after.
HOLDOUT_FRACTION = 0.3
#: Regression rows are decimated to at most this rate [Hz] (BROAD is 286 Hz): the effects sought
#: are slow next to 50 Hz, and the batch-means test does not count rows as independent anyway.
REGRESSION_RATE_HZ = 50.0
#: Significance level after Bonferroni correction over the candidate count.
ALPHA = 0.01
#: Contiguous batches per recording's held-out part for the batch-means test. 16 batches of a
#: 37 s held-out part are ~2.3 s long, longer than the ~1 s correlation time of handheld motion
#: (0.1-1 Hz) and far longer than that of the sensor noise; 15 degrees of freedom keep the
#: Bonferroni-corrected t quantile moderate (t_0.9998,15 ≈ 4.6 for ~45 candidates).
BATCHES = 16
#: A candidate must explain at least this share of the held-out residual: below it, a
#: "significant" fit on tens of thousands of rows is too small to matter for any metric.
MIN_EXPLAINED = 0.05
#: Time is a last-resort regressor (a drift with time since power-on does not transfer between
#: power cycles): a candidate without `time` within this explained share of the best wins.
TIME_TIE = 0.02
#: Relative singular-value cut of the column-scaled least squares: a combination of regressors
#: (with the offset) that varies by less than 1 % of the strongest one — e.g. mag_x²+mag_y²+mag_z²
#: at a constant field norm — would need coefficients ≥ 100× the effect it explains and would
#: amplify noise, so it is dropped (truncated SVD) instead of fitted.
RCOND = 0.01
#: Iterations of select -> add -> refit.
MAX_ITERATIONS = 4
#: Rest detection for the gravity-norm invariant [rad/s].
REST_RATE = 0.05
_SLICES = {"gyr": slice(0, 3), "acc": slice(3, 6), "mag": slice(6, 9)}
_METRICS = {"gyr": ("rate error RMS", "°/s", np.rad2deg(1.0)), "acc": ("specific-force error RMS", "m/s²", 1.0),
            "mag": ("field error RMS", "µT", 1.0)}


@dataclass
class Residuals:
    """Stacked over recordings: per target (N, m) residuals and, for norms, unit vectors (N, 3)."""

    t: np.ndarray                          # (N,) s, per recording time
    signals: dict[str, np.ndarray]         # name -> (N,)
    residual: dict[str, np.ndarray]        # target -> (N, 3) triad or (N, 1) norm
    direction: dict[str, np.ndarray]       # norm target -> (N, 3) unit vectors
    train: np.ndarray                      # (N,) bool, regression rows of the training part
    test: np.ndarray                       # (N,) bool, regression rows of the held-out part
    holdout: np.ndarray                    # (N,) bool, every held-out row counted by the metric


def _targets(data: ImuData) -> dict[str, str]:
    """target -> kind ('triad' or 'norm') for the residuals this recording supports."""
    out = {}
    for triad in TRIAD_ORDER:
        if not data.has(triad):
            continue
        ref = getattr(data, f"ref_{triad}")
        if ref is not None and np.isfinite(ref).any():
            out[triad] = "triad"
        elif triad in ("mag", "acc"):
            out[f"{triad}_norm"] = "norm"
    return out


def _reference_norm(target: str, data: ImuData, comp: np.ndarray, rows: np.ndarray) -> float:
    """Invariant magnitude: sidecar field norm / standard gravity, else the training-part median."""
    if target == "mag_norm" and data.field_norm_ut is not None:
        return data.field_norm_ut
    if target == "acc_norm":
        return 9.80665
    return float(np.nanmedian(np.linalg.norm(comp[rows], axis=1)))


def _run(artefact: ModelArtefact, data: ImuData, terms: bool = True) -> np.ndarray:
    """Runtime outputs (N, 20) of `data` with the artefact (without its terms when terms=False)."""
    art = artefact if terms else replace(artefact, terms=[])
    values = settings_dict(art)
    values.update(recording_parameters(data))
    return run_batch(coefficients_array(art), np.asarray(settings_array(values)), data.t, data.inputs())


def residuals(artefact: ModelArtefact, datasets: list[ImuData], targets: dict[str, str]) -> Residuals:
    """Residuals of every target and the candidate signals, stacked over the recordings."""
    parts = []
    for d in datasets:
        out, out0 = _run(artefact, d), _run(artefact, d, terms=False)
        sig = term_signals(d.t, out0[:, :9], d.temp)
        signals = {name: sig[:, k] for k, name in enumerate(TERM_SIGNALS)}
        signals.update(d.aux)
        n = len(d)
        holdout = d.t >= d.t[0] + (1.0 - HOLDOUT_FRACTION) * (d.t[-1] - d.t[0])
        step = max(1, int(round(float(1.0 / np.median(np.diff(d.t))) / REGRESSION_RATE_HZ)))
        sampled = np.zeros(n, bool)
        sampled[::step] = True
        mask = np.ones(n, bool) if d.eval_mask is None else d.eval_mask.astype(bool)
        res, direction = {}, {}
        for target, kind in targets.items():
            triad = target.split("_")[0]
            comp = out[:, _SLICES[triad]]
            if kind == "triad":
                ref = getattr(d, f"ref_{triad}")
                res[target] = comp - (ref if ref is not None else np.nan)
                continue
            norm = np.linalg.norm(comp, axis=1)
            r = norm - _reference_norm(target, d, comp, ~holdout)
            if triad == "acc":
                r = np.where(np.linalg.norm(out[:, 0:3], axis=1) < REST_RATE, r, np.nan)
            res[target], direction[target] = r[:, None], comp / norm[:, None]
        parts.append((d.t, signals, res, direction, sampled & ~holdout, sampled & holdout, holdout & mask))
    keys = set.intersection(*(set(p[1]) for p in parts))
    return Residuals(
        np.concatenate([p[0] for p in parts]),
        {k: np.concatenate([p[1][k] for p in parts]) for k in sorted(keys)},
        {k: np.concatenate([p[2][k] for p in parts]) for k in targets},
        {k: np.concatenate([p[3][k] for p in parts]) for k in targets if targets[k] == "norm"},
        np.concatenate([p[4] for p in parts]), np.concatenate([p[5] for p in parts]),
        np.concatenate([p[6] for p in parts]))


@dataclass
class Fit:
    """One candidate fitted on the training part and scored on the held-out part."""

    candidate: Candidate
    explained_fraction: float
    p_value: float
    terms: list[tuple[str, str, str | None, float]]   # (target component, a, b, coefficient)
    offset: np.ndarray                                # (3,) offset of the compensated triad refitted with it
    prediction: np.ndarray                            # (N, m) fitted effect on every row (NaN if not computable)
    offset_only: float                                # held-out metric with the offset-only fit, display unit


def _design(candidate: Candidate, r: Residuals, rows: np.ndarray):
    """Blocks of the stacked regression: for a triad one block per axis with columns [1, R], for a
    norm one block with columns [u_i, u_i·R] (an offset vector δ changes the norm by −u·δ).
    Each block: (y (n,), X (n, q), number of offset columns, names [(component, a, b)])."""
    R = regressor_matrix(candidate, r.signals, rows)
    y = r.residual[candidate.target][rows]
    triad = candidate.target.split("_")[0]
    comps = [f"{triad}_{a}" for a in "xyz"]
    if y.shape[1] == 3:
        X = np.column_stack([np.ones(len(y)), R])
        return [(y[:, i], X, 1, [(comps[i], a, b) for a, b in candidate.regressors]) for i in range(3)]
    u = r.direction[candidate.target][rows]
    X = np.column_stack([u] + [u[:, [i]] * R for i in range(3)])
    return [(y[:, 0], X, 3, [(comps[i], a, b) for i in range(3) for a, b in candidate.regressors])]


def _batches(r: Residuals) -> np.ndarray:
    """(N,) batch index of every held-out regression row (−1 elsewhere): each recording's held-out
    regression rows cut into BATCHES contiguous runs of equal count."""
    out = np.full(len(r.t), -1)
    starts = np.flatnonzero(np.concatenate([[True], np.diff(r.t) < 0]))
    for k, (a, b) in enumerate(zip(starts, list(starts[1:]) + [len(r.t)])):
        idx = a + np.flatnonzero(r.test[a:b])
        for j, chunk in enumerate(np.array_split(idx, BATCHES)):
            out[chunk] = k * BATCHES + j
    return out


def batch_means_p(d: np.ndarray, batch: np.ndarray) -> float:
    """One-sided p of mean(d) > 0 from the batch means of d (n,) over the batch labels (n,) ≥ 0:
    t = mean/(sd/√K), Student t with K − 1 degrees of freedom (K non-empty batches)."""
    means = np.array([d[batch == b].mean() for b in np.unique(batch)])
    if means.size < 2:
        return 1.0
    sd = float(np.std(means, ddof=1))
    if sd == 0.0:
        return 0.0 if means.mean() > 0 else 1.0
    return float(stats.t.sf(means.mean() / (sd / np.sqrt(means.size)), means.size - 1))


def _lstsq(X: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Least squares of y on the columns of X, scaled to unit RMS, by SVD truncated at RCOND."""
    scale = np.sqrt(np.mean(X * X, axis=0))
    scale[scale == 0] = 1.0
    return np.linalg.lstsq(X / scale, y, rcond=RCOND)[0] / scale


def fit_candidate(candidate: Candidate, r: Residuals, n_candidates: int) -> Fit | None:
    """Least squares (offset + candidate) on the training rows; on the held-out rows the share of
    the offset-only residual it explains and the batch-means p-value (Bonferroni-corrected)."""
    train, test = _design(candidate, r, r.train), _design(candidate, r, r.test)
    batch = _batches(r)[r.test]
    d = np.zeros(len(batch))
    sse0 = sse1 = 0.0
    terms, offset = [], np.zeros(3)
    for i, ((y, X, m, names), (yt, Xt, _, _)) in enumerate(zip(train, test)):
        ok, okt = np.isfinite(y) & np.all(np.isfinite(X), axis=1), np.isfinite(yt) & np.all(np.isfinite(Xt), axis=1)
        if ok.sum() < 2 * X.shape[1] or okt.sum() < 2 * X.shape[1]:
            return None
        beta, beta0 = _lstsq(X[ok], y[ok]), _lstsq(X[ok, :m], y[ok])
        e0 = np.where(okt, yt - np.where(okt[:, None], Xt[:, :m], 0.0) @ beta0, 0.0)
        e1 = np.where(okt, yt - np.where(okt[:, None], Xt, 0.0) @ beta, 0.0)
        d += e0 * e0 - e1 * e1
        sse0, sse1 = sse0 + e0 @ e0, sse1 + e1 @ e1
        offset[slice(i, i + 1) if m == 1 else slice(0, 3)] = beta[:m]
        terms += [(c, a, b, float(v)) for (c, a, b), v in zip(names, beta[m:])]
    explained = 1.0 - sse1 / sse0 if sse0 > 0 else 0.0
    p_value = batch_means_p(d, batch) if explained > 0 else 1.0
    scale = _METRICS[candidate.target.split("_")[0]][2]
    res = r.residual[candidate.target] - _offset_effect(candidate.target, r, offset_only_fit(candidate.target, r))
    e = res[r.holdout] * scale
    e = e[np.isfinite(e)]
    return Fit(candidate, float(explained), min(1.0, p_value * n_candidates), terms, offset,
               predict(candidate, r, terms), float(np.sqrt(np.mean(e * e))) if e.size else float("nan"))


def offset_only_fit(target: str, r: Residuals) -> np.ndarray:
    """(3,) offset of the compensated triad fitted alone (least squares on the training rows)."""
    y = r.residual[target][r.train]
    if y.shape[1] == 3:
        return np.nanmean(y, axis=0)
    u = r.direction[target][r.train]
    ok = np.isfinite(y[:, 0]) & np.all(np.isfinite(u), axis=1)
    return np.linalg.lstsq(u[ok], y[ok, 0], rcond=None)[0]


def _offset_effect(target: str, r: Residuals, offset: np.ndarray) -> np.ndarray:
    """Effect of a compensated-triad offset (3,) on the target's residual, (N, m)."""
    if target in r.direction:
        return np.sum(r.direction[target] * offset, axis=1, keepdims=True)
    return np.broadcast_to(offset, (len(r.t), 3))


def predict(candidate: Candidate, r: Residuals, terms) -> np.ndarray:
    """Fitted effect of the candidate's terms on every row, in the target's residual shape."""
    rows = np.ones(len(r.t), bool)
    R = regressor_matrix(candidate, r.signals, rows)
    k = len(candidate.regressors)
    coef = np.array([c for _, _, _, c in terms]).reshape(3, k)
    effect = R @ coef.T
    if candidate.target in r.direction:
        return np.sum(r.direction[candidate.target] * effect, axis=1, keepdims=True)
    return effect


def metric(r: Residuals, target: str) -> float:
    """Held-out RMS of a target's residual in its display unit (°/s, m/s², µT)."""
    scale = _METRICS[target.split("_")[0]][2]
    e = r.residual[target][r.holdout] * scale
    e = e[np.isfinite(e)]
    return float(np.sqrt(np.mean(e * e))) if e.size else float("nan")


def metric_name(target: str) -> str:
    """'rate error RMS, °/s' style name of the target's metric."""
    name, unit, _ = _METRICS[target.split("_")[0]]
    return f"{'norm ' if target.endswith('_norm') else ''}{name} (held-out), {unit}"


def _select(fits: list[Fit], n_terms: int) -> tuple[Fit | None, list[str]]:
    """Best significant carriable fit that fits the term budget, and notes on what was passed over."""
    notes = []
    ok = [f for f in fits if f.explained_fraction >= MIN_EXPLAINED and f.p_value < ALPHA]
    for f in ok:
        if not f.candidate.carriable:
            notes.append(f"'{f.candidate.name}' on {f.candidate.target} explains {f.explained_fraction:.1%} "
                         "but uses aux_* columns the FMU has no inputs for: reported, not added")
    fitting = [f for f in ok if f.candidate.carriable and n_terms + len(f.terms) <= TERMS_MAX]
    if len(fitting) < len([f for f in ok if f.candidate.carriable]):
        notes.append(f"significant candidates needing more than the {TERMS_MAX - n_terms} free term slots were skipped")
    if not fitting:
        return None, notes
    best = max(fitting, key=lambda f: f.explained_fraction)
    if any(a == "time" for a, _ in best.candidate.regressors):
        others = [f for f in fitting if all(a != "time" for a, _ in f.candidate.regressors)
                  and f.explained_fraction >= best.explained_fraction - TIME_TIE]
        if others:
            alt = max(others, key=lambda f: f.explained_fraction)
            notes.append(f"'{alt.candidate.name}' chosen over 'time' ({alt.explained_fraction:.1%} vs "
                         f"{best.explained_fraction:.1%}): time is the last-resort regressor")
            best = alt
    return best, notes


def shift_bias(model: ThermalModel, offset: np.ndarray) -> ThermalModel:
    """The thermal model whose output is lower by `offset` (3,) [triad unit]: b[:, 0] += A⁻¹·offset
    (exact where the gain polynomial is 1). A disabled model becomes the enabled identity + offset."""
    if not model.enabled:
        model = ThermalModel.identity()
    b = np.array(model.b)
    b[:, 0] += np.linalg.solve(model.A, offset)
    return replace(model, b=b)


def _add(artefact: ModelArtefact, fit: Fit) -> ModelArtefact:
    """A new artefact with the fit's terms appended and its offset moved into the thermal bias."""
    triad = fit.candidate.target.split("_")[0]
    name = f"diagnose: {fit.candidate.name} -> {fit.candidate.target}"
    terms = list(artefact.terms) + [{"name": name, "target": c, "a": a, "b": b, "coefficient": v}
                                    for c, a, b, v in fit.terms]
    notes = list(artefact.notes) + [f"{name}: {len(fit.terms)} terms; {triad} bias offset refitted by "
                                    f"{np.round(fit.offset, 6).tolist()} {_METRICS[triad][1] if triad != 'gyr' else 'rad/s'}"]
    thermal = {**artefact.thermal, triad: shift_bias(artefact.thermal[triad], fit.offset)}
    return replace(artefact, terms=terms, notes=notes, thermal=thermal)


def _candidate_json(f: Fit) -> dict:
    return {"name": f.candidate.name, "target": f.candidate.target, "regressors": f.candidate.labels(),
            "explained_fraction": f.explained_fraction, "p_value": f.p_value,
            "carriable": f.candidate.carriable}


def _selected_json(f: Fit) -> dict:
    """The selected candidate with its term count, refitted offset and offset-only metric."""
    return {**_candidate_json(f), "terms": len(f.terms), "offset": f.offset.tolist(),
            "after_offset_only": f.offset_only}


def load_recordings(paths: list[Path]) -> tuple[list[ImuData], list[str]]:
    """Read the recordings and derive missing references from ref_q (notes say what was derived)."""
    datasets, notes = [], []
    for p in paths:
        data, derived = derive_references(read_imu_csv(p))
        datasets.append(data)
        notes += [f"{data.name}: {n}" for n in derived]
    return datasets, notes


def diagnose(paths: list[Path], model_path: Path, out_dir: Path, seed: int = 0,
             max_iterations: int = MAX_ITERATIONS, plots: bool = True) -> dict:
    """Diagnose recordings `paths` with the artefact `model_path`; write out_dir/diagnosis.json,
    out_dir/model.json (the artefact with the added terms) and out_dir/report.md (+ PNG plots).

    Returns the diagnosis.json document. Deterministic: least squares and fixed splits only; `seed`
    is recorded in the new artefact's provenance (nothing is drawn at random).
    """
    from .diagnose_report import write_report
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    artefact = load_artefact(model_path)
    datasets, notes = load_recordings([Path(p) for p in paths])
    targets = {}
    for d in datasets:
        targets.update(_targets(d))
    r0 = residuals(artefact, datasets, targets)
    start = {t: metric(r0, t) for t in targets}
    current, r, iterations, first_fits, plot_data = artefact, r0, [], None, None
    for _ in range(max_iterations):
        candidates = build_candidates(r.signals, list(targets))
        fits = [f for f in (fit_candidate(c, r, len(candidates)) for c in candidates) if f is not None]
        fits.sort(key=lambda f: -f.explained_fraction)
        first_fits = fits if first_fits is None else first_fits
        best, why = _select(fits, len(current.terms))
        notes += why
        if best is None:
            break
        target = best.candidate.target
        new = _add(current, best)
        r_new = residuals(new, datasets, targets)
        step = {"selected": _selected_json(best),
                "target": target, "metric": metric_name(target),
                "before": metric(r, target), "after": metric(r_new, target),
                "candidates": [_candidate_json(f) for f in fits[:10]]}
        iterations.append(step)
        if plot_data is None:
            plot_data = (r, r_new, best)
        current, r = new, r_new
    first = iterations[0] if iterations else None
    target = first["target"] if first else (first_fits[0].candidate.target if first_fits else next(iter(targets)))
    before, after = start[target], metric(r, target)
    result = {
        "target": target, "metric": metric_name(target),
        "candidates": [_candidate_json(f) for f in (first_fits or [])],
        "selected": ({k: first["selected"][k] for k in ("name", "target", "regressors")} if first else None),
        "before": before, "after": after,
        "improvement_pct": 100.0 * (before - after) / before if first and before > 0 else 0.0,
        "iterations": iterations,
        "metrics_before": {t: start[t] for t in targets},
        "metrics_after": {t: metric(r, t) for t in targets},
        "recordings": [{"name": d.name, "samples": len(d)} for d in datasets],
        "holdout_fraction": HOLDOUT_FRACTION, "alpha_bonferroni": ALPHA, "min_explained": MIN_EXPLAINED,
        "regression_rate_hz": REGRESSION_RATE_HZ, "thermal_refitted": "bias offset only (b[:, 0] += A⁻¹·offset of the selected fit; gains and temperature polynomials kept)",
        "test": f"one-sided batch-means test of held-out predictive accuracy, {BATCHES} batches per recording",
        "model_in": str(model_path), "seed": seed, "notes": notes,
        "conclusion": ("nothing significant left" if not iterations else
                       f"added: {', '.join(s['selected']['name'] + ' -> ' + s['target'] for s in iterations)}"),
    }
    current.save(out_dir / "model.json")
    (out_dir / "diagnosis.json").write_text(json.dumps(result, indent=2, ensure_ascii=False) + "\n", encoding="utf-8")
    write_report(out_dir, result, plot_data if plots else None)
    return result
