"""Detection limits: the smallest effect of each candidate family that `imufmu diagnose` would select on
the recordings it was given (issue 30, item 3).

The limit is the selection rule itself applied to an injected effect, not a formula for it. An effect of
family F with coefficients s·β is added to the residual the loop left (β: every column of F
contributing alike, each at unit RMS over the training rows); the offset and the triad's linear refit
and then F are fitted again exactly as the selection fits them (training.diagnosis.diagnose_fit:
the same training and held-out blocks, instruments for the target's own signal, the batch-means test
with the same Bonferroni count), and s is doubled or halved, then bisected, to the smallest s at which
F would be selected (explained share ≥ the loop's minimum and p below its level). So the limit counts
what the linear refit absorbs (an effect that looks like a gain must be larger to be seen), how much
the recordings excite the family's regressors, and the held-out noise — including the reference's own
error, which is part of the residual.

The limit is stated as the injected effect's held-out RMS in the target's unit and, where the family
has one, as its physical reading (training.diagnosis.effect_readings) — the per-axis sizes of an effect
that would just be found.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from training.diagnosis.candidates import Candidate, column_effects
from training.diagnosis.diagnose_fit import (OFFSETS, Fit, Residuals, fit_beta, metric, offset_fit, predict,
                                             scored, test_errors)
from training.diagnosis.effect_readings import readings

#: The search: from the residual's own RMS, doubled or halved at most this many times ...
OCTAVES = 12
#: ... then bisected (in the logarithm) this many times: the limit to 2^(1/2^6) ≈ 1 %.
BISECTIONS = 6


@dataclass(frozen=True)
class Rule:
    """The loop's selection rule: minimum explained share, significance level, Bonferroni count."""

    min_explained: float
    alpha: float
    n_tests: int


def _direction(c: Candidate, r: Residuals) -> np.ndarray:
    """Coefficients under which every column of c adds an effect of RMS 1/√J over the training rows
    (J columns; projected on the field or gravity direction for a norm target)."""
    E = column_effects(c, r.signals, r.train)
    if c.target in r.direction:
        E = np.einsum("njc,nc->nj", E, r.direction[c.target][r.train])[:, :, None]
    rms = np.sqrt(np.nanmean(E * E, axis=(0, 2)))
    beta = np.zeros(len(c.columns))
    ok = np.isfinite(rms) & (rms > 0)
    beta[ok] = 1.0 / (rms[ok] * np.sqrt(len(c.columns)))
    return beta


def _as_fit(c: Candidate, beta: np.ndarray) -> Fit:
    """A fit of c alone with column coefficients beta (no offset, no refit): for predict and readings."""
    return Fit((c,), np.concatenate([np.zeros(OFFSETS), beta]), 0.0, 0.0, 1.0)


class _Injection:
    """The selection of c on the residual y + s·effect, for any s, from two sets of fits.

    Every fit of the selection is linear in the residual (least squares and two-stage least squares
    on fixed rows, with the refit decided once per set of residuals: Residuals.excited), and so are
    its held-out errors; so the fits on y and on the effect alone — on the same rows (each NaN where
    the other is) — give every s exactly as a fit on y + s·effect would."""

    def __init__(self, r: Residuals, c: Candidate, effect: np.ndarray) -> None:
        y = r.residual[c.target]
        both = np.isfinite(y) & np.isfinite(effect)
        self.c, self.r = c, r
        self.parts = [self._fits(replace(r, residual={**r.residual, c.target: np.where(both, v, np.nan)}))
                      for v in (y, effect)]

    def _fits(self, r: Residuals):
        """(base beta, candidate beta or None, held-out errors of each, their stacked rows) on r."""
        c = self.c
        base = offset_fit(c.target, r)
        beta = fit_beta((c,), c.target, r)
        eb, sample = test_errors((), base.beta, c.target, r)
        e1 = None if beta is None else test_errors((c,), beta, c.target, r)[0]
        return beta, eb, e1, sample

    def selected(self, s: float, rule: Rule) -> bool:
        """The loop would select c with its effect at scale s added to the residual."""
        (beta0, eb0, e10, sample), (beta1, eb1, e11, _) = self.parts
        if beta0 is None or beta1 is None:
            return False
        eb = eb0 + s * eb1
        fit = scored((self.c,), beta0 + s * beta1, (e10 + s * e11, eb, eb), sample, self.r, rule.n_tests)
        return fit is not None and fit.explained_fraction >= rule.min_explained and fit.p_value < rule.alpha


def _smallest_scale(injection: _Injection, start: float, rule: Rule) -> float | None:
    """The smallest s (to ~1 %) at which the injected effect is selected: 0 when the family is selected
    without it (it is in the residual already), None when not within 2^OCTAVES·start."""
    if injection.selected(0.0, rule):
        return 0.0
    lo = hi = start
    if injection.selected(start, rule):
        for _ in range(OCTAVES):
            lo /= 2.0
            if not injection.selected(lo, rule):
                break
        else:
            return lo
        hi = 2.0 * lo
    else:
        for _ in range(OCTAVES):
            hi *= 2.0
            if injection.selected(hi, rule):
                break
        else:
            return None
        lo = hi / 2.0
    for _ in range(BISECTIONS):
        mid = np.sqrt(lo * hi)
        lo, hi = (lo, mid) if injection.selected(mid, rule) else (mid, hi)
    return hi


#: What a limit says: the effect size at which the family is just selected; the family is selected
#: already (it is in what the loop left: it stopped at its iteration or term limit); no size within the
#: search is selected (the recordings do not excite the family's regressors).
LIMIT, PRESENT, UNREACHABLE = "limit", "present", "unreachable"


def detection_limit(r: Residuals, c: Candidate, rule: Rule, rate_hz: float,
                    aux_units: dict[str, str] | None = None) -> dict:
    """{family, target, status (LIMIT, PRESENT, UNREACHABLE), rms (display unit; 0 when PRESENT, None when
    UNREACHABLE), reading (at the limit)}."""
    beta = _direction(c, r)
    start = float(np.sqrt(np.nanmean(r.residual[c.target][r.train] ** 2)))
    unit_effect = predict(_as_fit(c, beta), r)
    scale = _smallest_scale(_Injection(r, c, unit_effect), start, rule) if beta.any() and start > 0 else None
    limit = {"family": c.name, "target": c.target, "status": UNREACHABLE, "rms": None, "reading": None}
    if scale == 0.0:
        return {**limit, "status": PRESENT, "rms": 0.0}
    if scale is not None:
        found = readings(_as_fit(c, scale * beta), rate_hz, aux_units)
        size = metric(replace(r, residual={c.target: scale * unit_effect}), c.target)
        limit.update(status=LIMIT, rms=size, reading=found[0] if found else None)
    return limit


def detection_limits(r: Residuals, candidates: list[Candidate], rule: Rule, rate_hz: float,
                     aux_units: dict[str, str] | None = None, progress: bool = False) -> list[dict]:
    """detection_limit of every candidate family, in the candidates' order."""
    from tqdm import tqdm
    return [detection_limit(r, c, rule, rate_hz, aux_units)
            for c in tqdm(candidates, desc="diagnose: detection limits", unit="family", disable=not progress,
                          leave=False)]
