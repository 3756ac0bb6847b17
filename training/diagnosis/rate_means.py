"""How a rate is compared with a rate reference derived from an attitude reference: as means over
MEAN_WINDOW_S of both, the rate passed through the reference's own derivative filter first.

A rate reference derived from a measured attitude (motion capture: ref_q) is the derivative of the
attitude, so it carries the attitude's noise differentiated — noise that grows with frequency. On BROAD,
after the gyro's 4 ms lag is removed, the residual of the rate against it is 0.9 °/s RMS per band at 3–6
and 6–15 Hz on the fastest axis but 0.2–0.4 °/s below 1 Hz: it is the reference, not the gyro, and it
hides every effect of the issue's sizes (a scale nonlinearity of 0.5 %/(rad/s) explains 1.5 % of it). A
mean over a window W is the attitude increment over W divided by W: the attitude noise's share falls as
W^-1.5 while a sensor error accumulates in the increment. The same linear filter on both sides of the
comparison and on every candidate's column keeps every fit unbiased (a signal is compared with its
reference as it would reach the residual): a filter changes which frequencies weigh, not what is read.

MEAN_WINDOW_S = 1 s keeps the motion of hand-held, vehicle and robot recordings at their dominant scale
(the increments still vary from one second to the next) and averages the differentiated noise of a
0.1 s derivative about 25-fold in power. Measured with it on BROAD (effects injected into the
calibration and the diagnosed recordings, docs/diagnosis/README.md): a rate nonlinearity of
0.5 %/(rad/s) is read within 20 % per axis, a g-sensitivity matrix within 12 % (Frobenius norm) and a
supply-voltage bias within 7 %; without it none of the three is selected. A rate reference that is measured (ref_gyr in the recording, a rate
table, a simulation) is compared sample by sample.
"""
from __future__ import annotations

import numpy as np
from scipy.ndimage import uniform_filter1d

from training.data.reference import rate_filter

#: Window [s] of the means a rate and its derived reference are compared over (see the module docstring).
MEAN_WINDOW_S = 1.0
#: The triad whose reference, when derived from the attitude, is a rate compared so.
TRIAD = "gyr"


def window_mean(x: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(N, k) centred mean over MEAN_WINDOW_S (an odd number of samples, so nothing is shifted); NaN where
    the window is not complete (a non-finite sample in it, or the recording's ends)."""
    x = np.asarray(x, dtype=np.float64)
    n = max(1, int(round(MEAN_WINDOW_S / float(np.median(np.diff(t)))))) | 1
    finite = np.isfinite(x)
    total = uniform_filter1d(np.where(finite, x, 0.0), n, axis=0, mode="constant")
    count = uniform_filter1d(finite.astype(np.float64), n, axis=0, mode="constant")
    return np.where(count > 1.0 - 0.5 / n, total / np.maximum(count, 1e-300), np.nan)


def as_compared(x: np.ndarray, t: np.ndarray) -> np.ndarray:
    """A rate-like signal (N, k) as it reaches the comparison with a derived rate reference: through the
    reference's derivative filter (training.data.reference.rate_filter), then the window mean."""
    return window_mean(rate_filter(x, t), t)


def compared_residual(rate: np.ndarray, reference: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(N, 3) residual of a compensated rate against its derived reference, as window means."""
    return window_mean(rate_filter(rate, t) - reference, t)
