"""Derive missing reference columns of a recording from its reference attitude (used for BROAD).

    ref_gyr = 2 · vec(q* ⊗ dq/dt)                      body rate [rad/s] (q body -> NED)
    ref_mag = R(q)ᵀ · m_ned                            body field [µT] from the earth field in the
                                                       reference's frame (training.data.reference_field:
                                                       sidecar, IGRF at the site, or the angle estimated
                                                       from the magnetometer); left out when unknown
    ref_acc = R(q)ᵀ · (d²p/dt² − g_ned)                 specific force [m/s²] when aux_pos_x/y/z [m]
                                                       (the optical marker position in NED) is present;
                                                       g the recording's local gravity (earth.local_gravity)

Derivatives are Savitzky-Golay (centred, so without delay) over each run of finite reference
samples; runs shorter than the window stay NaN. The marker's lever arm to the IMU is neglected.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.signal import savgol_filter

from training.data.dataset import ImuData
from training.data.earth import gravity_ned, local_gravity
from training.data.reference_field import reference_field
from training.frames import (euler_from_quat, make_continuous, quat_multiply, quat_to_matrix, rotate_to_body,
                             wrap_angle)

#: Smoothing window of the attitude derivative [s]: 0.1 s keeps motion up to ~5 Hz (BROAD's
#: fastest rotations) while averaging the optical orientation noise over ~30 samples at 286 Hz.
RATE_WINDOW_S = 0.1
#: Smoothing window of the position second derivative [s]: doubly differentiated marker noise
#: needs a longer window; 0.2 s still passes the ~2 Hz translations of BROAD.
ACCEL_WINDOW_S = 0.2
POLYORDER = 2
POSITION_COLUMNS = ("aux_pos_x", "aux_pos_y", "aux_pos_z")


def true_runs(ok: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) index ranges of the True runs of a boolean array."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], ok.astype(int), [0]])))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2])]


def _derivative(x: np.ndarray, t: np.ndarray, window_s: float, order: int) -> np.ndarray:
    """Savitzky-Golay derivative of `order` of x (N, k) over finite runs; NaN elsewhere.
    Assumes a near-uniform sample rate within a run (the median step is used)."""
    out = np.full_like(x, np.nan, dtype=np.float64)
    for a, b in true_runs(np.all(np.isfinite(x), axis=1)):
        dt = float(np.median(np.diff(t[a:b]))) if b - a > 1 else 0.0
        window = max(POLYORDER + 2 + order, int(round(window_s / dt)) | 1) if dt > 0 else 0
        if window % 2 == 0:
            window += 1
        if dt > 0 and b - a >= window:
            out[a:b] = savgol_filter(x[a:b], window, max(POLYORDER, order), deriv=order,
                                     delta=dt, axis=0)
    return out


def rate_from_attitude(t: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Body rate (N, 3) [rad/s] from the attitude q (N, 4) [w, x, y, z] body -> nav; NaN gaps kept."""
    q = np.array(q, dtype=np.float64)
    for a, b in true_runs(np.all(np.isfinite(q), axis=1)):
        q[a:b] = make_continuous(q[a:b] / np.linalg.norm(q[a:b], axis=1, keepdims=True))
    dq = _derivative(q, t, RATE_WINDOW_S, 1)
    w, x, y, z = q.T
    dw, dx, dy, dz = dq.T
    # vec(q* ⊗ dq), q* = [w, −x, −y, −z] (Hamilton product)
    return 2.0 * np.column_stack([w * dx - x * dw - y * dz + z * dy,
                                  w * dy + x * dz - y * dw - z * dx,
                                  w * dz - x * dy + y * dx - z * dw])


def matched_raw(data: ImuData, triad: str) -> np.ndarray:
    """The raw triad (N, 3) filtered as its derived reference is: the rate reference is the
    Savitzky-Golay derivative of the attitude, a low-pass, so the raw rate goes through the same filter
    (rate_filter). Regressing the raw rate on the smoothed reference would shrink the gains (BROAD:
    0.95 instead of 1). The field reference is not filtered; neither is the raw field. Specific force:
    returned unfiltered (its kinematic part is smoothed over ACCEL_WINDOW_S, gravity is not)."""
    raw = np.asarray(getattr(data, triad), dtype=np.float64)
    return rate_filter(raw, data.t) if triad == "gyr" else raw


def rate_filter(x: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(N, k) columns of a rate-like signal filtered as the derived rate reference is: integrated and
    differentiated by the reference's Savitzky-Golay filter (a linear, unit-DC-gain filter: a gain/bias
    model fitted on the filtered pair holds for the raw signal, and an effect in the raw rate reaches the
    residual against the reference filtered so). Trapezoidal rule, which puts the rate at the sample
    times (the rectangle rule Σ x_k·Δt_k would advance it by ½ sample); an interval touching a non-finite
    sample adds nothing, and the result stays NaN at such samples."""
    x = np.asarray(x, dtype=np.float64)
    inc = 0.5 * (x[1:] + x[:-1]) * np.diff(t)[:, None]
    angle = np.cumsum(np.concatenate([np.zeros_like(x[:1]), np.where(np.isfinite(inc), inc, 0.0)]), axis=0)
    angle[~np.all(np.isfinite(x), axis=1)] = np.nan
    return _derivative(angle, t, RATE_WINDOW_S, 1)


def derive_references(data: ImuData) -> tuple[ImuData, list[str]]:
    """A copy of `data` with ref_gyr, ref_mag and ref_acc filled from ref_q where they are missing,
    and notes saying what was derived. Without ref_q the data is returned unchanged."""
    notes: list[str] = []
    if data.ref_q is None:
        return data, notes
    q = np.asarray(data.ref_q, dtype=np.float64)
    fields = {}
    if data.ref_gyr is None:
        fields["ref_gyr"] = rate_from_attitude(data.t, q)
        notes.append(f"ref_gyr derived from ref_q (Savitzky-Golay derivative, {RATE_WINDOW_S} s window)")
    if data.ref_mag is None:
        resolved = reference_field(data)
        earth = resolved.earth_field()
        if earth is not None:
            fields["ref_mag"] = rotate_to_body(q, earth.field_ned())
            notes.append(f"ref_mag = R(ref_q)ᵀ · earth field ({resolved.text()})")
        else:
            notes.append(f"ref_mag: not derived from ref_q, the earth field in its frame is incomplete "
                         f"({resolved.text()})")
    if data.ref_acc is None and all(c in data.aux for c in POSITION_COLUMNS):
        g_ned = gravity_ned(local_gravity(data.meta)[0])
        pos = np.column_stack([data.aux[c] for c in POSITION_COLUMNS])
        acc_pos = _derivative(pos, data.t, ACCEL_WINDOW_S, 2)
        frame = _position_frame(q, acc_pos, data.acc, g_ned)
        fields["ref_acc"] = rotate_to_body(q, acc_pos @ frame.T - g_ned)
        notes.append(f"ref_acc = R(ref_q)ᵀ · (C · d²aux_pos/dt² − g), g = {g_ned[2]:.5f} m/s² (Savitzky-Golay, "
                     f"{ACCEL_WINDOW_S} s window); position frame -> NED rotation C = {np.round(frame, 3).tolist()}")
    return replace(data, **fields), notes


def _position_frame(q: np.ndarray, acc_pos: np.ndarray, acc: np.ndarray, g_ned: np.ndarray) -> np.ndarray:
    """Rotation C (3, 3) from the position frame to NED: least-squares (Kabsch) fit of
    C · a_pos to R(q) · f_measured + g over the samples where both are finite. The recording does
    not say in which frame aux_pos is given; 3 rotation angles fitted to thousands of samples
    take the frame from the data without fitting the accelerometer's errors. g_ned (3,) [m/s²]."""
    nav = np.einsum("nij,nj->ni", quat_to_matrix(q), acc) + g_ned
    ok = np.all(np.isfinite(nav), axis=1) & np.all(np.isfinite(acc_pos), axis=1)
    if ok.sum() < 3:
        return np.eye(3)
    u, _, vt = np.linalg.svd(nav[ok].T @ acc_pos[ok])
    d = np.sign(np.linalg.det(u @ vt))
    return u @ np.diag([1.0, 1.0, d]) @ vt


def reference_euler_magnetic(data: ImuData) -> np.ndarray:
    """(N, 3) reference Euler angles relative to magnetic north [rad] in the runtime's output order
    [roll, pitch, yaw] (training.frames orders them [yaw, pitch, roll]); yaw = reference yaw − the
    reference frame's declination (training.data.reference_field: the sidecar's, IGRF's for a geographic
    frame, or estimated from the magnetometer; 0 when none is known)."""
    e = euler_from_quat(data.ref_q)[:, ::-1]
    e[:, 2] = wrap_angle(e[:, 2] - reference_field(data).declination_rad())
    return e


def reference_quaternion_magnetic(data: ImuData) -> np.ndarray:
    """Reference attitude relative to magnetic north: ref_q turned by −declination about down (the
    declination of `reference_euler_magnetic`)."""
    half = -0.5 * reference_field(data).declination_rad()
    rot = np.tile([np.cos(half), 0.0, 0.0, np.sin(half)], (len(data), 1))
    return quat_multiply(rot, data.ref_q)
