"""The rotation a calibrated gyro integrates over the motions between rests, and its derivatives.

Quaternions [w, x, y, z], Hamilton, as training/frames.py. Motions are stacked and zero-padded to one
length (a zero increment is the identity rotation). The increment q_j = exp(φ_j), φ_j = A_g (G(T_j) ⊙
Δθ_j) the calibrated rotation vector of sample step j, turns the body frame after the step into the
one before it, so the prefix product P_j = q_0 ⊗ … ⊗ q_j takes body vectors after step j into the
motion's starting body frame, and the full product R takes the end rest's body frame into the start's:
a world-fixed direction s seen at the start is seen at the end as Rᵀ s (Tedaldi, Pretto, Menegatti,
ICRA 2014, eq. 14-17).

Derivatives by first-order perturbation instead of automatic differentiation: a change δφ_j of one
increment turns the end attitude, seen from the start frame, by R(P_j) δφ_j (to first order in δφ_j,
and up to the right Jacobian of the exponential, I − [φ_j]×/2, whose first-order part is taken into
account by evaluating R(P) half-way through the step). Summed over the steps:

    δΦ = Σ_j R(P_{j-½}) δφ_j,     δ(Rᵀ s) = Rᵀ [s]× δΦ

The Jacobian is therefore one weighted sum over the samples — exact to second order in the step's
rotation, which at ≥ 50 Hz and hand speeds (< 0.1 rad a step) is far below the data noise.
"""
from __future__ import annotations

import numpy as np

from training.frames import quat_from_rotvec, quat_multiply, quat_to_matrix


def calibrated_increments(inc: np.ndarray, tn: np.ndarray, a: np.ndarray, g: np.ndarray) -> np.ndarray:
    """φ = A (G(T) ⊙ Δθ) (S, L, 3) of increments inc (S, L, 3) [rad] at normalised temperatures tn (S, L),
    with G_i = 1 + Σ_k g[i, k-1] Tn^k (g (3, P), P = 0: G = 1)."""
    gain = 1.0 + sum(g[:, k - 1] * tn[..., None] ** k for k in range(1, g.shape[1] + 1))
    return (inc * gain) @ a.T


def prefix_products(q: np.ndarray) -> np.ndarray:
    """Every prefix product q_0 ⊗ … ⊗ q_j along axis 1 of q (S, L, 4) -> (S, L, 4), by the
    Hillis-Steele scan (log2(L) vectorised steps; after the step of offset k, element j holds the
    product of the 2k elements ending at j, the earlier ones on the left)."""
    k = 1
    while k < q.shape[1]:
        q = np.concatenate([q[:, :k], quat_multiply(q[:, :-k], q[:, k:])], axis=1)
        k *= 2
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def attitudes(phi: np.ndarray) -> np.ndarray:
    """Prefix quaternions P (S, L, 4) of the calibrated increments φ (S, L, 3) [rad]."""
    return prefix_products(quat_from_rotvec(phi))


def end_directions(p: np.ndarray, start: np.ndarray) -> np.ndarray:
    """Rᵀ s (S, D, 3): directions s (S, D, 3) of the start rest seen at the end, R = R(P_{L-1})."""
    return np.einsum("sji,sdj->sdi", quat_to_matrix(p[:, -1]), start)


def _mid_matrices(p: np.ndarray) -> np.ndarray:
    """R(P_{j-½}) (S, L, 3, 3): the mean of the attitude matrices before and after each step."""
    r = quat_to_matrix(p)
    before = np.concatenate([np.broadcast_to(np.eye(3), r[:, :1].shape), r[:, :-1]], axis=1)
    return 0.5 * (before + r)


def rotation_jacobian(p: np.ndarray, inc: np.ndarray, tn: np.ndarray, a: np.ndarray, g: np.ndarray) -> np.ndarray:
    """dΦ/dθ (S, 3, 9 + 3P): the end attitude's turn seen from the start frame per parameter, θ = [A_g
    row-major, g[i, k-1] axis-major]; p (S, L, 4) the prefix quaternions at θ, inc (S, L, 3) the raw
    increments, tn (S, L), a (3, 3), g (3, P)."""
    mid = _mid_matrices(p)
    degree = g.shape[1]
    u = inc * (1.0 + sum(g[:, k - 1] * tn[..., None] ** k for k in range(1, degree + 1)))
    cols = [np.einsum("sjak,sjl->sakl", mid, u).reshape(len(inc), 3, 9)]
    for i in range(3):
        for k in range(1, degree + 1):
            cols.append(np.einsum("sjab,b,sj->sa", mid, a[:, i], inc[..., i] * tn ** k)[..., None])
    return np.concatenate(cols, axis=-1)


def direction_jacobian(p: np.ndarray, start: np.ndarray, d_phi: np.ndarray) -> np.ndarray:
    """d(Rᵀ s)/dθ (S, D, 3, n) of directions s (S, D, 3) from dΦ/dθ (S, 3, n): Rᵀ [s]× dΦ/dθ."""
    r = quat_to_matrix(p[:, -1])
    cross = np.cross(start[..., None, :], np.moveaxis(d_phi, 1, 2)[:, None, :, :])   # s × dΦ_col (S, D, n, 3)
    return np.einsum("sji,sdnj->sdin", r, cross)


def winding(p: np.ndarray, axis: np.ndarray, h0: np.ndarray) -> np.ndarray:
    """Winding angle [rad] (S,) about axis (S, 3) of the body vector h0 (S, 3) (both unit, perpendicular)
    over the prefix attitudes p (S, L, 4): the sum of the signed angles between consecutive projections
    of R(P_j) h0 on the plane perpendicular to the axis, starting from h0 itself."""
    v = np.einsum("sjab,sb->sja", quat_to_matrix(p), h0)
    v = np.concatenate([h0[:, None, :], v], axis=1)
    proj = v - np.sum(v * axis[:, None, :], axis=-1, keepdims=True) * axis[:, None, :]
    cross = np.sum(np.cross(proj[:, :-1], proj[:, 1:]) * axis[:, None, :], axis=-1)
    return np.sum(np.arctan2(cross, np.sum(proj[:, :-1] * proj[:, 1:], axis=-1)), axis=1)
