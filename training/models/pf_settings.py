"""Particle-filter settings derived from the calibration data (docs/magpf.md).

A user switches the online hard/soft-iron filter on with `enable_pf = 1` and nothing else; every
setting that depends on the sensor must then come from `imufmu train`, from the magnetometer
*after* the trained calibration (what the filter sees at run time), the sample rate and the field
norm. `pf_settings_from_calibration` computes them; `noise_statistics` gives the figures the
rules use.

Units: field [µT], time [s], rate [Hz], angles [rad] (the FMU's `pf_min_rotation`), spreads [µT]
(hard iron) and [1] (soft-iron entries), decimation [samples].

Statistics of the calibrated field h_c (per recording segment; a time step ≤ 0 or longer than
`GAP_PERIODS` sample periods starts a new segment, so recordings may be concatenated; non-finite
rows are dropped):

* r = |h_c| − m, with m the running mean of |h_c| that the filter's change test itself subtracts
  (exponential, `norm_time_constant_updates()` updates = 300·d/rate seconds at decimation d). To be
  independent of the direction of time, m runs forward and backward and both residuals count.
  **σ** = std of r — the whole residual the test sees in an unchanged environment: sensor noise
  plus what the calibration leaves (field non-uniformity, model error), σ² = σ_w² + σ_slow².
* **σ_w** (white noise per axis along the field): the variogram γ(L) = ½ var(|h_c|(k + L) −
  |h_c|(k)) over lags L = 1, √2, 2, … samples up to `MAX_LAG_S`; σ_w² = γ where d ln γ / d ln L is
  smallest — the plateau between the sensor's own correlation time (its filters; a magnetometer
  held or interpolated onto a faster clock, as BROAD's: lag-1 differences give 0.31 µT there, the
  plateau 0.67 µT) and the slow residual. The norm is orientation-invariant after calibration, so
  this needs no rest segment.
* **σ_slow** = √(σ² − σ_w²): the part of the residual that does not average out over time.

Every variance is taken over the values within `outlier_sigmas()` robust standard deviations of the
median (the filter's own glitch gate: 4 × change threshold 25 in z = 10 σ), so a few corrupted
readings in the calibration data do not inflate the settings.

Rules (F = field norm, d = decimation, rate = sample rate):

1. ``pf_decimation`` d = max(1, round(rate · T_u)), T_u = `UPDATE_INTERVAL_S` = 20 ms. The
   filter's change test counts in updates (innovation average over 5, ambient-norm mean over 300);
   a fixed update interval makes them fixed times whatever the rate: 0.1 s — a magnet being
   attached (~1 s) is seen within a tenth of its approach, and 5 updates still average the white
   noise — and 6 s — longer than a turn of the hand (1–2 s), so the orientation-dependent residual
   of a carrier change is not absorbed as an ambient offset, short against walking from one spot
   of the room to another. 50 updates/s is also ≥ 2× the 10–20 Hz bandwidth of handheld motion.
2. ``pf_measurement_noise`` = σ. The test normalises e = |h_m|² − |h_0|² − h(x̂) ≈ 2F r by
   √(4F²σ² + 6σ⁴) ≈ 2Fσ, so z = (e − ē)²/var ≈ (r/σ)²: with σ the residual's own std, z has unit
   mean on the calibration data and the threshold 25 is a 5σ gate. A σ from the sample-to-sample
   noise alone (or the FMU default 0.3 µT) makes the calibration's own residual look like a change.
3. ``pf_min_rotation`` a = k · √2 σ_w / F, k = `GATE_SIGMAS` = √(2 ln 1000) = 3.72. At rest a new
   sample differs from the last one used by noise alone: two perpendicular components, each
   N(0, 2σ_w²), so the angle is Rayleigh with scale √2 σ_w / F and P(angle > a) = exp(−k²/2) =
   1/1000 per sample: a sensor at rest adds p·rate samples per second to the sums (0.3/s at
   285.7 Hz; one direction repeated would outweigh the rest of the sphere), a moving one every
   sample that turned by a.
4. ``pf_change_spread_hard`` s = κ · √threshold · σ, κ = `CHANGE_MARGIN` = 2, threshold 25. A
   hard-iron shift Δ gives e ≈ 2F|Δ| cos θ, z ≈ (|Δ| cos θ / σ)²: the test declares shifts of about
   5σ and more. The prior after a change (around the old estimate) puts that smallest declarable
   shift at half a standard deviation and one three times larger within 1.5; a magnet approaching
   further is declared again and the prior re-centred. A wider prior only widens the cloud along the
   directions the first seconds after the change have not yet covered, and the compensation (the
   cloud's mean) wanders by several µT until they are (FMU default 30 µT on BROAD: norm spread
   4–7 % instead of ~2 %, bench_magpf). Scaling with σ keeps the prior's weight against one sample,
   3σ²/s² = 3/(25κ²), the same for every sensor.
5. ``pf_settle_spread`` S = max(σ_slow, σ_w √(3 / n_s)), n_s = `SETTLE_SAMPLES` = 100. The
   attitude filter averages the field heading over tau_mag (9 s), which removes the white noise but
   not the calibration's systematic residual σ_slow: a re-estimated hard iron whose uncertainty is
   below σ_slow adds no more heading error than the trained calibration did, so the field may steer
   the heading again. Floor: with a near-perfect calibration (σ_slow → 0) the gate would never open;
   σ_w √(3/n) is the hard-iron σ that n = 100 well-spread samples give (Fisher information n/(3σ²)
   per axis over the sphere) — inactive on BROAD (0.12 vs 0.55 µT).
6. ``pf_prior_spread_hard`` = S (an offset error δ of the trained calibration, std σ_δ per axis,
   changes the norm by δ·u, of std σ_δ since Σu_i² = 1: the calibration's systematic residual
   bounds what it can have missed), and
   ``pf_prior_spread_soft`` = S / F (a soft-iron error ε changes the norm by εF). Both act only
   with ``pf_hold_prior = 0``: a held calibration is the prior itself until the first declared
   change, after which the change spreads apply.

Settings that do not depend on the sensor keep the runtime defaults (particles 128, change
threshold 25, norm time constant 300 updates, Rao-Blackwellised mode, held prior).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from training.models import magpf

#: Rule constants (see the module docstring).
UPDATE_INTERVAL_S = 0.02
GATE_SIGMAS = float(np.sqrt(2.0 * np.log(1000.0)))
CHANGE_MARGIN = 2.0
SETTLE_SAMPLES = 100.0
#: A time step longer than this many sample periods (or ≤ 0) starts a new segment.
GAP_PERIODS = 5.0
#: Variogram lags: factor between successive lags, longest lag [s].
LAG_FACTOR = float(np.sqrt(2.0))
MAX_LAG_S = 1.0
#: Fewest finite samples the statistics need.
MIN_SAMPLES = 100


def norm_time_constant_updates() -> float:
    """The filter's ambient-norm time constant [updates]: its internal default (sources/ImuMagPf.c
    ImuMagPfInternal, not an FMU parameter)."""
    return float(magpf.internal_defaults()["norm_time_constant"])


def change_threshold() -> float:
    """The filter's change threshold [1] on the averaged normalised innovation: its internal default."""
    return float(magpf.internal_defaults()["change_threshold"])


def outlier_sigmas() -> float:
    """Glitch gate of the statistics [robust σ]: the filter's own, sqrt(4 × change threshold) = 10."""
    return float(np.sqrt(4.0 * change_threshold()))


@dataclass(frozen=True)
class NoiseStatistics:
    """sigma: std of |h_c| about the test's running mean [µT]; sigma_white: white noise per axis
    [µT]; sigma_slow: sqrt(sigma² − sigma_white²) [µT]; lags [samples] and gamma [µT²]: the
    variogram of |h_c|; plateau_lag [samples]: where sigma_white was read; samples: used count."""

    sigma: float
    sigma_white: float
    sigma_slow: float
    lags: np.ndarray
    gamma: np.ndarray
    plateau_lag: int
    samples: int


def _segments(field: np.ndarray, t: np.ndarray, rate_hz: float) -> list[np.ndarray]:
    """Index arrays of the runs of finite samples with steps in (0, GAP_PERIODS / rate]."""
    finite = np.all(np.isfinite(field), axis=1) & np.isfinite(t)
    step_ok = (np.diff(t) > 0.0) & (np.diff(t) <= GAP_PERIODS / rate_hz) & finite[1:] & finite[:-1]
    cuts = np.flatnonzero(~step_ok) + 1
    runs = np.split(np.arange(len(t)), cuts)
    return [r[finite[r]] for r in runs if np.count_nonzero(finite[r]) >= 2]


def _gated_variance(x: np.ndarray) -> float:
    """Variance of x about its mean over the values within `outlier_sigmas()` robust σ of the median."""
    med = np.median(x)
    scale = 1.4826 * np.median(np.abs(x - med))
    if scale > 0.0:
        x = x[np.abs(x - med) <= outlier_sigmas() * scale]
    return float(np.var(x))


def _running_mean(x: np.ndarray, samples: float) -> np.ndarray:
    """Exponential running mean with time constant `samples`, started at the mean of the first ones."""
    from scipy.signal import lfilter
    a = 1.0 / max(samples, 1.0)
    start = float(np.mean(x[:max(1, int(samples))]))
    y, _ = lfilter([a], [1.0, -(1.0 - a)], x, zi=[(1.0 - a) * start])
    return y


def _variogram(norms: list[np.ndarray], rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """(lags [samples], gamma [µT²]) of the norm series, pooled over segments."""
    longest = max(2, int(MAX_LAG_S * rate_hz))
    lags = sorted({int(round(LAG_FACTOR ** k)) for k in range(200) if LAG_FACTOR ** k <= longest})
    out_lags, gamma = [], []
    for lag in lags:
        diffs = [n[lag:] - n[:-lag] for n in norms if len(n) > lag]
        if sum(len(d) for d in diffs) < MIN_SAMPLES // 2:
            break
        out_lags.append(lag)
        gamma.append(0.5 * _gated_variance(np.concatenate(diffs)))
    return np.array(out_lags, dtype=int), np.array(gamma)


def decimation_for(rate_hz: float, update_interval_s: float = UPDATE_INTERVAL_S) -> int:
    """Rule 1: filter every d-th sample so that updates come every update_interval_s [s]."""
    return max(1, int(round(float(rate_hz) * update_interval_s)))


def noise_statistics(field_calibrated, t, rate_hz: float, decimation: int) -> NoiseStatistics:
    """σ, σ_w, σ_slow of the calibrated field (N, 3) µT at times t (N,) s; the running mean of σ
    has the filter's time constant at `decimation`. ValueError with fewer than MIN_SAMPLES usable."""
    field = np.asarray(field_calibrated, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)
    if field.ndim != 2 or field.shape[1] != 3 or t.shape != (field.shape[0],):
        raise ValueError(f"field_calibrated must be (N, 3) and t (N,): got {field.shape} and {t.shape}")
    if not (np.isfinite(rate_hz) and rate_hz > 0):
        raise ValueError(f"rate_hz must be > 0, got {rate_hz}")
    segments = _segments(field, t, rate_hz)
    norms = [np.linalg.norm(field[s], axis=1) for s in segments]
    count = sum(len(n) for n in norms)
    if count < MIN_SAMPLES:
        raise ValueError(f"need >= {MIN_SAMPLES} finite calibrated field samples, got {count}")
    window = norm_time_constant_updates() * decimation
    residual = np.concatenate([np.concatenate([n - _running_mean(n, window),
                                               n[::-1] - _running_mean(n[::-1], window)]) for n in norms])
    sigma = float(np.sqrt(_gated_variance(residual)))
    lags, gamma = _variogram(norms, rate_hz)
    if len(gamma) >= 2:
        slope = np.diff(np.log(np.maximum(gamma, 1e-300))) / np.diff(np.log(lags))
        k = int(np.argmin(slope))
    else:
        k = 0
    sigma_white = min(float(np.sqrt(gamma[k])), sigma)
    sigma_slow = float(np.sqrt(max(sigma ** 2 - sigma_white ** 2, 0.0)))
    return NoiseStatistics(sigma, sigma_white, sigma_slow, lags, gamma, int(lags[k]), count)


def pf_settings_from_calibration(field_calibrated, t, field_norm: float, rate_hz: float, *,
                                 update_interval_s: float = UPDATE_INTERVAL_S,
                                 gate_sigmas: float = GATE_SIGMAS,
                                 change_margin: float = CHANGE_MARGIN,
                                 settle_samples: float = SETTLE_SAMPLES) -> dict[str, float]:
    """FMU settings of the particle filter (names of contract.layout.SETTINGS) from calibration data.

    field_calibrated: (N, 3) µT, the magnetometer after the trained calibration (several
    recordings may be concatenated: a non-increasing time or a gap starts a new segment);
    t: (N,) s; field_norm: |h_0| [µT] the calibration was fitted to; rate_hz: sample rate [Hz].
    The keyword constants are the rules' (module docstring), for sensitivity studies.
    Returns pf_decimation [samples], pf_measurement_noise [µT], pf_min_rotation [rad],
    pf_change_spread_hard [µT], pf_settle_spread [µT], pf_prior_spread_hard [µT],
    pf_prior_spread_soft [1].
    """
    if not (np.isfinite(field_norm) and field_norm > 0):
        raise ValueError(f"field_norm must be > 0 µT, got {field_norm}")
    d = decimation_for(rate_hz, update_interval_s)
    st = noise_statistics(field_calibrated, t, rate_hz, d)
    settle = max(st.sigma_slow, st.sigma_white * float(np.sqrt(3.0 / settle_samples)))
    return {
        "pf_decimation": float(d),
        "pf_measurement_noise": st.sigma,
        "pf_min_rotation": float(min(gate_sigmas * np.sqrt(2.0) * st.sigma_white / field_norm, np.pi / 2)),
        "pf_change_spread_hard": change_margin * float(np.sqrt(change_threshold())) * st.sigma,
        "pf_settle_spread": settle,
        "pf_prior_spread_hard": settle,
        "pf_prior_spread_soft": settle / float(field_norm),
    }
