"""Frames and rotations: the one place of the project's quaternion and Euler-angle helpers.

Convention (ARCHITECTURE.md; the C runtime's, sources/ImuQuaternion.h):
- Quaternions are [w, x, y, z], Hamilton product, rotating body -> nav (NED):
  v_nav = q ⊗ v_body ⊗ q*, equivalently v_nav = R_nb · v_body.
- Euler angles are ZYX and ordered as the rotation sequence: [yaw ψ, pitch θ, roll φ] [rad],
  q = q_z(ψ) ⊗ q_y(θ) ⊗ q_x(φ). The runtime's outputs list them the other way round (roll,
  pitch, yaw); a caller that compares with them reverses the columns where it does so.
- Angles are in radians; differences of angles are wrapped to (−π, π] by `wrap_angle`.
All functions take stacked arrays: quaternions (N, 4), vectors (N, 3); most broadcast (4,), (3,).
The one other quaternion code is differentiable: training/selfcal/rotations.py keeps torch versions of
the product and the exponential map for autograd, in this convention.
"""
from __future__ import annotations

import numpy as np


def wrap_angle(a: np.ndarray) -> np.ndarray:
    """Wrap angles [rad] to (−π, π]."""
    return np.pi - np.mod(np.pi - a, 2.0 * np.pi)


def quat_multiply(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product p ⊗ q of (N, 4) (or broadcastable (4,)) quaternions -> (N, 4)."""
    pw, px, py, pz = np.moveaxis(np.asarray(p, dtype=float), -1, 0)
    qw, qx, qy, qz = np.moveaxis(np.asarray(q, dtype=float), -1, 0)
    return np.stack([pw * qw - px * qx - py * qy - pz * qz,
                     pw * qx + px * qw + py * qz - pz * qy,
                     pw * qy - px * qz + py * qw + pz * qx,
                     pw * qz + px * qy - py * qx + pz * qw], axis=-1)


def quat_conjugate(q: np.ndarray) -> np.ndarray:
    """Conjugate q* (the inverse of a unit quaternion), same shape as q."""
    return np.asarray(q, dtype=float) * np.array([1.0, -1.0, -1.0, -1.0])


def quat_from_rotvec(rotvec: np.ndarray) -> np.ndarray:
    """Exponential map: rotation vector (N, 3) [rad] -> unit quaternion (N, 4).

    q = [cos(|r|/2), sin(|r|/2) r/|r|]; sin(|r|/2)/|r| is evaluated as sinc to stay exact at 0.
    """
    r = np.asarray(rotvec, dtype=float)
    angle = np.linalg.norm(r, axis=-1)
    half_sinc = 0.5 * np.sinc(angle / (2.0 * np.pi))  # sin(|r|/2) / |r|
    return np.concatenate([np.cos(0.5 * angle)[..., None], r * half_sinc[..., None]], axis=-1)


def quat_to_rotvec(q: np.ndarray) -> np.ndarray:
    """Logarithm map of unit quaternions (N, 4) -> rotation vectors (N, 3) [rad], angle ≤ π."""
    q = np.asarray(q, dtype=float)
    q = np.where(q[..., :1] < 0.0, -q, q)          # shortest rotation
    angle = 2.0 * np.arctan2(np.linalg.norm(q[..., 1:], axis=-1), q[..., 0])
    # |q_vec| = sin(angle/2), so r = q_vec · angle / sin(angle/2); via sinc it is exact at 0
    return q[..., 1:] / (0.5 * np.sinc(angle / (2.0 * np.pi)))[..., None]


def quat_from_euler(ypr: np.ndarray) -> np.ndarray:
    """ZYX Euler angles (N, 3) [yaw, pitch, roll] in rad -> quaternion (N, 4), body -> NED."""
    ypr = np.asarray(ypr, dtype=float)
    cy, sy = np.cos(0.5 * ypr[..., 0]), np.sin(0.5 * ypr[..., 0])
    cp, sp = np.cos(0.5 * ypr[..., 1]), np.sin(0.5 * ypr[..., 1])
    cr, sr = np.cos(0.5 * ypr[..., 2]), np.sin(0.5 * ypr[..., 2])
    return np.stack([cr * cp * cy + sr * sp * sy,
                     sr * cp * cy - cr * sp * sy,
                     cr * sp * cy + sr * cp * sy,
                     cr * cp * sy - sr * sp * cy], axis=-1)


def euler_from_quat(q: np.ndarray) -> np.ndarray:
    """Quaternion (N, 4), body -> NED -> ZYX Euler angles (N, 3) [yaw, pitch, roll] in rad."""
    w, x, y, z = np.moveaxis(np.asarray(q, dtype=float), -1, 0)
    yaw = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    pitch = np.arcsin(np.clip(2.0 * (w * y - z * x), -1.0, 1.0))
    roll = np.arctan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    return np.stack([yaw, pitch, roll], axis=-1)


def quat_from_matrix(m: np.ndarray) -> np.ndarray:
    """[w, x, y, z] unit quaternion of one proper rotation matrix m (3×3), the largest-component
    formula (Shepperd) so that no division is by a small number."""
    t = np.trace(m)
    k = int(np.argmax([t, m[0, 0], m[1, 1], m[2, 2]]))
    if k == 0:
        s = 2.0 * np.sqrt(1.0 + t)
        q = [0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s]
    else:
        i, j, l = k - 1, k % 3, (k + 1) % 3
        s = 2.0 * np.sqrt(1.0 + m[i, i] - m[j, j] - m[l, l])
        q = np.zeros(4)
        q[0], q[1 + i] = (m[l, j] - m[j, l]) / s, 0.25 * s
        q[1 + j], q[1 + l] = (m[j, i] + m[i, j]) / s, (m[l, i] + m[i, l]) / s
    return np.asarray(q) / np.linalg.norm(q)


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrices R_nb (N, 3, 3) of unit quaternions (N, 4): v_nav = R_nb · v_body."""
    w, x, y, z = np.moveaxis(np.asarray(q, dtype=float), -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=-1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=-1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=-2)


def rotate_to_body(q: np.ndarray, v_nav: np.ndarray) -> np.ndarray:
    """Nav-frame vectors (N, 3) or (3,) expressed in the body frame: v_b = R_nbᵀ · v_n -> (N, 3)."""
    r = quat_to_matrix(q)
    return np.einsum("nji,nj->ni", r, np.broadcast_to(v_nav, (r.shape[0], 3)))


def body_rate_from_euler(ypr: np.ndarray, ypr_dot: np.ndarray) -> np.ndarray:
    """Body angular rate (N, 3) [rad/s] from ZYX Euler angles (N, 3) and their rates (N, 3).

    ω_b = [φ' − ψ' sin θ,  θ' cos φ + ψ' sin φ cos θ,  −θ' sin φ + ψ' cos φ cos θ]
    (kinematics of the ZYX sequence, e.g. Titterton & Weston, Strapdown Inertial Navigation
    Technology, eq. 3.47 inverted).
    """
    _, pitch, roll = np.moveaxis(ypr, -1, 0)
    dyaw, dpitch, droll = np.moveaxis(ypr_dot, -1, 0)
    return np.stack([droll - dyaw * np.sin(pitch),
                     dpitch * np.cos(roll) + dyaw * np.sin(roll) * np.cos(pitch),
                     -dpitch * np.sin(roll) + dyaw * np.cos(roll) * np.cos(pitch)], axis=-1)


def make_continuous(q: np.ndarray) -> np.ndarray:
    """Flip signs of (N, 4) quaternions so that consecutive rows have a non-negative dot product
    (q and −q are the same rotation; a continuous series is easier to read and compare)."""
    q = np.asarray(q, dtype=float)
    flips = np.einsum("ij,ij->i", q[1:], q[:-1]) < 0.0
    sign = np.concatenate([[1.0], np.where(np.cumsum(flips) % 2 == 1, -1.0, 1.0)])
    return q * sign[:, None]
