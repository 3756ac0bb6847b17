"""Allan deviation of still stretches and the IEEE 952 noise terms read from it.

The overlapping Allan variance (allantools.oadev, NIST SP 1065 eq. 11) of a rate signal with white
noise density N [u/√Hz], bias instability B [u] (flicker floor) and random walk K [u/√s] is
(IEEE Std 952-1997, annex C; El-Sheimy et al., IEEE TIM 57(1), 2008):

    σ²(τ) = N²/τ + (2 ln2/π) B² + K² τ/3

Pooling: every still stretch gives its own overlapping Allan variance at the averaging factors m it
is long enough for (a stretch of n samples serves m ≤ n / MIN_CLUSTERS); the pooled variance is the
term-weighted mean and the equivalent degrees of freedom (edf) add up (independent stretches).
The edf of each stretch comes from allantools.edf_greenhall for the noise that dominates at τ, the
confidence intervals from allantools.confidence_interval (χ², 68.3 % unless told).

Fit: the three coefficients (N², (2 ln2/π) B², K²/3) by non-negative weighted least squares on σ²,
each τ weighted by its own variance 2 σ⁴/edf with σ² the model's (iterated) and the edf capped at
EDF_CAP: the short τ have edf in the 10⁵ and the points are strongly correlated, so uncapped they
pin the fit to the shortest τ and any departure from the ideal lines there (a flicker process that
flattens only above a few seconds, an anti-aliasing filter, quantisation) moves B and K by
tens of percent (measured: B −12…−23 %, K +5…+85 % uncapped, B −8…+5 %, K −40…+21 % capped,
3 h static, benchmarks/noise_recovery.py grades). The B term is kept only
where a floor shows (its share of the model is largest somewhere in the curve); otherwise the fit
has two terms, which keeps K from trading against a phantom floor. N is then re-read on the τ where
white noise makes WHITE_SHARE of the model, with the full edf (the −1/2 line, as IEEE 952 reads it).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import allantools
import numpy as np
from scipy.optimize import nnls

#: Flicker floor factor: σ_floor = √(2 ln2/π) · B = 0.664 B (IEEE 952).
FLOOR_FACTOR = float(np.sqrt(2.0 * np.log(2.0) / np.pi))
#: A stretch of n samples gives the Allan variance up to τ = n / (MIN_CLUSTERS · rate): nine
#: clusters leave at least ~8 degrees of freedom at the longest τ (the usual cut, allan_variance_ros).
MIN_CLUSTERS = 9
#: Averaging times per decade of the log-spaced τ grid.
TAUS_PER_DECADE = 12
#: Confidence level of every interval: one standard deviation of a normal variable (68.3 %).
CONFIDENCE = float(allantools.confidence_interval.__defaults__[0])
#: allantools' noise exponents: white rate (N), flicker (B), random walk (K).
ALPHA = {"noise_density": 0, "bias_instability": -1, "random_walk": -2}
#: Largest edf a τ counts with in the fit (see the module docstring).
EDF_CAP = 100.0
#: N is refined on the τ where white noise is at least this share of the model.
WHITE_SHARE = 0.9
#: IRLS passes of the weighted fit (the weights settle after two or three).
FIT_PASSES = 4
#: A term "shows" at τ when it is at least this share of the model variance there; a figure is read
#: (its CI taken) at the shortest such τ, where the edf is largest.
DOMINANT_SHARE = 0.5


@dataclass(frozen=True)
class AllanCurve:
    """Pooled overlapping Allan variance of one axis: taus (M,) s, avar (M,) u², terms (M,) summed
    oadev terms; lengths: samples of every stretch used; rate_hz."""

    taus: np.ndarray
    avar: np.ndarray
    terms: np.ndarray
    lengths: tuple[int, ...]
    rate_hz: float

    @property
    def adev(self) -> np.ndarray:
        """Allan deviation (M,) [u]."""
        return np.sqrt(self.avar)

    def edf(self, alpha: np.ndarray | int) -> np.ndarray:
        """Equivalent degrees of freedom (M,) of the pooled variance for noise exponent alpha (per τ or
        one): Σ over stretches of allantools.edf_greenhall (overlapping Allan, d = 2)."""
        alphas = np.broadcast_to(np.asarray(alpha, dtype=int), self.taus.shape)
        out = np.zeros(self.taus.size)
        for j, (tau, a) in enumerate(zip(self.taus, alphas)):
            m = int(round(tau * self.rate_hz))
            out[j] = sum(_edf(int(a), m, n + 1) for n in self.lengths if n >= MIN_CLUSTERS * m)
        return out

    def ci(self, alpha: np.ndarray | int, level: float = CONFIDENCE) -> np.ndarray:
        """(M, 2) confidence interval of the Allan deviation [u] (allantools.confidence_interval)."""
        edf = self.edf(alpha)
        return np.array([allantools.confidence_interval(float(d), float(e), ci=level)
                         for d, e in zip(self.adev, edf)])


@lru_cache(maxsize=65536)
def _edf(alpha: int, m: int, phase_points: int) -> float:
    """allantools.edf_greenhall of the overlapping Allan variance (d = 2), cached (the fit asks often)."""
    return float(allantools.edf_greenhall(alpha=alpha, d=2, m=m, N=phase_points, overlapping=True))


def tau_grid(longest: int, rate_hz: float) -> np.ndarray:
    """Log-spaced averaging factors m (integers, unique) from 1 to longest / MIN_CLUSTERS, as taus [s]."""
    top = longest // MIN_CLUSTERS
    if top < 1:
        return np.zeros(0)
    count = max(2, int(np.ceil(np.log10(top) * TAUS_PER_DECADE)) + 1)
    m = np.unique(np.round(np.logspace(0.0, np.log10(top), count)).astype(int))
    return m / rate_hz


def allan_curve(stretches: list[np.ndarray], rate_hz: float) -> AllanCurve | None:
    """Pooled overlapping Allan variance of the still stretches (each (n,) [u], its mean or reference
    already removed) sampled at rate_hz [Hz]; None when no stretch reaches MIN_CLUSTERS samples."""
    stretches = [np.asarray(s, dtype=float) for s in stretches if len(s) >= MIN_CLUSTERS]
    if not stretches:
        return None
    taus = tau_grid(max(len(s) for s in stretches), rate_hz)
    weighted, terms = np.zeros(taus.size), np.zeros(taus.size)
    for s in stretches:
        usable = taus[np.round(taus * rate_hz) * MIN_CLUSTERS <= len(s)]
        if usable.size == 0:
            continue
        t, dev, _, n = allantools.oadev(s - s.mean(), rate=rate_hz, data_type="freq", taus=usable)
        index = np.searchsorted(taus, t - 0.5 / rate_hz)
        weighted[index] += dev ** 2 * n
        terms[index] += n
    keep = terms > 0
    return AllanCurve(taus[keep], weighted[keep] / terms[keep], terms[keep],
                      tuple(len(s) for s in stretches), float(rate_hz))


def model_terms(taus: np.ndarray) -> np.ndarray:
    """(M, 3) design matrix of σ² in the coefficients (N², (2 ln2/π) B², K²/3): [1/τ, 1, τ]."""
    return np.column_stack([1.0 / taus, np.ones_like(taus), taus])


@dataclass(frozen=True)
class AllanFit:
    """Fitted σ²(τ) = c0/τ + c1 + c2 τ: coefficients (3,) [u²·s, u², u²/s]; floor: whether the
    B term was fitted (a floor shows)."""

    coefficients: np.ndarray
    floor: bool

    @property
    def noise_density(self) -> float:
        """N [u/√Hz] = √c0: the −1/2 line's value at τ = 1 s."""
        return float(np.sqrt(self.coefficients[0]))

    @property
    def bias_instability(self) -> float:
        """B [u] = √c1 / 0.664: the floor over √(2 ln2/π)."""
        return float(np.sqrt(self.coefficients[1]) / FLOOR_FACTOR)

    @property
    def random_walk(self) -> float:
        """K [u/√s] = √(3 c2): the +1/2 line's value at τ = 3 s."""
        return float(np.sqrt(3.0 * self.coefficients[2]))

    def parts(self, taus: np.ndarray) -> np.ndarray:
        """(M, 3) the three terms of σ² [u²] at taus [s]."""
        return model_terms(taus) * self.coefficients

    def avar(self, taus: np.ndarray) -> np.ndarray:
        """Model σ² (M,) [u²]."""
        return self.parts(taus).sum(axis=1)

    def dominant_alpha(self, taus: np.ndarray) -> np.ndarray:
        """(M,) allantools noise exponent of the largest term at each τ (0, −1, −2)."""
        return np.array([0, -1, -2])[np.argmax(self.parts(taus), axis=1)]


def _wls(curve: AllanCurve, columns: list[int]) -> tuple[np.ndarray, float]:
    """Iteratively reweighted NNLS of σ² on the chosen columns; returns the coefficients (3,) and the
    weighted residual sum of squares (χ²)."""
    a = model_terms(curve.taus)[:, columns]
    edf = np.minimum(curve.edf(0), EDF_CAP)
    model = curve.avar.copy()
    coefficients = np.zeros(3)
    chi2 = np.inf
    for _ in range(FIT_PASSES):
        sigma = model * np.sqrt(2.0 / np.maximum(edf, 1.0))  # σ of the σ² estimate at each τ
        c, _ = nnls(a / sigma[:, None], curve.avar / sigma)
        coefficients = np.zeros(3)
        coefficients[columns] = c
        fit = AllanFit(coefficients, 1 in columns)
        model = np.maximum(fit.avar(curve.taus), 1e-300)
        edf = np.minimum(curve.edf(fit.dominant_alpha(curve.taus)), EDF_CAP)
        chi2 = float(np.sum(((curve.avar - model) / (model * np.sqrt(2.0 / np.maximum(edf, 1.0)))) ** 2))
    return coefficients, chi2


def fit_allan(curve: AllanCurve) -> AllanFit:
    """The noise model of `curve`: white + random walk, and the flicker floor too when it shows (the
    three-term fit gives the floor the largest share of the model at some τ)."""
    full, _ = _wls(curve, [0, 1, 2])
    fit = AllanFit(full, True)
    parts = fit.parts(curve.taus)
    if not (full[1] > 0.0 and np.any(parts[:, 1] >= DOMINANT_SHARE * parts.sum(axis=1))):
        two, _ = _wls(curve, [0, 2])
        fit = AllanFit(two, False)
    return _white_refined(curve, fit)


def _white_refined(curve: AllanCurve, fit: AllanFit) -> AllanFit:
    """N² read on the −1/2 line alone: the τ where white noise is WHITE_SHARE of the model, each with its
    full (uncapped) edf, the other two terms held — the short τ pin N far better than the capped fit."""
    parts = fit.parts(curve.taus)
    white = parts[:, 0] >= WHITE_SHARE * parts.sum(axis=1)
    if not np.any(white):
        return fit
    taus, avar = curve.taus[white], curve.avar[white]
    weight = curve.edf(0)[white] / np.maximum(fit.avar(taus), 1e-300) ** 2
    y = avar - fit.coefficients[1] - fit.coefficients[2] * taus
    c0 = float(np.sum(weight * y / taus) / np.sum(weight / taus ** 2))
    if c0 <= 0.0:
        return fit
    return AllanFit(np.array([c0, fit.coefficients[1], fit.coefficients[2]]), fit.floor)
