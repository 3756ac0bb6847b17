"""A population of sensor units of one type: the spread of each error parameter across units.

A sensor file describes one nominal unit. Each triad table may add a `spread` sub-table that names
keys of that triad table and the standard deviation of that parameter across units, in the key's
own unit (a number for every element, or an array of the key's shape):

    [gyr]
    bias_dps = [0.52, -0.38, 0.45]
    [gyr.spread]
    bias_dps = 0.15                 # σ [°/s] of each axis's bias across units
    scale = [0.002, 0.002, 0.004]   # σ [1] per axis

A unit is the nominal unit with every spread parameter drawn once, Gaussian around its nominal
value (`draw_unit`); a symmetric matrix (soft_iron) gets a symmetric perturbation. Keys without a
spread are the same in every unit. Simulating the file as a single sensor uses the nominal unit
(`nominal`).
"""
from __future__ import annotations

import copy
from pathlib import Path

import numpy as np

from contract.errors import ScenarioError

#: Name of the sub-table of a triad table that declares the spreads.
SPREAD_TABLE = "spread"
#: Tables of a sensor file that may carry a spread.
TRIAD_TABLES = ("gyr", "acc", "mag")
#: Keys whose value is a symmetric matrix: their perturbation is symmetrised.
SYMMETRIC_KEYS = ("soft_iron",)


def nominal(raw: dict) -> dict:
    """The sensor table `raw` (parsed TOML) without its spread tables: the nominal unit."""
    out = copy.deepcopy(raw)
    for triad in TRIAD_TABLES:
        if isinstance(out.get(triad), dict):
            out[triad].pop(SPREAD_TABLE, None)
    return out


def spreads(raw: dict, path: Path) -> dict[str, np.ndarray]:
    """{"<triad>.<key>": σ array of the key's shape} declared in the sensor table `raw` read from
    `path`; ScenarioError naming the file and key for a spread of an absent or non-numeric key, or a
    negative, non-finite or wrongly shaped σ."""
    out = {}
    for triad in TRIAD_TABLES:
        table = raw.get(triad)
        declared = table.get(SPREAD_TABLE, {}) if isinstance(table, dict) else {}
        if not isinstance(declared, dict):
            raise ScenarioError(f"{path}: [{triad}] key '{SPREAD_TABLE}': expected a table")
        for key, sigma in declared.items():
            out[f"{triad}.{key}"] = _sigma(table, key, sigma, f"{path}: [{triad}.{SPREAD_TABLE}] key '{key}'")
    return out


def _sigma(table: dict, key: str, sigma, where: str) -> np.ndarray:
    """σ of `key` broadcast to the shape of its nominal value in `table`."""
    if key not in table or key == SPREAD_TABLE:
        raise ScenarioError(f"{where}: the triad table sets no '{key}' to spread")
    try:
        value = np.asarray(table[key], dtype=float)
        spread = np.broadcast_to(np.asarray(sigma, dtype=float), value.shape).copy()
    except (TypeError, ValueError):
        raise ScenarioError(f"{where}: expected a number or an array of the shape of '{key}', "
                            f"got {sigma!r}") from None
    if not np.all(np.isfinite(spread)) or np.any(spread < 0):
        raise ScenarioError(f"{where}: expected finite σ ≥ 0, got {sigma!r}")
    return spread


def draw_unit(raw: dict, path: Path, rng: np.random.Generator) -> dict:
    """One unit of the population: the nominal sensor table with every spread parameter drawn
    (nominal + σ · N(0, 1) per element, in the order of `spreads`; symmetric keys symmetrised)."""
    out = nominal(raw)
    for name, sigma in spreads(raw, path).items():
        triad, key = name.split(".", 1)
        delta = sigma * rng.standard_normal(sigma.shape)
        if key in SYMMETRIC_KEYS:
            delta = 0.5 * (delta + delta.T)
        value = np.asarray(out[triad][key], dtype=float) + delta
        out[triad][key] = value.tolist() if value.ndim else float(value)
    return out
