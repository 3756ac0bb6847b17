"""The time-shift column of a triad, scanned over whole samples.

A time shift's column is the central difference of the triad (x(t) − x(t − τ) ≈ τ·ẋ): linear in τ,
it reads a lag of a few samples. A clock offset of 200 ms on handheld motion turns the field by
0.1–0.5 rad, far outside that range: the linearised fit reads a fraction of it, and when `train` saw
the same offset, its calibration was fitted to the lagged signal too (a magnetometer 20 samples late in
the calibration and the diagnosed recordings: 25.7 µT held-out error, nothing selected).

So before the candidates are fitted, the residual of every triad with a reference is scanned over
whole-sample shifts of the triad: the shift k [samples] after which an offset and a gain matrix leave the least of
r + x(t + k) − x(t) over the training rows of every recording, |k| ≤ MAX_SHIFT_S (the gain because the
calibration `train` fitted on the shifted signal is bent by the shift: without it, the same
recordings scan to 370 ms for 200). When the best shift is not zero (|k| > LINEAR_SAMPLES), the column
becomes the difference over that shift, (x(t + k) − x(t)) / τ_k:
a coefficient −τ_k then means "lags by τ_k", as the central difference's does, and
training.diagnosis.diagnose.refine_lag finds the exact lag through the runtime. Whether the shift is an
effect is left to the held-out test like every other family.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from training.diagnosis.candidates import SHIFT_HALF_WIDTH, central_differences

#: Largest clock offset scanned [s], either way. A reference further off than this is not the same
#: recording's clock (imufmu import's alignment is the tool for it).
MAX_SHIFT_S = 0.5
#: Spacing [s] of the first pass of the scan (scan_shift).
SCAN_STEP_S = 0.01
#: Shifts up to this many samples stay with the central difference. 0: every whole-sample shift the scan
#: finds gets the exact difference over it, and the linear refit beside it regresses on the shifted triad.
#: Beside the central difference the gain cannot be refitted (it would absorb the linearisation error, which
#: the runtime's exact shift does not make: diagnose_fit.refit_for), and where `train`'s gain was bent, the
#: shift alone then explains less than the refitted gain alone: BROAD's gyro lags its optical reference by
#: 1.2 samples (docs/diagnosis/broad_time_offset) and its shift was never selected with a linear range of 4
#: samples; with the exact column and the refit it is (held-out rate error 3.81 → 1.36 °/s).
LINEAR_SAMPLES = 0


@dataclass
class WideShift:
    """A triad's scanned shift beyond the linear range and the signals with that triad shifted by it: the
    linear refit beside the shift regresses on the shifted triad, which is what the runtime calibrates
    once its lag is set (the residual is x(t) − G·x(t + τ) − b: on the unshifted triad the shift's
    column would need the matrix −G as its coefficient, not the lag alone)."""

    shift_s: float
    signals: dict[str, np.ndarray]        # the candidate signals, the triad's components shifted
    instruments: dict[str, np.ndarray]    # their instruments (training.diagnosis.candidates.instrument_signals)


def shifted(x: np.ndarray, t: np.ndarray, shift_s: float) -> np.ndarray:
    """(N, 3) x[n + k] for the shift's k samples, NaN outside the recording."""
    k = int(round(shift_s / float(np.median(np.diff(t)))))
    out = np.full(x.shape, np.nan)
    lo, hi = max(0, -k), min(len(x), len(x) - k)
    if lo < hi:
        out[lo:hi] = x[lo + k:hi + k]
    return out


def shifted_difference(x: np.ndarray, t: np.ndarray, k: int) -> np.ndarray:
    """(N, 3) (x[n + k] − x[n]) / (t[n + k] − t[n]) for a shift of k samples (either sign); NaN where n + k
    is outside the recording."""
    out = np.full(x.shape, np.nan)
    n = len(t)
    if k == 0 or abs(k) >= n:
        return out
    lo, hi = max(0, -k), min(n, n - k)
    idx = np.arange(lo, hi)
    out[idx] = (x[idx + k] - x[idx]) / (t[idx + k] - t[idx])[:, None]
    return out


def _shifted_rows(x: np.ndarray, r: np.ndarray, rows: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """(y, X) at the rows n with n + k inside and finite: y = r[n] + x[n + k] − x[n], the residual of the
    triad shifted by k samples, and X = [1, x[n + k]], its offset and gain."""
    n = rows[(rows + k >= 0) & (rows + k < len(x))]
    y, X = r[n] + x[n + k] - x[n], np.column_stack([np.ones(len(n)), x[n + k]])
    ok = np.all(np.isfinite(y), axis=1) & np.all(np.isfinite(X), axis=1)
    return y[ok], X[ok]


def _shift_cost(parts: list[tuple[np.ndarray, np.ndarray, np.ndarray, float]], rows: list[np.ndarray],
                k: int, rate_hz: float) -> float:
    """Mean squared residual of the triads shifted by k samples (at rate_hz) after an offset and a gain refit."""
    pairs = [_shifted_rows(x, r, n, int(round(k * rate / rate_hz))) for (x, r, _, rate), n in zip(parts, rows)]
    y, X = np.concatenate([p[0] for p in pairs]), np.concatenate([p[1] for p in pairs])
    if len(y) <= X.shape[1]:
        return np.inf
    e = y - X @ np.linalg.lstsq(X, y, rcond=None)[0]
    return float(np.mean(e * e))


def scan_shift(parts: list[tuple[np.ndarray, np.ndarray, np.ndarray, float]], rate_hz: float) -> float:
    """The shift [s] of a triad after which an offset and a gain matrix (the linear calibration, which
    `train` fitted to the shifted signal when the calibration recording had the shift too) leave the
    least residual over the training rows of every recording; parts: per recording (triad x (N, 3),
    residual r (N, 3), training rows (N,) bool, its rate [Hz]). 0 when no shift beats none. Shifts are
    tried every SCAN_STEP_S (every sample at ≤ 100 Hz), then every sample around the best of them: the
    cost varies over the motion's time scale, tenths of a second (three times fewer fits at 286 Hz;
    each residuals() of a diagnosis scans every triad)."""
    steps = int(round(MAX_SHIFT_S * rate_hz))
    stride = max(1, int(round(SCAN_STEP_S * rate_hz)))
    rows = [np.flatnonzero(train) for _, _, train, _ in parts]
    coarse = sorted(set(range(0, steps + 1, stride)) | {-k for k in range(0, steps + 1, stride)}, key=abs)
    costs = {k: _shift_cost(parts, rows, k, rate_hz) for k in coarse}
    centre = min(coarse, key=lambda k: costs[k])
    for k in range(max(-steps, centre - stride + 1), min(steps, centre + stride - 1) + 1):
        if k not in costs:
            costs[k] = _shift_cost(parts, rows, k, rate_hz)
    best = min(sorted(costs, key=abs), key=lambda k: costs[k])
    return best / rate_hz if np.isfinite(costs[best]) else 0.0


def beyond_linear(shift_s: float, rate_hz: float) -> bool:
    """The scanned shift is outside the central difference's linear range."""
    return abs(int(round(shift_s * rate_hz))) > LINEAR_SAMPLES


def shift_column(x: np.ndarray, t: np.ndarray, shift_s: float) -> np.ndarray:
    """(N, 3) time-shift column of a triad for the scanned shift: the central difference within the
    linear range, else the difference over the shift."""
    rate = 1.0 / float(np.median(np.diff(t)))
    if not beyond_linear(shift_s, rate):
        return central_differences(x, t)
    return shifted_difference(x, t, int(round(shift_s * rate)))
