"""Time offset between a sampled signal and its reference (e.g. an IMU gyro and an optical rate).

Both series are on the same uniform sample grid k = 0..N-1. For a whole-sample shift s the
residual is r_k(s) = x_k − y_{k−s} − b(s), with the bias b(s) fitted per shift and per component
(least squares: the mean residual), so a constant sensor bias does not move the estimate:

    J(s) = Σ_components mean_k (x_k − y_{k−s} − b(s))²        (mean squared residual)
    δ    = argmin_s J(s)

Sign convention: δ > 0 means x lags y, x(t) ≈ y(t − δ): the signal shows at time t what the
reference showed δ earlier (for an IMU against an optical reference: the IMU lags).

J is evaluated at every whole shift in [−max_shift, max_shift] on one fixed set of samples (those
selected by `mask` where x_k and every y_{k−s} of the grid are finite), so the curves of all shifts
compare the same data. The whole-sample minimum is refined by the vertex of the parabola through J
at the minimum and its two neighbours: for a smooth reference J(s) = σ² + E[(y(t−s) − y(t−δ))²]
≈ σ² + E[ẏ²](s − δ)², a parabola in s whose vertex is δ; the neglected quartic term is of relative
size (2πB/fs)² for motion band-limited to B (≈ 1 % at 5 Hz and 286 Hz).

Uncertainty: the selected samples are cut into `n_segments` contiguous segments; per segment and
shift the sums of r and r² are kept, so a bootstrap over segments (resample segments with
replacement, refit b(s) and δ) and a split-half (first vs second half of the segments) cost no
new residuals. Segments are seconds long, far longer than the residual's correlation time, so
they are close to independent.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class OffsetEstimate:
    """Result of estimate_offset. Offsets in samples (divide by the sample rate for seconds)."""

    delta: float                 # refined offset [samples], δ > 0: signal lags reference; NaN at the grid edge
    shifts: np.ndarray           # (S,) whole-sample shifts of the grid
    rms: np.ndarray              # (S,) RMS residual sqrt(J(s)) over the selected samples (bias removed)
    n_samples: int               # samples used
    bootstrap: np.ndarray = field(default_factory=lambda: np.empty(0))  # δ of each bootstrap draw [samples]
    halves: tuple[float, float] = (np.nan, np.nan)                     # δ of the first / second half [samples]

    @property
    def bootstrap_std(self) -> float:
        """Standard deviation of the bootstrap δ [samples] (NaN without draws)."""
        b = self.bootstrap[np.isfinite(self.bootstrap)]
        return float(np.std(b, ddof=1)) if b.size > 1 else float("nan")

    def bootstrap_interval(self, level: float = 0.95) -> tuple[float, float]:
        """Percentile interval of the bootstrap δ [samples]."""
        b = self.bootstrap[np.isfinite(self.bootstrap)]
        if b.size < 2:
            return float("nan"), float("nan")
        q = 50.0 * (1.0 - level)
        return float(np.percentile(b, q)), float(np.percentile(b, 100.0 - q))

    @property
    def split_half_difference(self) -> float:
        """δ(second half) − δ(first half) [samples]."""
        return float(self.halves[1] - self.halves[0])


def refine_minimum(shifts: np.ndarray, cost: np.ndarray) -> float:
    """Vertex of the parabola through the cost at its whole-sample minimum and both neighbours;
    NaN when the minimum lies on the edge of the grid (the offset may be outside it)."""
    cost = np.asarray(cost, dtype=float)
    if not np.isfinite(cost).any():
        return float("nan")
    i = int(np.nanargmin(cost))
    if i == 0 or i == len(cost) - 1:
        return float("nan")
    c_m, c_0, c_p = cost[i - 1], cost[i], cost[i + 1]
    curvature = c_m - 2.0 * c_0 + c_p
    if not curvature > 0.0:
        return float(shifts[i])
    return float(shifts[i] + 0.5 * (c_m - c_p) / curvature)


def usable_samples(signal: np.ndarray, reference: np.ndarray, mask: np.ndarray | None,
                   max_shift: int) -> np.ndarray:
    """Indices k where mask holds, signal[k] is finite and reference[k − s] is finite for every
    whole shift |s| ≤ max_shift."""
    x = np.asarray(signal, dtype=float).reshape(len(signal), -1)
    y = np.asarray(reference, dtype=float).reshape(len(reference), -1)
    n = len(x)
    ok_y = np.all(np.isfinite(y), axis=1)
    # reference finite on the whole window [k − max_shift, k + max_shift]
    bad = np.concatenate([[0], np.cumsum(~ok_y)])
    k = np.arange(max_shift, n - max_shift)
    window_ok = (bad[k + max_shift + 1] - bad[k - max_shift]) == 0
    sel = np.zeros(n, dtype=bool)
    sel[k[window_ok]] = True
    sel &= np.all(np.isfinite(x), axis=1)
    if mask is not None:
        sel &= np.asarray(mask, dtype=bool)
    return np.flatnonzero(sel)


def _cost(s1: np.ndarray, s2: np.ndarray, n: np.ndarray | float) -> np.ndarray:
    """J(s) from summed residuals s1 (S, C) and squares s2 (S, C) over n samples, bias removed."""
    return np.sum(s2 / n - (s1 / n) ** 2, axis=-1)


def estimate_offset(signal: np.ndarray, reference: np.ndarray, mask: np.ndarray | None = None,
                    max_shift: int = 30, n_segments: int = 20, n_bootstrap: int = 200,
                    seed: int = 0) -> OffsetEstimate:
    """Offset δ [samples] of `signal` against `reference` (both (N,) or (N, C) on one uniform grid):
    δ = argmin_s J(s) (module docstring), whole-sample grid |s| ≤ max_shift, parabolic refinement,
    bias fitted per shift. `mask` (N,) selects the samples that count (e.g. where the body moves).
    n_bootstrap draws over n_segments contiguous segments with numpy's default_rng(seed); 0 = none.
    Raises ValueError when fewer than 2·n_segments samples are usable."""
    x = np.asarray(signal, dtype=float).reshape(len(signal), -1)
    y = np.asarray(reference, dtype=float).reshape(len(reference), -1)
    if x.shape != y.shape:
        raise ValueError(f"signal {x.shape} and reference {y.shape} differ in shape")
    idx = usable_samples(x, y, mask, max_shift)
    n_segments = max(1, int(n_segments))
    if idx.size < 2 * n_segments:
        raise ValueError(f"only {idx.size} usable samples for the offset estimate")
    shifts = np.arange(-max_shift, max_shift + 1)
    starts = np.linspace(0, idx.size, n_segments + 1).astype(int)[:-1]
    counts = np.diff(np.append(starts, idx.size)).astype(float)
    s1 = np.empty((n_segments, shifts.size, x.shape[1]))
    s2 = np.empty_like(s1)
    xs = x[idx]
    for j, s in enumerate(shifts):
        r = xs - y[idx - s]
        s1[:, j] = np.add.reduceat(r, starts, axis=0)
        s2[:, j] = np.add.reduceat(r * r, starts, axis=0)
    cost = _cost(s1.sum(0), s2.sum(0), idx.size)
    delta = refine_minimum(shifts, cost)

    def subset(weights: np.ndarray) -> float:
        w = weights[:, None, None]
        return refine_minimum(shifts, _cost((w * s1).sum(0), (w * s2).sum(0), float(weights @ counts)))

    rng = np.random.default_rng(seed)
    boot = np.array([subset(np.bincount(rng.integers(0, n_segments, n_segments), minlength=n_segments)
                            .astype(float)) for _ in range(n_bootstrap)])
    half = n_segments // 2
    first = (np.arange(n_segments) < half).astype(float)
    halves = (subset(first), subset(1.0 - first)) if half > 0 else (np.nan, np.nan)
    return OffsetEstimate(delta=delta, shifts=shifts, rms=np.sqrt(np.maximum(cost, 0.0)),
                          n_samples=int(idx.size), bootstrap=boot, halves=halves)


def shift_series(x: np.ndarray, delta: float) -> np.ndarray:
    """x resampled at k − delta (samples) by linear interpolation: out[k] = x(k − delta);
    NaN where a neighbour is NaN or k − delta is outside the series. x is (N,) or (N, C)."""
    x = np.asarray(x, dtype=float)
    flat = x.reshape(len(x), -1)
    pos = np.arange(len(x)) - float(delta)
    lo = np.floor(pos).astype(int)
    frac = (pos - lo)[:, None]
    inside = (lo >= 0) & (lo + 1 < len(x))
    inside |= (frac[:, 0] == 0.0) & (lo >= 0) & (lo < len(x))
    lo_c = np.clip(lo, 0, len(x) - 1)
    hi_c = np.clip(lo + 1, 0, len(x) - 1)
    out = (1.0 - frac) * flat[lo_c] + np.where(frac > 0.0, frac * flat[hi_c], 0.0)
    out[~inside] = np.nan
    return out.reshape(x.shape)
