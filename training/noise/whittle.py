"""Whittle (frequency-domain maximum-likelihood) fit of N, B, K to still data, and its Cramér–Rao bound.

The model is the simulator's noise (training.simulator.sensors): white noise of density N [u/√Hz]
(per-sample σ = N √fs), a bias random walk K [u/√s] (increments K √Δt) and the flicker-like bias of
instability B [u] (the sum of the same FLICKER_TERMS first-order Gauss–Markov poles, τk = 10^(k/2) s,
σk = FLICKER_SIGMA_FACTOR · B). The random walk is not stationary, so each stretch is differenced once:
y = Δx is stationary with the discrete-time spectrum (ω = 2π f / fs, D = 4 sin²(ω/2))

    S(ω) = N² fs · D  +  K² / fs  +  B² · D · Σk σ̂k² (1 − ak²) / (1 − 2 ak cos ω + ak²)

(σ̂k = FLICKER_SIGMA_FACTOR, ak = exp(−Δt/τk)); S is linear in (N², B², K²). The Whittle negative
log-likelihood over the Fourier frequencies 0 < ω < π of every stretch is Σ ln S + I/S, I the periodogram
(tapered, with S its expectation: `expected_basis`); it is minimised over the log-parameters by Fisher
scoring. Its Fisher information at θ = (ln N, ln B, ln K) is I_ij = ½ Σ ∂lnS/∂θi ∂lnS/∂θj summed over all
the two-sided frequencies (= Σ over 0 < ω < π), whose inverse bounds the variance of any unbiased
estimator of the relative figures (the Cramér–Rao bound; `cramer_rao` uses the untapered spectrum `basis`,
the record's information, not this estimator's).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from training.simulator.sensors import FLICKER_SIGMA_FACTOR, FLICKER_TERMS

#: Fewest samples of a stretch that enters the likelihood (shorter ones carry no K information).
MIN_SAMPLES = 16
#: Fraction of a differenced stretch inside the taper's two cosine ends.
TAPER_FRACTION = 0.1
#: Fisher-scoring iterations at most, the largest step of a log-power, and the log-powers' range around the start.
MAX_ITERATIONS = 200
STEP_LIMIT = 2.0
LOG_FLOOR = -40.0


def basis(m: int, rate_hz: float) -> np.ndarray:
    """(3, F) spectra of the differenced series of m samples at the Fourier frequencies 0 < ω < π, per unit
    N², B², K² (rows: white, flicker, random walk)."""
    j = np.arange(1, (m - 1) // 2 + 1)
    w = 2.0 * np.pi * j / m
    d = 4.0 * np.sin(w / 2.0) ** 2
    dt = 1.0 / rate_hz
    flicker = np.zeros_like(w)
    c = np.cos(w)
    for k in range(FLICKER_TERMS):
        a = np.exp(-dt / 10.0 ** (k / 2.0))
        flicker += FLICKER_SIGMA_FACTOR ** 2 * (1.0 - a * a) / (1.0 - 2.0 * a * c + a * a)
    return np.vstack([rate_hz * d, d * flicker, np.full_like(w, dt)])


def taper(m: int) -> np.ndarray:
    """The data taper (m,) of a differenced stretch: Tukey, cosine ends of TAPER_FRACTION / 2 each, Σ h² = 1."""
    from scipy.signal.windows import tukey
    h = tukey(m, TAPER_FRACTION) if m > 2 else np.ones(m)
    return h / np.sqrt(np.sum(h * h))


def expected_basis(m: int, rate_hz: float) -> np.ndarray:
    """(3, F) expected tapered periodograms of the differenced series of m samples (a stretch of m + 1), per
    unit N², B², K², at the frequencies of `basis`: E I_j = Σ_|τ|<m ρ(τ) c(τ) e^(−iω_j τ), c the differenced
    processes' autocovariances, ρ the taper's autocorrelation (the debiased Whittle likelihood, Sykulski et al.
    2019). Untapered, the differenced white noise leaves 2 N² fs / m in every bin (its two end samples), which
    at the lowest frequencies outweighs the random walk on the benchmark's 3 h and leaves K undetermined
    (−100 … +500 %); the taper averages the ends."""
    lag = np.arange(m, dtype=float)
    h = taper(m)
    size = 1 << int(np.ceil(np.log2(2 * m)))
    rho = np.fft.irfft(np.abs(np.fft.rfft(h, size)) ** 2, size)[:m]
    dt = 1.0 / rate_hz
    c = np.zeros((3, m))
    c[0, 0], c[0, 1] = 2.0 * rate_hz, -rate_hz
    for k in range(FLICKER_TERMS):
        a = np.exp(-dt / 10.0 ** (k / 2.0))
        var = FLICKER_SIGMA_FACTOR ** 2
        c[1, 0] += 2.0 * var * (1.0 - a)
        c[1, 1:] -= var * (1.0 - a) ** 2 * a ** (lag[1:] - 1.0)
    c[2, 0] = dt
    spectra = 2.0 * np.fft.rfft(c * rho, axis=1).real - c[:, :1] * rho[0]
    return spectra[:, 1:(m - 1) // 2 + 1]


def periodogram(x: np.ndarray) -> np.ndarray:
    """Tapered periodogram |rfft(h Δx)|² of the differenced stretch at the frequencies of `basis`
    (m = len(x) − 1)."""
    y = np.diff(np.asarray(x, float))
    m = y.size
    return np.abs(np.fft.rfft(y * taper(m))[1:(m - 1) // 2 + 1]) ** 2


@dataclass(frozen=True)
class WhittleFit:
    """The fitted figures [u/√Hz, u, u/√s] and the Cramér–Rao 1σ of their logarithms at the fit."""

    noise_density: float
    bias_instability: float
    random_walk: float
    sigma_log: np.ndarray


def _stack(pieces: list[np.ndarray], rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """The basis (3, F) and periodogram (F,) of every stretch long enough, concatenated."""
    bases, pers = [], []
    for x in pieces:
        if len(x) >= MIN_SAMPLES:
            bases.append(expected_basis(len(x) - 1, rate_hz))
            pers.append(periodogram(x))
    if not bases:
        return np.zeros((3, 0)), np.zeros(0)
    return np.hstack(bases), np.concatenate(pers)


def fisher(a: np.ndarray, power: np.ndarray) -> np.ndarray:
    """Fisher information (3, 3) of θ = (ln N, ln B, ln K) for basis `a` (3, F) at powers (N², B², K²):
    Σ_j ∂lnS/∂θi ∂lnS/∂θj over the F frequencies 0 < ω < π, each periodogram ordinate being exponential
    with mean S_j (information 1 on ln S_j) — the ½ Σ of the two-sided sum over all m frequencies."""
    parts = a * np.asarray(power, float)[:, None]
    g = 2.0 * parts / parts.sum(axis=0)
    return g @ g.T


def cramer_rao(n: int, rate_hz: float, n_density: float, b: float, k: float) -> np.ndarray:
    """Cramér–Rao 1σ of (ln N, ln B, ln K), the relative 1σ of N, B, K, for one still stretch of n samples."""
    info = fisher(basis(n - 1, rate_hz), [n_density ** 2, b ** 2, k ** 2])
    return np.sqrt(np.diag(np.linalg.inv(info)))


def whittle_fit(pieces: list[np.ndarray], rate_hz: float, start: tuple[float, float, float]) -> WhittleFit | None:
    """Maximum-Whittle-likelihood N, B, K of the still stretches `pieces` (each a 1-D series of one axis),
    started from `start` = (N, B, K) (zeros are replaced by small values); None without a stretch of
    MIN_SAMPLES."""
    a, per = _stack(pieces, rate_hz)
    if per.size == 0:
        return None
    # work relative to the start (white: the differenced data's mean level), so the log-parameters are O(1)
    white = float(np.mean(per) / np.mean(a[0]))
    ref = np.array([max(start[0] ** 2, 1e-3 * white), max(start[1] ** 2, 1e-6 * white),
                    max(start[2] ** 2, 1e-6 * white)])
    scale = float(np.mean(per))
    unit = a * ref[:, None] / scale
    per_unit = per / scale
    count = per.size

    def objective(p):
        s = np.exp(p) @ unit
        return float(np.sum(np.log(s) + per_unit / s)) / count

    # Fisher scoring on the log-powers (the expected Hessian Σ g gᵀ with g = ∂lnS/∂p), halving the step
    # while the likelihood does not improve.
    p = np.zeros(3)
    value = objective(p)
    for _ in range(MAX_ITERATIONS):
        e = np.exp(p)
        s = e @ unit
        g = unit * e[:, None] / s
        grad = g @ (1.0 - per_unit / s) / count
        hess = g @ g.T / count + 1e-12 * np.eye(3)
        step = -np.linalg.solve(hess, grad)
        step = np.clip(step, -STEP_LIMIT, STEP_LIMIT)
        for _ in range(30):
            trial = np.clip(p + step, LOG_FLOOR, -LOG_FLOOR)
            new = objective(trial)
            if new <= value:
                break
            step = step / 2.0
        else:
            break
        moved = np.max(np.abs(trial - p))
        p, value = trial, new
        if moved < 1e-6:
            break
    res_x = p
    power = np.exp(res_x) * ref
    info = fisher(a, power)
    try:
        sigma = np.sqrt(np.abs(np.diag(np.linalg.inv(info))))
    except np.linalg.LinAlgError:
        sigma = np.full(3, np.inf)
    return WhittleFit(float(np.sqrt(power[0])), float(np.sqrt(power[1])), float(np.sqrt(power[2])), sigma)
