"""The temperature polynomial degree of a triad's gain/bias model, chosen from the data (issue 15).

Rule (`choose_degree`):

1. **Never more coefficients than the data pin down.** A polynomial of degree d has d + 1
   coefficients per axis, so B(T) — and G(T), which shares the degree — needs d + 1 distinct
   temperatures: clusters of `training.models.thermal.temperature_clusters` (CLUSTER_WIDTH_C wide bins
   holding at least CLUSTER_MIN_SHARE of the samples; a ramp passing through does not count).
   Two soaks allow degree 1 at most. A degree-2 fit on two soaks leaves the curvature and the
   centre value it trades against free: it gave −2.35 m/s² of acc z bias at 31 °C between soaks
   at 13 and 48 °C (+0.11 and −0.13 m/s² at the soaks themselves).
2. **The simplest degree that holds on held-out data.** Each allowed degree is fitted on the
   first 1 − HOLDOUT_FRACTION (training.models.holdout's share) of the samples of every temperature band
   and scored on the rest (`held_out_rows`): held out within each band, not at the end of the
   recording, because an end-of-recording split can take the last soak whole and leave the
   degree it pins untestable (three soaks, the third in the last quarter). The fit uses a linear
   proxy of the model (below), so the choice costs a least-squares solve per degree, not a
   gradient descent. The degree with the lowest held-out drift error (`proxy_error`: the residual
   averaged over consecutive blocks, then RMS) is chosen; a tie (within DEGREE_TOLERANCE, 0 by
   default) goes to the lower degree. A degree the
   fitted part cannot pin (fewer than d + 1 clusters in it) is not validated and not chosen.
3. `--degree P` given by the user is a maximum: the data may force a lower degree, and the
   reason says so. The default, `auto`, searches 0 … AUTO_MAX_DEGREE.

Proxy of x_c = A·G(T)·(x − B(T)) per axis i, linear in its coefficients: the reference component
i is regressed on the three raw axes x_j, the gain terms Tn^k·x_i (k = 1..min(d, PROXY_GAIN_DEGREE))
and the bias terms Tn^k (k = 0..d) — the model to first order in the cross-axis terms. The held-out
score averages the residual over consecutive blocks first (white noise out, drift in). For a bias-only fit (a
reference that hardly moves) the proxy is the model itself: raw − reference on Tn^k.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from contract.layout import MAX_DEGREE
from training.models.holdout import HOLDOUT_FRACTION
from training.models.thermal import (CLUSTER_WIDTH_C, DEFAULT_T0, DEFAULT_TS, normalised_temperature,
                                     temperature_clusters, temperature_normalisation)

#: The `--degree` value that lets the data choose.
AUTO = "auto"
#: Highest degree `auto` considers: a cubic fitted on a calibration range swings hardest outside
#: it, and the product's sensors (MEMS) drift with at most a gentle curvature; ask for 3 explicitly.
AUTO_MAX_DEGREE = 2
#: A higher degree is chosen only when it lowers the held-out drift error by more than this share.
#: 0: the lowest error wins, a tie goes to the lower degree. A margin of a few per cent looks safer
#: but is not: where the held-out error has a floor the degree cannot touch (the g-sensitivity of
#: scenarios/variants/diag_calibration_gsens.toml, sensor noise) a real curvature of the gyro bias
#: lowers it by only 1.5 %, and a 2 % margin dropped it (the leftover was then read as a rate
#: nonlinearity by `imufmu diagnose`). Noise is kept out by the block means and unpinned
#: coefficients by the cluster cap, so the held-out error itself is trusted.
DEGREE_TOLERANCE = 0.0
#: Highest power of Tn in the proxy's gain terms: a gain curvature G(T) of a MEMS sensor (~1e-6/°C²)
#: moves the output far less than a bias curvature, and where the motion covers only part of the
#: temperature range an unregularised least-squares fit of it swings wildly on held-out data (the
#: gradient-descent fit, started at G = 1, does not); the proxy therefore judges the degree by the
#: bias polynomial and the gain slope, and the fitted model gives G(T) the chosen degree.
PROXY_GAIN_DEGREE = 1
#: Consecutive blocks the held-out rows are averaged over before the RMS: ~100 samples each in a
#: short recording, so the noise of a block mean is ~10x below the per-sample noise, while a drift
#: in temperature (which changes over tens of seconds) is resolved.
HELD_OUT_BLOCKS = 25


def parse_degree(value) -> int | str:
    """'auto' or an integer 0..MAX_DEGREE (from the CLI or an API caller); ValueError otherwise."""
    if isinstance(value, str) and value.strip().lower() == AUTO:
        return AUTO
    try:
        number = int(value)
    except (TypeError, ValueError):
        raise ValueError(f"degree {value!r} is neither '{AUTO}' nor an integer 0..{MAX_DEGREE}") from None
    if number != value and not isinstance(value, str) or not 0 <= number <= MAX_DEGREE:
        raise ValueError(f"degree {value!r} is neither '{AUTO}' nor an integer 0..{MAX_DEGREE}")
    return number


def ceiling(degree) -> int:
    """Largest degree considered: the user's maximum, or AUTO_MAX_DEGREE for 'auto'."""
    degree = parse_degree(degree)
    return AUTO_MAX_DEGREE if degree == AUTO else int(degree)


@dataclass(frozen=True)
class DegreeChoice:
    """The degree chosen for one triad and why.

    requested: the user's maximum ('auto' or an integer); allowed: the highest degree the
    distinct temperatures pin down (clusters − 1, capped by the request); held_out: held-out drift
    error [triad unit] per validated degree (proxy_error); reason: one sentence for the notes and the report."""

    degree: int
    requested: int | str
    clusters: int
    allowed: int
    held_out: dict[int, float] = field(default_factory=dict)
    reason: str = ""

    def as_dict(self) -> dict:
        """JSON-ready form (held-out keys as strings)."""
        return {"degree": self.degree, "requested": self.requested, "temperature_clusters": self.clusters,
                "allowed": self.allowed, "held_out_error": {str(k): v for k, v in self.held_out.items()},
                "rule": self.reason}


def _proxy_design(raw: np.ndarray, tn: np.ndarray, axis: int, degree: int, gains: bool) -> np.ndarray:
    """Regressors (N, ·) of the linear proxy for `axis` (see the module docstring)."""
    bias = [tn ** k for k in range(degree + 1)]
    if not gains:
        return np.column_stack(bias)
    return np.column_stack([raw[:, 0], raw[:, 1], raw[:, 2]]
                           + [tn ** k * raw[:, axis] for k in range(1, min(degree, PROXY_GAIN_DEGREE) + 1)]
                           + bias)


def proxy_error(raw, target, tn, fit_rows, test_rows, degree: int, gains: bool) -> float:
    """Held-out systematic error of the degree-`degree` proxy fitted on fit_rows, scored on test_rows
    [unit]: RMS over axes of the residual averaged over HELD_OUT_BLOCKS consecutive blocks of the
    held-out rows (time order), so that white noise, which every degree leaves alike, averages out
    and the temperature drift the degree misses remains."""
    test = np.flatnonzero(test_rows)
    blocks = np.array_split(test, min(HELD_OUT_BLOCKS, test.size))
    means = []
    for i in range(3):
        y = target[:, i] if gains else raw[:, i] - target[:, i]
        x = _proxy_design(raw, tn, i, degree, gains)
        coef = np.linalg.lstsq(x[fit_rows], y[fit_rows], rcond=None)[0]
        r = x[test] @ coef - y[test]
        means.append([np.mean(r[np.searchsorted(test, b)]) for b in blocks])
    weights = np.array([b.size for b in blocks], dtype=float)
    return float(np.sqrt(np.sum(np.square(means) * weights) / (3 * weights.sum())))


def held_out_rows(temp: np.ndarray) -> np.ndarray:
    """(N,) bool: the last HOLDOUT_FRACTION (in row = time order) of the rows of every temperature band
    CLUSTER_WIDTH_C wide (the bands of temperature_clusters; rows without temperature form one band),
    so that the held-out part spans the temperatures the fit sees and every degree they pin down
    can be tested on it."""
    temp = np.asarray(temp, dtype=np.float64)
    finite = np.isfinite(temp)
    band = np.full(temp.shape, -1, dtype=int)
    if finite.any():
        band[finite] = np.floor((temp[finite] - temp[finite].min()) / CLUSTER_WIDTH_C).astype(int)
    tail = np.zeros(temp.shape, dtype=bool)
    for b in np.unique(band):
        rows = np.flatnonzero(band == b)
        tail[rows[int(round((1.0 - HOLDOUT_FRACTION) * rows.size)):]] = True
    return tail


def choose_degree(raw: np.ndarray, target: np.ndarray, temp: np.ndarray, requested, gains: bool,
                  unit: str = "") -> DegreeChoice:
    """The degree of a triad's temperature polynomials from its data (rule: module docstring).

    raw, target: (N, 3) raw triad and reference [unit] and temp (N,) °C, rows in time order; requested: 'auto' or the user's maximum;
    gains: True when A·G(T) is fitted too, False for a bias-only fit; unit: the triad unit (text)."""
    requested = parse_degree(requested)
    top = ceiling(requested)
    ok = np.all(np.isfinite(raw), axis=1) & np.all(np.isfinite(target), axis=1)
    raw, target, temp = raw[ok], target[ok], temp[ok]
    tail = held_out_rows(temp)
    clusters = temperature_clusters(temp)
    allowed = min(top, max(clusters - 1, 0))
    span = _span(temp)
    pinned = (f"{clusters} distinct temperature{'s' if clusters != 1 else ''} (clusters {CLUSTER_WIDTH_C:g} °C "
              f"wide) over {span} pin down degree {max(clusters - 1, 0)} at most")
    if allowed == 0:
        why = "no finite temperature" if clusters == 0 else pinned
        return DegreeChoice(0, requested, clusters, 0, {}, _with_request(0, requested, top, f"degree 0: {why}"))
    norm = temperature_normalisation(temp)
    t0, ts = norm if norm is not None else (DEFAULT_T0, DEFAULT_TS)
    tn = normalised_temperature(temp, t0, ts)
    head = ~tail
    head_clusters = temperature_clusters(temp[head]) if head.any() else 0
    scores = {}
    if tail.any():
        for d in range(allowed + 1):
            if d + 1 <= head_clusters and head.sum() > 3 * (2 * d + 4):
                scores[d] = proxy_error(raw, target, tn, head, tail, d, gains)
    if not scores:
        reason = (f"degree {allowed}: {pinned}; no held-out part to test lower degrees on, so the highest "
                  "the data pin down")
        return DegreeChoice(allowed, requested, clusters, allowed, {}, _with_request(allowed, requested, top, reason))
    best = min(scores.values())
    degree = min(d for d, e in scores.items() if e <= (1.0 + DEGREE_TOLERANCE) * best)
    listed = ", ".join(f"{d}: {e:.3g}" for d, e in scores.items())
    reason = (f"degree {degree}: {pinned}; held-out drift error by degree ({listed} {unit}; fitted on the first "
              f"{1 - HOLDOUT_FRACTION:.0%} of the samples of every temperature band, scored on the rest, RMS of "
              f"{HELD_OUT_BLOCKS} block means): {_criterion()}")
    untested = [d for d in range(allowed + 1) if d not in scores]
    if untested:
        reason += (f"; degree {', '.join(map(str, untested))} not chosen: the fitted part holds only "
                   f"{head_clusters} distinct temperature{'s' if head_clusters != 1 else ''}")
    return DegreeChoice(degree, requested, clusters, allowed, scores, _with_request(degree, requested, top, reason))


def _criterion() -> str:
    """How the held-out errors decide, in words."""
    if DEGREE_TOLERANCE <= 0.0:
        return "the lowest error wins, a tie goes to the lower degree"
    return f"the lowest degree within {DEGREE_TOLERANCE:.0%} of the best"


def _with_request(degree: int, requested, top: int, reason: str) -> str:
    """The reason, prefixed with what the request was and whether the data forced less."""
    if requested == AUTO:
        return f"--degree auto (0..{top}) chose {reason}"
    if degree < requested:
        return f"--degree {requested} is a maximum; the data forced {reason}"
    return f"--degree {requested} (maximum) kept {reason}"


def _span(temp: np.ndarray) -> str:
    """'lo..hi °C' of the finite temperatures, or 'no temperature'."""
    finite = temp[np.isfinite(temp)]
    return f"{finite.min():.1f}..{finite.max():.1f} °C" if finite.size else "no temperature"
