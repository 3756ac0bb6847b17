"""A fleet prior: what the calibrations of many units of one type say about the next unit.

Per triad, the gain/bias temperature model's coefficients θ = [A's 6 free entries, g, b] (the
units of ThermalModel) of every unit calibrated against a reference, at a common temperature
normalisation (t0, ts) and degree: their mean and standard deviation across units, the fits'
residual RMS (the noise the data of one unit carry) and the temperature range the units were
calibrated over. `GainBiasFitter(prior=...)` then fits the maximum a posteriori model: the data's
mean squared error plus the prior's

    σ_n² / (3N) · Σ_j ((θ_j − μ_j) / σ_j)²

(the negative log posterior of Gaussian noise σ_n and a Gaussian prior, scaled like the MSE), so a
short recording pins down what it observes and the population supplies the rest: the temperature
dependence of a recording at one temperature, the gains of an axis that did not turn.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from contract.errors import ModelError
from contract.layout import MAX_DEGREE, TRIAD_ORDER
from training.models.thermal import _A_FREE, ThermalModel

#: Units whose normalisation differs from the population's median by more than this [°C] in t0 or
#: ts are left out of the prior (their coefficients are in another basis).
NORMALISATION_TOLERANCE_C = 0.5
#: Fewest units a triad's prior is built from (the standard deviation of fewer says little).
MIN_PRIOR_UNITS = 5
#: Floor of each coefficient's prior σ, relative to the largest σ of its kind (A, g or b): a
#: coefficient every unit shares exactly still gets a finite weight.
SIGMA_FLOOR = 1e-6
#: Largest magnitude of a prior's coefficient, σ, noise or temperature accepted from a fleet.json: far
#: beyond any sensor's (the FMU's input guard stops at 100 rad/s, 2000 m/s², 20 x the field norm),
#: far below what overflows the MAP fit's squares (1e300 means gave an overflow traceback).
MAX_COEFFICIENT = 1e6


@dataclass(frozen=True)
class TriadPrior:
    """The population of one triad's calibration: θ = [a6 (6), g (3·degree), b (3·(degree+1))]."""

    t0: float
    ts: float
    degree: int
    mean: np.ndarray
    sigma: np.ndarray
    noise: float                       # median residual RMS of the units' fits [triad unit]
    t_range: tuple[float, float]       # temperatures the units were calibrated over [°C]
    units: int

    def to_json(self) -> dict:
        """JSON form (fleet.json 'prior')."""
        return {"t0": self.t0, "ts": self.ts, "degree": self.degree, "mean": self.mean.tolist(),
                "sigma": self.sigma.tolist(), "noise": self.noise, "t_range": list(self.t_range), "units": self.units}

    @classmethod
    def from_json(cls, doc) -> "TriadPrior":
        """Inverse of to_json; PriorFieldError naming the field and its allowed range when a field is
        missing, of the wrong type or outside it (fleet.json is an input a user may have edited)."""
        if not isinstance(doc, dict):
            raise PriorFieldError("", "an object with t0, ts, degree, mean, sigma, noise, t_range, units")
        degree = _integer(doc, "degree", 0, MAX_DEGREE)
        size = parameter_count(degree)
        mean = _numbers(doc, "mean", size, f"{size} finite numbers of magnitude < {MAX_COEFFICIENT:g} (degree {degree})")
        sigma = _numbers(doc, "sigma", size, f"{size} numbers in (0, {MAX_COEFFICIENT:g}) (degree {degree})")
        if not np.all(sigma > 0):
            raise PriorFieldError("sigma", f"{size} numbers in (0, {MAX_COEFFICIENT:g}) (degree {degree})")
        t_range = _numbers(doc, "t_range", 2, "[low, high] in °C, finite, low ≤ high")
        if not t_range[0] <= t_range[1]:
            raise PriorFieldError("t_range", "[low, high] in °C, finite, low ≤ high")
        ts = _number(doc, "ts", "a finite number > 0 [°C]")
        if not ts > 0:
            raise PriorFieldError("ts", "a finite number > 0 [°C]")
        noise = _number(doc, "noise", "a finite number ≥ 0 [triad unit]")
        if not noise >= 0:
            raise PriorFieldError("noise", "a finite number ≥ 0 [triad unit]")
        return cls(_number(doc, "t0", "a finite number [°C]"), ts, degree, mean, sigma, noise,
                   (float(t_range[0]), float(t_range[1])), _integer(doc, "units", 1, 10 ** 9))


class PriorFieldError(ValueError):
    """A field of a fleet.json prior entry is missing or outside its allowed range."""

    def __init__(self, name: str, allowed: str):
        self.name, self.allowed = name, allowed
        super().__init__(f"{name or 'the entry'} must be {allowed}")


def _number(doc: dict, name: str, allowed: str) -> float:
    """doc[name] as a finite float of magnitude < MAX_COEFFICIENT (not a bool or a string)."""
    value = doc.get(name)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not abs(value) < MAX_COEFFICIENT:
        raise PriorFieldError(name, allowed)
    return float(value)


def _integer(doc: dict, name: str, low: int, high: int) -> int:
    """doc[name] as an integer in [low, high] (2.0 counts, 1.7 does not)."""
    value = doc.get(name)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or value != int(value) \
            or not low <= value <= high:
        raise PriorFieldError(name, f"an integer in {low}..{high}")
    return int(value)


def _numbers(doc: dict, name: str, size: int, allowed: str) -> np.ndarray:
    """doc[name] as `size` finite floats of magnitude < MAX_COEFFICIENT."""
    value = doc.get(name)
    if not isinstance(value, list) or len(value) != size:
        raise PriorFieldError(name, allowed)
    return np.array([_number({name: v}, name, allowed) for v in value])


def parameter_count(degree: int) -> int:
    """Length of θ for a degree."""
    return 6 + 3 * degree + 3 * (degree + 1)


def theta(model: ThermalModel, degree: int) -> np.ndarray:
    """θ of a model, its polynomials zero-padded to `degree`."""
    g = np.zeros((3, degree))
    g[:, :model.degree] = model.g
    b = np.zeros((3, degree + 1))
    b[:, :model.degree + 1] = model.b
    return np.concatenate([[model.A[i, j] for i, j in _A_FREE], g.ravel(), b.ravel()])


def build_prior(models: list[ThermalModel], noises: list[float]) -> TriadPrior | None:
    """The prior of one triad from the units' models (enabled, full gain/bias fits) and their fits'
    residual RMS; None when fewer than MIN_PRIOR_UNITS share the median normalisation."""
    if not models:
        return None
    t0, ts = float(np.median([m.t0 for m in models])), float(np.median([m.ts for m in models]))
    kept = [(m, n) for m, n in zip(models, noises)
            if abs(m.t0 - t0) <= NORMALISATION_TOLERANCE_C and abs(m.ts - ts) <= NORMALISATION_TOLERANCE_C]
    if len(kept) < MIN_PRIOR_UNITS:
        return None
    degree = max(m.degree for m, _ in kept)
    thetas = np.array([theta(m, degree) for m, _ in kept])
    sigma = thetas.std(axis=0, ddof=1)
    for part in _parts(degree):
        sigma[part] = np.maximum(sigma[part], SIGMA_FLOOR * max(float(sigma[part].max(initial=0.0)), 1e-300))
    ranges = [m.t_range for m, _ in kept if m.t_range is not None]
    t_range = (min(r[0] for r in ranges), max(r[1] for r in ranges)) if ranges else (t0 - ts, t0 + ts)
    return TriadPrior(t0, ts, degree, thetas.mean(axis=0), sigma, float(np.median([n for _, n in kept])),
                      t_range, len(kept))


def _parts(degree: int) -> tuple[slice, slice, slice]:
    """Slices of θ: A's entries, g, b."""
    return slice(0, 6), slice(6, 6 + 3 * degree), slice(6 + 3 * degree, parameter_count(degree))


def load_prior(path: str | Path) -> dict[str, TriadPrior]:
    """{triad: TriadPrior} from a fleet.json (`imufmu fleet train`); ModelError names the file and
    the problem."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text())
    except FileNotFoundError:
        raise ModelError(f"{path}: fleet prior not found") from None
    except (OSError, ValueError, RecursionError) as e:
        raise ModelError(f"{path}: not a fleet.json ({type(e).__name__}: {e})") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("prior"), dict):
        raise ModelError(f"{path}: not a fleet.json with a prior: 'prior' must be an object of triads "
                         f"({', '.join(TRIAD_ORDER)})")
    priors = {}
    for triad, entry in doc["prior"].items():
        if triad not in TRIAD_ORDER:
            raise ModelError(f"{path}: prior.{triad}: unknown triad (allowed: {', '.join(TRIAD_ORDER)})")
        try:
            priors[triad] = TriadPrior.from_json(entry)
        except PriorFieldError as e:
            raise ModelError(f"{path}: prior.{triad}{'.' + e.name if e.name else ''}: must be {e.allowed}") from None
    if not priors:
        raise ModelError(f"{path}: the fleet has no prior (fewer than {MIN_PRIOR_UNITS} units calibrated "
                         "against a reference)")
    return priors
