"""Temperature side of the self-calibration: which distinct temperatures the rest windows pin
down, the polynomial degree of B(T) they allow, and the matrix of powers of normalised temperature.

The bias model is the runtime's (training/models/thermal.py): B_i(T) = sum_k b[i][k] Tn^k with
Tn = (T - t0) / ts. A polynomial of degree P has P + 1 coefficients per axis, so it needs at
least P + 1 distinct temperatures; windows closer than CLUSTER_WIDTH_C count as one.
"""
from __future__ import annotations

import numpy as np

from contract.layout import MAX_DEGREE
from training.models.thermal import (CLUSTER_WIDTH_C, DEFAULT_T0, DEFAULT_TS, normalised_temperature,
                                     temperature_normalisation)


def cluster_labels(temp: np.ndarray) -> np.ndarray:
    """Cluster index (K,) int of each temperature (K,) °C; NaN -> -1.

    Greedy in ascending order: a cluster starts at its coldest member and takes every
    temperature within CLUSTER_WIDTH_C of it; labels count up from 0 (coldest cluster)."""
    temp = np.asarray(temp, dtype=np.float64)
    labels = np.full(temp.shape, -1, dtype=int)
    order = np.argsort(np.where(np.isfinite(temp), temp, np.inf), kind="stable")
    label, start = -1, -np.inf
    for k in order:
        if not np.isfinite(temp[k]):
            break
        if temp[k] - start > CLUSTER_WIDTH_C:
            label, start = label + 1, temp[k]
        labels[k] = label
    return labels


def count_clusters(temp: np.ndarray) -> int:
    """Number of distinct temperatures (K,) °C as defined by `cluster_labels` (0 when none finite)."""
    labels = cluster_labels(temp)
    return int(labels.max() + 1) if labels.size else 0


def choose_degree(temp: np.ndarray, requested: int, points: int,
                  per_degree: int = 1) -> tuple[int, str]:
    """(degree P, reason) of B(T) for rest windows at temperatures temp (K,) °C.

    P <= requested, <= MAX_DEGREE, <= distinct temperatures - 1, and the (P + 1) * per_degree
    coefficients that P adds must leave at least one redundant data point of `points` (so a
    residual remains to judge the fit). The reason says what limited P ('' when requested)."""
    clusters = count_clusters(temp)
    degree = min(int(requested), MAX_DEGREE, max(clusters - 1, 0))
    while degree > 0 and (degree + 1) * per_degree >= points:
        degree -= 1
    if degree == requested:
        return degree, ""
    if clusters <= 1:
        why = ("no temperature recorded" if clusters == 0 else
               f"the rests span {_span_text(temp)}, one distinct temperature "
               f"(< {CLUSTER_WIDTH_C} °C apart)")
        return degree, f"bias constant in temperature: {why}"
    return degree, (f"degree {degree} < requested {requested}: {clusters} distinct temperatures "
                    f"(clusters {CLUSTER_WIDTH_C} °C wide) over {_span_text(temp)}, {points} data points")


def _span_text(temp: np.ndarray) -> str:
    """'lo..hi °C' of the finite temperatures."""
    finite = np.asarray(temp, dtype=np.float64)
    finite = finite[np.isfinite(finite)]
    return f"{finite.min():.1f}..{finite.max():.1f} °C" if finite.size else "no temperature"


def normalisation(temps: list[np.ndarray]) -> tuple[float, float]:
    """(t0, ts) [°C] of the runtime's Tn over all recordings' temperatures (N_i,) each:
    centre and half-range (training.models.thermal.temperature_normalisation), identity when none."""
    joined = np.concatenate([np.asarray(t, dtype=np.float64) for t in temps]) if temps else np.array([])
    norm = temperature_normalisation(joined)
    return norm if norm is not None else (DEFAULT_T0, DEFAULT_TS)


def powers(temp: np.ndarray, t0: float, ts: float, degree: int) -> np.ndarray:
    """Columns Tn^0..Tn^P (K, P+1) of the normalised temperature of temp (K,) °C (NaN -> Tn = 0)."""
    tn = normalised_temperature(temp, t0, ts)
    return np.column_stack([tn ** k for k in range(degree + 1)])


def temperature_span(temp: np.ndarray) -> list[float] | None:
    """[lowest, highest] finite temperature [°C], None when none is finite."""
    finite = np.asarray(temp, dtype=np.float64)
    finite = finite[np.isfinite(finite)]
    return [float(finite.min()), float(finite.max())] if finite.size else None
