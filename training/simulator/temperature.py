"""Sensor temperature profile: piecewise-linear ramps and soaks plus a power-on warm-up."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class TemperatureProfile:
    """T(t) = ramp(t) + rise · (1 − exp(−t/τ)).

    `ramp` interpolates linearly between breakpoints (times_s (M+1,) [s], temps_c (M+1,) [°C]);
    the exponential is the sensor's self-heating after power-on (rise [°C], τ [s]).
    """

    times_s: np.ndarray
    temps_c: np.ndarray
    warmup_rise_c: float
    warmup_tau_s: float

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Temperature [°C] and its exact time derivative [°C/s] at times t (N,) [s]."""
        slopes = np.diff(self.temps_c) / np.diff(self.times_s)
        piece = np.clip(np.searchsorted(self.times_s, t, side="right") - 1, 0, slopes.size - 1)
        decay = np.exp(-t / self.warmup_tau_s)
        temp = np.interp(t, self.times_s, self.temps_c) + self.warmup_rise_c * (1.0 - decay)
        rate = slopes[piece] + self.warmup_rise_c / self.warmup_tau_s * decay
        return temp, rate
