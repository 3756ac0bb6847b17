"""Batch ellipsoid fit of magnetometer data (hard and soft iron) with casadi/IPOPT.

Model (the "linear calibration"): h_c = M (h − offset), M symmetric 3×3, offset (3,) µT, so that
|h_c| equals the local field norm for every sample. Fit: minimise Σ_k (|M (h_k − o)|² − F²)² / F²
over o and the 6 entries of M (algebraic residual, smooth; IPOPT with exact derivatives from
casadi), started from o = mean of the samples and M = I · F / rms|h − mean|. `residual` is the RMS of
|h_c| − F [µT] over the samples used. With the PF's parametrisation, M = I + B and offset = h_p.
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

#: Samples used by the fit at most (evenly thinned beyond): IPOPT time grows linearly with them.
MAX_SAMPLES = 20000


@dataclass(frozen=True)
class EllipsoidFit:
    """offset (3,) µT, matrix (3, 3) symmetric [1], residual: RMS of |h_c| − F [µT]."""

    offset: np.ndarray
    matrix: np.ndarray
    residual: float


def apply_ellipsoid(fit: EllipsoidFit, mag) -> np.ndarray:
    """h_c = M (h − offset) for mag (N, 3) µT -> (N, 3) µT."""
    return (np.asarray(mag, dtype=np.float64) - fit.offset) @ fit.matrix.T


def _symmetric(p) -> ca.MX:
    """Symmetric 3×3 casadi matrix from entries m11 m12 m13 m22 m23 m33."""
    return ca.vertcat(ca.horzcat(p[0], p[1], p[2]), ca.horzcat(p[1], p[3], p[4]),
                      ca.horzcat(p[2], p[4], p[5]))


def fit_ellipsoid(mag, field_norm: float) -> EllipsoidFit:
    """Fit offset and symmetric matrix to mag (N, 3) µT (N ≥ 9, finite rows used) for a field
    norm F [µT]. Raises ValueError when fewer than 9 finite samples or F ≤ 0."""
    m = np.asarray(mag, dtype=np.float64)
    m = m[np.all(np.isfinite(m), axis=1)]
    if m.shape[0] < 9 or not field_norm > 0:
        raise ValueError(f"ellipsoid fit needs >= 9 finite samples and field_norm > 0 "
                         f"(got {m.shape[0]} samples, field_norm={field_norm})")
    if m.shape[0] > MAX_SAMPLES:
        m = m[np.linspace(0, m.shape[0] - 1, MAX_SAMPLES).astype(int)]
    center = m.mean(axis=0)
    scale = field_norm / float(np.sqrt(np.mean(np.sum((m - center) ** 2, axis=1))))
    x = ca.MX.sym("x", 9)
    data = ca.DM(m.T)
    d = data - ca.repmat(x[:3], 1, m.shape[0])
    hc = ca.mtimes(_symmetric(x[3:]), d)
    r = (ca.sum1(hc * hc) - field_norm ** 2) / field_norm
    solver = ca.nlpsol("ellipsoid", "ipopt", {"x": x, "f": ca.sumsqr(r)},
                       {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes"})
    x0 = np.concatenate([center, [scale, 0, 0, scale, 0, scale]])
    sol = np.asarray(solver(x0=x0)["x"]).ravel()
    fit = EllipsoidFit(sol[:3], np.asarray(_symmetric(ca.DM(sol[3:]))), 0.0)
    norms = np.linalg.norm(apply_ellipsoid(fit, m), axis=1)
    return EllipsoidFit(fit.offset, fit.matrix, float(np.sqrt(np.mean((norms - field_norm) ** 2))))
