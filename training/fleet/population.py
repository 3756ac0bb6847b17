"""The population of a fleet's calibrations: what a unit of this type looks like.

Per unit, the calibrated parameters of every triad at POPULATION_TEMP_C (`unit_parameters`): the
bias, the scale factors (diagonal of the calibration matrix, minus 1) and the cross-axis angles of
the linear map the thermal model applies there. Per parameter over the units that trained: mean,
standard deviation, median and robust σ (1.4826 · MAD). A unit whose parameter lies more than
OUTLIER_SIGMAS robust σ from the median is an outlier, named with the parameter and the distance.
"""
from __future__ import annotations

import numpy as np

from contract.layout import TRIAD_ORDER
from training.artefact import ModelArtefact
from training.display import DISPLAY
from training.models.fit_quality import cross_axis_deg
from training.models.thermal import ThermalModel, apply_thermal

#: Temperature [°C] the units' parameters are compared at (clamped to each unit's calibrated range).
POPULATION_TEMP_C = 25.0
#: Robust standard deviations from the median beyond which a parameter is an outlier: a normal
#: population of 10 000 units × 36 parameters has 1 such value by chance in ~7 000 fleets.
OUTLIER_SIGMAS = 6.0
#: Fewest trained units for outliers to be named: the robust σ (1.4826 · MAD) of n normal values is
#: uncertain by about 1.17/√n of itself, 21 % at 30 units; in a clean fleet of 12 a 3 σ unit came out
#: at 6.3 robust σ (measured: simulate-fleet --devices 12 --seed 0, unit_0005 gyr.bias_x).
MIN_UNITS_FOR_OUTLIERS = 30
#: Consistency factor of the MAD for a normal distribution.
MAD_TO_SIGMA = 1.4826


def linear_map(model: ThermalModel, temp_c: float) -> tuple[np.ndarray, np.ndarray]:
    """(M (3, 3), b (3,)) with apply_thermal(model, x, temp_c) = M (x − b), read off the model by
    applying it to 0 and the unit vectors."""
    points = np.vstack([np.zeros(3), np.eye(3)])
    out = apply_thermal(model, points, np.full(4, temp_c))
    m = (out[1:] - out[0]).T
    return m, -np.linalg.solve(m, out[0])


def unit_parameters(artefact: ModelArtefact) -> dict[str, tuple[float, str]]:
    """{"<triad>.<parameter>": (value, unit)} of one calibration at POPULATION_TEMP_C; a triad left
    uncalibrated (identity) contributes nothing."""
    out = {}
    for triad in TRIAD_ORDER:
        model = artefact.thermal[triad]
        if not model.enabled:
            continue
        unit, factor = DISPLAY[triad]
        m, b = linear_map(model, POPULATION_TEMP_C)
        for axis, value in zip("xyz", b):
            out[f"{triad}.bias_{axis}"] = (float(value * factor), unit)
        for axis, value in zip("xyz", np.diag(m)):
            out[f"{triad}.scale_{axis}"] = (float(value - 1.0), "1")
        pairs = [a + c for a in "xyz" for c in "xyz" if a != c]
        for pair, value in zip(pairs, cross_axis_deg(m)):
            out[f"{triad}.cross_{pair}"] = (value, "°")
    return out


def population(parameters: dict[str, dict[str, tuple[float, str]]]) -> dict[str, dict]:
    """Per parameter over the units {unit: unit_parameters}: unit, units, mean, std, median,
    robust_sigma, p05, p95 and the values by unit."""
    names = sorted({p for params in parameters.values() for p in params})
    out = {}
    for name in names:
        units = [u for u in sorted(parameters) if name in parameters[u]]
        values = np.array([parameters[u][name][0] for u in units])
        median = float(np.median(values))
        out[name] = {"unit": parameters[units[0]][name][1], "units": len(units),
                     "mean": float(values.mean()), "std": float(values.std(ddof=1)) if len(values) > 1 else 0.0,
                     "median": median, "robust_sigma": float(MAD_TO_SIGMA * np.median(np.abs(values - median))),
                     "p05": float(np.percentile(values, 5)), "p95": float(np.percentile(values, 95)),
                     "values": dict(zip(units, values.tolist()))}
    return out


def outliers(stats: dict[str, dict]) -> list[dict]:
    """[{unit, parameter, value, median, robust_sigma, distance}] of every parameter value further
    than OUTLIER_SIGMAS robust σ from the population median, largest distance first; [] for a
    population under MIN_UNITS_FOR_OUTLIERS units."""
    found = []
    for name, s in stats.items():
        if s["units"] < MIN_UNITS_FOR_OUTLIERS or s["robust_sigma"] <= 0.0:
            continue
        for unit, value in s["values"].items():
            distance = abs(value - s["median"]) / s["robust_sigma"]
            if distance > OUTLIER_SIGMAS:
                found.append({"unit": unit, "parameter": name, "value": value, "median": s["median"],
                              "robust_sigma": s["robust_sigma"], "distance": float(distance), "unit_of_value": s["unit"]})
    return sorted(found, key=lambda o: -o["distance"])
