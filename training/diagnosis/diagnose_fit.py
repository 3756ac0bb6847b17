"""Fitting candidate families to the diagnosis residuals and testing them on held-out data.

Regression: the residual of a triad target is stacked over its three components, with a
per-component offset; a norm target (no reference) is linearised, |x − δ| − n ≈ r − u·δ with
u = x/|x|, so an offset vector δ and a column effect e enter as u·δ and u·e. Least squares on the
training rows, columns scaled to unit RMS, SVD truncated at RCOND. A family built from the target's
own triad shares the target's noise, so least squares would fit the noise on itself (a pure-noise
residual regressed on x·|x| explains ~85 %); it is fitted by two-stage least squares (instrumental
variables: Angrist & Pischke 2009, ch. 4) with the same columns formed from neighbour means
(training.diagnosis.candidates.instrument_signals), which carry the motion but not the noise of the sample.

Significance: a one-sided test of predictive accuracy over batches (Diebold & Mariano 1995, J. Bus.
Econ. Stat. 13(3); batch means: Schmeiser 1982, Oper. Res. 30(3)). The held-out rows form contiguous
blocks; d_b = ln(SSE_base,b / SSE_candidate,b), the log of how much block b's squared error shrinks,
and t = mean(d)/(sd(d)/√K) is Student t with K − 1 degrees of freedom when the candidate does not
predict better than the base (the offset alone, or the families already selected). Blocks seconds
long are nearly independent even when the residual varies slowly. The log ratio weighs every block
alike: with a difference of squared errors, an effect that grows with the motion (a rate
nonlinearity, a lag) or with the temperature rate is judged by its few largest blocks, and a
94 %-explained temperature-rate bias came out p ≈ 0.01.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from training.diagnosis.candidates import LINEAR_REFIT, Candidate, column_effects, linear_refit
from training.diagnosis.rate_means import as_compared
from training.diagnosis.time_shift import WideShift
from training.display import DISPLAY

#: Relative singular-value cut of the column-scaled least squares: a combination of columns that
#: varies by less than 1 % of the strongest one — e.g. mag_x²+mag_y²+mag_z² at a constant field
#: norm — would need coefficients ≥ 100× the effect it explains and would amplify noise, so it is
#: dropped (truncated SVD) instead of fitted.
RCOND = 0.01
OFFSETS = 3
#: Smallest `spread` of a norm target's directions at which its symmetric gain is refitted with every family
#: (a third of the whole sphere's 1/3): on a patch of the sphere an ellipsoid's gains and offset trade against
#: each other and against the effect (x-io's hand-held part, spread 0.03: refits reading 70-85 % gain changes
#: fit the held-out norm alike, benchmarks/norm_identifiability.py).
NORM_SPREAD = 1.0 / 9.0


@dataclass
class Residuals:
    """Stacked over recordings: per target (N, m) residuals and, for norms, unit vectors (N, 3)."""

    t: np.ndarray                          # (N,) s, per recording time
    starts: np.ndarray                     # first row of every recording
    signals: dict[str, np.ndarray]         # name -> (N,)
    instruments: dict[str, dict]           # triad -> signals with that triad's instruments
    residual: dict[str, np.ndarray]        # target -> (N, 3) triad or (N, 1) norm
    direction: dict[str, np.ndarray]       # norm target -> (N, 3) unit vectors
    train: np.ndarray                      # (N,) bool, regression rows of the training blocks
    test: np.ndarray                       # (N,) bool, regression rows of the held-out blocks
    holdout: np.ndarray                    # (N,) bool, every held-out row counted by the metric
    fitted: np.ndarray                     # (N,) bool, every row of the training blocks (term ranges)
    block: np.ndarray                      # (N,) held-out block id (−1 in the training blocks)
    excited: dict[str, bool]               # target -> its gain is refitted with every family (excitation)
    wide_shifts: dict[str, WideShift] = field(default_factory=dict)  # triad -> its shift scanned beyond the linear range
    matched: dict[str, np.ndarray] = field(default_factory=dict)  # target -> (N,) bool, rows compared as rate means (rate_means)
    compared: dict = field(default_factory=dict, repr=False, compare=False)  # memo of _compared_product


@dataclass
class Fit:
    """Families fitted jointly on one target with its linear calibration: beta = [offset (3), the
    refit's column coefficients (refit_for: none for a norm target or beside a time shift),
    the families' column coefficients...]."""

    candidates: tuple[Candidate, ...]
    beta: np.ndarray
    explained_fraction: float     # share of the base fit's held-out residual explained (offset and linear refit)
    gain: float                   # share of the base's held-out residual explained
    p_value: float                # one-sided, against the base, Bonferroni-corrected by the caller's count
    refit: Candidate | None = None  # the linear calibration fitted with the families

    @property
    def target(self) -> str:
        return self.candidates[0].target

    @property
    def label(self) -> str:
        """The fitted families' names joined by ' + ', as reports and notes show them."""
        return " + ".join(c.name for c in self.candidates)

    @property
    def offset(self) -> np.ndarray:
        return self.beta[:OFFSETS]

    @property
    def refit_coefficients(self) -> np.ndarray:
        """Coefficients of the linear refit's columns (empty without one)."""
        return self.beta[OFFSETS:OFFSETS + self._refit_columns]

    @property
    def _refit_columns(self) -> int:
        return 0 if self.refit is None else len(self.refit.columns)

    def coefficients(self) -> list[np.ndarray]:
        """Column coefficients per candidate."""
        out, k = [], OFFSETS + self._refit_columns
        for c in self.candidates:
            out.append(self.beta[k:k + len(c.columns)])
            k += len(c.columns)
        return out


def metric(r: Residuals, target: str) -> float:
    """Held-out RMS of a target's residual in its display unit (°/s, m/s², µT)."""
    e = r.residual[target][r.holdout] * DISPLAY[target.split("_")[0]][1]
    e = e[np.isfinite(e)]
    return float(np.sqrt(np.mean(e * e))) if e.size else float("nan")


def _signals_of(c: Candidate, cands, r: Residuals, instrument: bool) -> dict[str, np.ndarray]:
    """The signals a candidate's columns are formed from: its instruments if asked and own; for the linear
    refit beside a shift scanned beyond the linear range, the shifted triad (WideShift)."""
    wide = r.wide_shifts.get(c.triad)
    if wide is not None and c.name == LINEAR_REFIT and any(o.kind == "lag" and o.triad == c.triad for o in cands):
        return wide.instruments if instrument else wide.signals
    return r.instruments[c.triad] if instrument and c.own else r.signals


def _effects(cands, r: Residuals, rows: np.ndarray, instrument: bool) -> np.ndarray:
    """(n, J, 3) column effects of the candidates at rows (instrument columns if asked and own)."""
    parts = [_column_effects(c, _signals_of(c, cands, r, instrument), r, rows) for c in cands]
    return np.concatenate(parts, axis=1) if parts else np.zeros((int(rows.sum()), 0, 3))


def _column_effects(c: Candidate, signals: dict[str, np.ndarray], r: Residuals, rows: np.ndarray) -> np.ndarray:
    """column_effects of c at rows; where the target's residual compares a rate with a rate reference
    derived from the attitude (Residuals.matched), the columns as they reach that residual, over each
    recording (training.diagnosis.rate_means.as_compared): an effect in the raw rate reaches it filtered,
    and the unfiltered column differs from it by 12-20 % of its size on hand-held motion even before the
    means (BROAD 02 through the 0.1 s derivative filter: ω|ω| 14-16 %, ω_x·ω_z 20 %)."""
    if not r.matched.get(c.target, np.zeros(1, bool)).any():
        return column_effects(c, signals, rows)
    out = np.zeros((int(np.count_nonzero(rows)) if rows.dtype == bool else len(rows), len(c.columns), 3))
    for j, column in enumerate(c.columns):
        for k, a, b, w in column:
            out[:, j, k] += w * _compared_product(r, c.target, signals, a, b)[rows]
    return out


def _compared_product(r: Residuals, target: str, signals: dict[str, np.ndarray], a: str, b: str | None) -> np.ndarray:
    """(N,) the regressor s[a]·s[b] as it reaches the target's residual (rate_means.as_compared on the
    recordings in Residuals.matched[target]), memoised per signal set in Residuals.compared (the entry keeps
    its signal dict alive, so its id is not reused)."""
    memo = r.compared.setdefault((target, id(signals)), (signals, {}))[1]
    if (a, b) not in memo:
        x = signals[a] * (1.0 if b is None else signals[b])
        mask, bounds = r.matched[target], list(r.starts) + [len(r.t)]
        memo[(a, b)] = np.concatenate([as_compared(x[lo:hi, None], r.t[lo:hi])[:, 0] if mask[lo] else x[lo:hi]
                                       for lo, hi in zip(bounds[:-1], bounds[1:])])
    return memo[(a, b)]


def excitation(signals: dict[str, np.ndarray], residual: dict[str, np.ndarray], train: np.ndarray,
               direction: dict[str, np.ndarray] | None = None) -> dict[str, bool]:
    """Target -> its reference varies more, on every axis, than what an offset and a gain matrix on the
    triad's signal leave of its residual (standard deviations over the training rows): the signal then
    carries the true quantity's variation, which determines a gain. A static gyro against ref_gyr = 0 does
    not: its signal is its drifting bias, and a "gain" on it would absorb the bias's temperature drift
    (pan_thermal: the temperature family, 91 % explained, was no longer selected). Measured against what
    the linear calibration leaves rather than the raw residual, because an effect in the calibration
    recording can bend `train`'s calibration into a residual larger than the reference (a magnetometer
    200 ms late: 32 µT of residual against 29 µT of reference on x, yet a gain refit is what it needs).
    Decided once per set of residuals (Residuals.excited), for every candidate fitted on them. A norm target
    (its unit vectors in `direction`): where its directions spread over the sphere (`spread`)."""
    out = {}
    for target, res in residual.items():
        triad = target.split("_")[0]
        if res.shape[1] == 1 and direction is not None and target in direction:
            out[target] = spread(direction[target][train & np.isfinite(res[:, 0])]) >= NORM_SPREAD
            continue
        if res.shape[1] != 3 or not all(f"{triad}_{a}" in signals for a in "xyz"):
            out[target] = False
            continue
        signal = np.column_stack([signals[f"{triad}_{a}"] for a in "xyz"])[train]
        ok = _finite(signal, res[train])
        if ok.sum() <= 4:
            out[target] = False
            continue
        X = np.column_stack([np.ones(int(ok.sum())), signal[ok]])
        left = res[train][ok] - X @ np.linalg.lstsq(X, res[train][ok], rcond=None)[0]
        reference = signal[ok] - res[train][ok]
        out[target] = bool(np.all(np.std(reference, axis=0) > np.std(left, axis=0)))
    return out


def spread(u: np.ndarray) -> float:
    """Smallest eigenvalue of the mean of u·uᵀ over unit vectors u (N, 3): 1/3 when they cover the sphere
    evenly (six-position rests), 0 when they lie on a great circle or at one point."""
    u = u[np.all(np.isfinite(u), axis=1)]
    return float(np.linalg.eigvalsh(u.T @ u / len(u))[0]) if len(u) > 3 else 0.0


def refit_for(cands, target: str, r: Residuals) -> Candidate | None:
    """The linear refit fitted with `cands`: the target's (training.diagnosis.candidates.linear_refit)
    when its reference excites the gain (Residuals.excited, `excitation`), except beside a time shift whose
    column is the central difference, the shift's linearisation: the gain would absorb the linearisation
    error, which the runtime's exact shift does not make (a gyro 7 samples early: held-out error 99.6 %
    lower without the refit, 85.8 % with it). A whole-sample shift found by the scan (Residuals.wide_shifts,
    time_shift.LINEAR_SAMPLES) is not linearised: its column is the difference over the shift itself, and
    the calibration `train` fitted to the shifted signal is refitted with it (a magnetometer 200 ms late
    in the calibration too: the shift alone explains nothing; BROAD's gyro 1.2 samples behind its optical
    reference: never selected without the refit)."""
    if any(c.kind == "lag" and c.triad not in r.wide_shifts for c in cands):
        return None
    refit = linear_refit(target, r.signals)
    return refit if refit is not None and r.excited.get(target, False) else None


def with_refit(cands, target: str, r: Residuals) -> tuple[Candidate, ...]:
    """The linear refit of `cands` (when there is one) followed by `cands`: the columns of their fit."""
    refit = refit_for(cands, target, r)
    return tuple(cands) if refit is None else (refit, *cands)


def design(cands, target: str, r: Residuals, rows: np.ndarray, instrument: bool = False):
    """(y, X, sample): the stacked regression at `rows` with the offset, the linear refit and the
    columns of `cands`; sample maps each stacked row to its row."""
    cands = with_refit(cands, target, r)
    E = _effects(cands, r, rows, instrument)
    y = r.residual[target][rows]
    n = len(y)
    if y.shape[1] == 3:
        X = np.concatenate([np.column_stack([np.tile(np.eye(3)[c], (n, 1)), E[:, :, c]]) for c in range(3)])
        return y.T.ravel(), X, np.tile(np.arange(n), 3)
    u = r.direction[target][rows]
    return y[:, 0], np.column_stack([u, np.einsum("njc,nc->nj", E, u)]), np.arange(n)


def _lstsq(X: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Least squares of y on the columns of X, scaled to unit RMS, by SVD truncated at RCOND."""
    scale = np.sqrt(np.mean(X * X, axis=0))
    scale[scale == 0] = 1.0
    beta = np.linalg.lstsq(X / scale, y, rcond=RCOND)[0]
    return beta / (scale if beta.ndim == 1 else scale[:, None])


def solve(X: np.ndarray, y: np.ndarray, Z: np.ndarray | None = None) -> np.ndarray:
    """Least squares, or two-stage least squares with instruments Z (same shape as X)."""
    if Z is None:
        return _lstsq(X, y)
    return _lstsq(Z @ _lstsq(Z, X), y)


def _finite(*arrays) -> np.ndarray:
    ok = np.ones(len(arrays[0]), bool)
    for a in arrays:
        ok &= np.isfinite(a) if a.ndim == 1 else np.all(np.isfinite(a), axis=1)
    return ok


def fit_beta(cands, target: str, r: Residuals) -> np.ndarray | None:
    """Coefficients [offset, columns] on the training rows; None when too few finite rows."""
    y, X, _ = design(cands, target, r, r.train)
    own = any(c.own for c in with_refit(cands, target, r))
    Z = design(cands, target, r, r.train, instrument=True)[1] if own else None
    ok = _finite(y, X) if Z is None else _finite(y, X, Z)
    if ok.sum() < 4 * X.shape[1]:
        return None
    return solve(X[ok], y[ok], None if Z is None else Z[ok])


def test_errors(cands, beta: np.ndarray, target: str, r: Residuals):
    """(e, sample) held-out stacked errors y − X·beta (NaN where not computable) and their rows."""
    y, X, sample = design(cands, target, r, r.test)
    e = y - X @ beta
    return np.where(_finite(y, X), e, np.nan), sample


def batch_log_ratios(e_base: np.ndarray, e_new: np.ndarray, batch: np.ndarray) -> np.ndarray:
    """ln(SSE_base / SSE_new) per batch label of the rows (batches with a zero sum left out)."""
    labels = np.unique(batch)
    sb = np.array([np.sum(e_base[batch == b] ** 2) for b in labels])
    sn = np.array([np.sum(e_new[batch == b] ** 2) for b in labels])
    ok = (sb > 0) & (sn > 0)
    return np.log(sb[ok] / sn[ok])


def one_sided_p(d: np.ndarray) -> float:
    """One-sided p of mean(d) > 0 from K batch values d: t = mean/(sd/√K), Student t, K − 1 dof."""
    if d.size < 2:
        return 1.0
    sd = float(np.std(d, ddof=1))
    if sd == 0.0:
        return 0.0 if d.mean() > 0 else 1.0
    return float(stats.t.sf(d.mean() / (sd / np.sqrt(d.size)), d.size - 1))


def offset_fit(target: str, r: Residuals) -> Fit:
    """The offset and the linear refit alone (the base of every first comparison)."""
    refit = refit_for((), target, r)
    beta = fit_beta((), target, r)
    size = OFFSETS + (0 if refit is None else len(refit.columns))
    return Fit((), np.zeros(size) if beta is None else beta, 0.0, 0.0, 1.0, refit)


def fit_candidates(cands, r: Residuals, base: Fit, offset_only: Fit, n_tests: int) -> Fit | None:
    """Fit `cands` jointly; score against `base` and the offset alone on the held-out rows."""
    target = cands[0].target
    beta = fit_beta(cands, target, r)
    if beta is None:
        return None
    e1, sample = test_errors(cands, beta, target, r)
    eb, _ = test_errors(base.candidates, base.beta, target, r)
    e0, _ = test_errors((), offset_only.beta, target, r)
    return scored(cands, beta, (e1, eb, e0), sample, r, n_tests)


def scored(cands, beta: np.ndarray, errors: tuple, sample: np.ndarray, r: Residuals, n_tests: int) -> Fit | None:
    """The Fit of `cands` at `beta` from the held-out errors (candidate, base, offset alone) at the stacked
    rows `sample` of test_errors: explained shares and the Bonferroni-corrected batch-means p."""
    e1, eb, e0 = errors
    ok = np.isfinite(e1) & np.isfinite(eb) & np.isfinite(e0)
    if ok.sum() < 2 * len(beta):
        return None
    sse1, sseb, sse0 = (float(np.sum(e[ok] ** 2)) for e in (e1, eb, e0))
    rows = np.flatnonzero(r.test)[sample[ok]]
    gain = 1.0 - sse1 / sseb if sseb > 0 else 0.0
    p = one_sided_p(batch_log_ratios(eb[ok], e1[ok], r.block[rows])) if gain > 0 else 1.0
    return Fit(tuple(cands), beta, 1.0 - sse1 / sse0 if sse0 > 0 else 0.0, gain, min(1.0, p * n_tests),
               refit_for(cands, cands[0].target, r))


def predict(fit: Fit, r: Residuals) -> np.ndarray:
    """Fitted effect of the fit's columns (without the offset) on every row, in the target's shape."""
    rows = np.ones(len(r.t), bool)
    E = _effects(fit.candidates, r, rows, instrument=False)
    effect = np.einsum("njc,j->nc", E, np.concatenate(fit.coefficients()) if fit.candidates else np.zeros(0))
    if fit.target in r.direction:
        return np.sum(r.direction[fit.target] * effect, axis=1, keepdims=True)
    return effect
