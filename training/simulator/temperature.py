"""Sensor temperature profile: piecewise-linear ramps and soaks plus power-on warm-ups."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class TemperatureProfile:
    """T(t) = ramp(t) + rise · (1 − exp(−t/τ)) + Σ_i h_i(t).

    `ramp` interpolates linearly between breakpoints (times_s (M+1,) [s], temps_c (M+1,) [°C]);
    the exponential is the sensor's self-heating after power-on (rise [°C], τ [s]).
    `power_ons` adds a warm-up per segment, (start_s, end_s, rise_c, tau_s) each: the unit is
    powered on at start_s, heats by h_i = rise (1 − exp(−(t − start)/τ)) until end_s, and after
    end_s (powered off) the heat decays, h_i = h_i(end) exp(−(t − end)/τ); h_i = 0 before start.
    """

    times_s: np.ndarray
    temps_c: np.ndarray
    warmup_rise_c: float
    warmup_tau_s: float
    power_ons: tuple[tuple[float, float, float, float], ...] = ()

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Temperature [°C] and its exact time derivative [°C/s] at times t (N,) [s]."""
        slopes = np.diff(self.temps_c) / np.diff(self.times_s)
        piece = np.clip(np.searchsorted(self.times_s, t, side="right") - 1, 0, slopes.size - 1)
        decay = np.exp(-t / self.warmup_tau_s)
        temp = np.interp(t, self.times_s, self.temps_c) + self.warmup_rise_c * (1.0 - decay)
        rate = slopes[piece] + self.warmup_rise_c / self.warmup_tau_s * decay
        for start, end, rise, tau in self.power_ons:
            heat, heat_rate = _power_on(t, start, end, rise, tau)
            temp, rate = temp + heat, rate + heat_rate
        return temp, rate


def _power_on(t: np.ndarray, start: float, end: float, rise: float,
              tau: float) -> tuple[np.ndarray, np.ndarray]:
    """Self-heating [°C] and its derivative [°C/s] of one power-on from start to end [s]."""
    on = (t >= start) & (t < end)
    after = t >= end
    heat_on = rise * (1.0 - np.exp(-(np.minimum(t, end) - start) / tau))
    decay = np.exp(-(t - end) / tau)
    heat = np.where(on, heat_on, 0.0) + np.where(after, heat_on * decay, 0.0)
    rate = (np.where(on, rise / tau * np.exp(-(t - start) / tau), 0.0)
            + np.where(after, -heat_on * decay / tau, 0.0))
    return heat, rate
