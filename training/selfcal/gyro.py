"""Gyroscope bias B(T) from the rests, and gains + misalignment from the rotation between rests.

Bias: at rest the true rate is zero, so every rest-window mean is B(T) at the window's
temperature, plus the earth rate projected on the sensor axes (|Ω| = 7.292e-5 rad/s =
0.0042 °/s at most per axis, depending on pose and latitude) — too small to separate from the
bias without knowing the poses in the earth frame, so it is absorbed in B (its pose average).

Gains: with A_g a general 3x3 (gains, non-orthogonality and the rotation of the gyro axes to
the accelerometer frame: 9 unknowns), the rotation integrated from ω_c = A_g (ω - B(T)) over the
motion between two consecutive rests k, k+1 must carry every calibrated body-fixed-in-the-world
direction d (specific force at rest; the field, when calibrated) from its value at rest k to its
value at rest k+1:

    ΔR_k = Π_j exp([ω_c,j Δt_j]x),   d_{k+1} = ΔR_kᵀ d_k

(Tedaldi, Pretto, Menegatti, ICRA 2014, §IV-D, eq. 14-17). Fitted by torch L-BFGS in double
precision over all segments at once: segments are padded with zero rate (the identity rotation)
to power-of-two lengths, one tensor per length, and the ordered product of the per-sample
rotations is formed by pairwise quaternion products — log2(L) vectorised steps instead of an
L-step loop over time, with the same result since the product is associative.
"""
from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass, replace

import numpy as np
import torch

from contract.layout import MAX_DEGREE
from training.data.dataset import ImuData
from training.models.thermal import normalised_temperature
from training.selfcal.accel import MAX_CONDITION, ModelCheck, gain_summary, judge
from training.selfcal.rest import RestWindow
from training.selfcal.temperature import choose_degree, count_clusters, powers

#: Earth rotation rate [rad/s] (WGS-84): its projection on the axes at rest is absorbed in B.
EARTH_RATE = 7.292115e-5
EARTH_RATE_NOTE = ("the earth rate (7.29e-5 rad/s = 0.0042 °/s, projected on the axes by pose and "
                   "latitude) is in every rest mean and is absorbed in the bias B(T)")
#: Rest means further than this many robust σ (1.4826 MAD) from the bias fit are outliers (a
#: slow steady turn mistaken for a rest) and dropped before the refit.
OUTLIER_SIGMAS = 4.0
#: ... but never closer than twice the earth rate [rad/s]: rests of different poses legitimately
#: differ by up to 2 |Ω| per axis.
MIN_OUTLIER_RATE = 2.0 * EARTH_RATE
#: Longest motion between two rests that is integrated [s]: a residual bias of 1e-4 rad/s
#: (0.006 °/s, a good self-calibration) turns the integrated attitude by 0.17° in 30 s, which is
#: already a fifth of the 1 % gain effect on a 90° turn.
MAX_SEGMENT_S = 30.0
#: Longest sample step integrated [s]: the trapezoid rule errs by ~h³ ω''/12 per step, 1e-3 rad
#: for hand motion (ω'' ~ 100 rad/s³) at h = 0.05 s; a longer step is a gap in the log, not a
#: sample, and the segment across it is skipped (a dropped sample or two at >= 50 Hz is not).
MAX_STEP_S = 0.05
#: Segments turning less than this [deg] are skipped: at a 1 % gain error they carry < 0.1° of
#: signal, below the direction noise of a rest, and only add correlated bias error.
MIN_SEGMENT_ROTATION_DEG = 10.0
#: Largest standard error of an entry of A_g (dimensionless) for the fit to be applied: 2e-3 =
#: 0.2 % of gain or 0.11° of misalignment, a fifth of the ~1 % / ~0.5° errors of a MEMS gyro.
MAX_GAIN_STD = 2e-3
#: Segments whose direction error after the first fit exceeds this many robust σ are dropped
#: (an undetected disturbance of the field, a bump at a rest) and the fit repeated ...
SEGMENT_OUTLIER_SIGMAS = 4.0
#: ... but never below this direction error [deg]: hand-placed rests scatter by a fraction of a
#: degree, which is noise, not an outlier.
MIN_SEGMENT_OUTLIER_DEG = 1.0
#: torch threads: the fit is small and must not take over the machine (and is deterministic at
#: a fixed thread count).
TORCH_THREADS = 2
#: L-BFGS budget: iterations per call and function evaluations; convergence on a 9-parameter
#: smooth least squares takes ~10-30.
LBFGS_ITERATIONS = 100
#: Smallest direction noise [rad] any direction type is trusted to: the mean of a 1 s rest of a
#: MEMS accelerometer (~100 µg/√Hz) points to ~1e-4 rad; the weights 1/σ² must stay finite.
DIRECTION_NOISE_FLOOR = 1e-4
#: Central-difference step for the Jacobian of A_g's entries (dimensionless).
JACOBIAN_STEP = 1e-6


@dataclass(frozen=True)
class GyroBias:
    """B(T): coefficients b (3, P+1) rad/s in powers of Tn, degree P, reason the degree is lower
    than requested, distinct temperature clusters, rests used / dropped as outliers, RMS of the
    rest means before (raw) and after [rad/s], and the mean residual (R, 3) rad/s of each
    recording's rests (their spread is the run-to-run bias no B(T) can hold)."""

    b: np.ndarray
    degree: int
    reason: str
    clusters: int
    rests: int
    dropped: int
    rms_before: float
    rms_after: float
    recording_offsets: np.ndarray


@dataclass(frozen=True)
class GyroGain:
    """A_g (3, 3) (I when not fitted), gain polynomial g (3, P) (G_i = 1 + Σ_k g[i, k-1] Tn^k; P = 0
    when not fitted), fitted flag, reason (why not more), segments used and skipped (by cause),
    direction errors RMS [deg] raw / bias only / after, the check, and the direction noise (D,)
    [deg] per direction type (gravity, field) that weighted the fit."""

    A: np.ndarray
    g: np.ndarray
    fitted: bool
    reason: str
    segments: int
    skipped: dict
    rms_raw_deg: float
    rms_bias_deg: float
    rms_after_deg: float
    check: ModelCheck | None
    direction_noise_deg: np.ndarray


def bias_at(b: np.ndarray, temp: np.ndarray, t0: float, ts: float) -> np.ndarray:
    """B(T) (N, 3) rad/s from coefficients b (3, P+1) at temperatures temp (N,) °C."""
    return powers(temp, t0, ts, b.shape[1] - 1) @ b.T


def fit_gyro_bias(windows: list[RestWindow], t0: float, ts: float, degree: int) -> GyroBias:
    """B(T) by least squares on the rest-window means (rests only, not hand-held holds), with one
    outlier pass. Returns a zero bias with rests = 0 when no rest has the gyro."""
    use = [w for w in windows if w.kind == "rest" and np.all(np.isfinite(w.gyr))]
    if not use:
        return GyroBias(np.zeros((3, 1)), 0, "no rest with the gyroscope recorded", 0, 0, 0, np.nan,
                        np.nan, np.zeros((0, 3)))
    g = np.array([w.gyr for w in use])
    temp = np.array([w.temp for w in use])
    p, reason = choose_degree(temp, degree, len(use))
    keep = _bias_inliers(g, temp, np.array([w.dataset for w in use]), t0, ts, p)
    b = np.linalg.lstsq(powers(temp[keep], t0, ts, p), g[keep], rcond=None)[0].T
    after = g[keep] - bias_at(b, temp[keep], t0, ts)
    recording = np.array([w.dataset for w in use])
    residual = g - bias_at(b, temp, t0, ts)
    offsets = np.array([residual[keep & (recording == i)].mean(axis=0) for i in np.unique(recording[keep])])
    return GyroBias(b, p, reason, count_clusters(temp), int(keep.sum()), int((~keep).sum()),
                    float(np.sqrt(np.mean(g[keep] ** 2))), float(np.sqrt(np.mean(after ** 2))), offsets)


def _bias_inliers(g: np.ndarray, temp: np.ndarray, recording: np.ndarray, t0: float, ts: float,
                  degree: int) -> np.ndarray:
    """(K,) bool: rest means g (K, 3) rad/s within OUTLIER_SIGMAS robust σ (at least
    MIN_OUTLIER_RATE) of the median residual of their own recording (K,) after a first B(T) fit —
    each power-up has its own run-to-run bias, which is no outlier; all of them when fewer than
    half would remain."""
    b = np.linalg.lstsq(powers(temp, t0, ts, degree), g, rcond=None)[0].T
    res = g - bias_at(b, temp, t0, ts)
    dev = np.empty_like(res)
    for i in np.unique(recording):
        own = recording == i
        dev[own] = np.abs(res[own] - np.median(res[own], axis=0))
    sigma = 1.4826 * np.median(dev, axis=0)
    keep = np.all(dev <= np.maximum(OUTLIER_SIGMAS * sigma, MIN_OUTLIER_RATE), axis=1)
    return keep if 2 * keep.sum() > len(keep) else np.ones(len(keep), dtype=bool)


@contextmanager
def _torch_threads(n: int):
    """Run the block with torch limited to n threads, restoring the previous count."""
    before = torch.get_num_threads()
    torch.set_num_threads(min(n, before))
    try:
        yield
    finally:
        torch.set_num_threads(before)


@dataclass(frozen=True)
class Segments:
    """Motions between consecutive rests: rotation-vector increments per segment [(L_s, 3) rad]
    (rate x dt, raw and bias-corrected), the normalised temperature of each increment [(L_s,)]
    (0 where unknown, as in the runtime), the mean temperature (S,) °C (NaN where unknown),
    start/end directions (S, D, 3) (unit; NaN-free, weight 0 where missing), weights (S, D), and
    the (dataset, begin, end) sample indices of each."""

    raw: list
    corrected: list
    tn: list
    temp: np.ndarray
    start: np.ndarray
    end: np.ndarray
    weight: np.ndarray
    where: list


def _increments(data: ImuData, begin: int, end: int, bias: np.ndarray) -> np.ndarray:
    """Rotation-vector increments (end - begin, 3) rad from sample begin to end: trapezoidal
    rate (ω_j + ω_j+1)/2 minus bias, times the step."""
    w = data.gyr[begin:end + 1] - bias[begin:end + 1]
    dt = np.diff(data.t[begin:end + 1])
    return 0.5 * (w[:-1] + w[1:]) * dt[:, None]


def _endpoints(a: RestWindow, b: RestWindow) -> tuple[int, int]:
    """Sample indices where the integration starts (end of a rest, middle of a hold) and ends
    (start of a rest, middle of a hold): a rest is still to the noise, so its last sample holds
    its mean direction; a hold drifts slowly, so its middle does."""
    begin = a.stop - 1 if a.kind == "rest" else (a.start + a.stop) // 2
    end = b.start if b.kind == "rest" else (b.start + b.stop) // 2
    return begin, end


def build_segments(datasets: list[ImuData], windows: list[RestWindow], directions: np.ndarray,
                   biases: list[np.ndarray], t0: float, ts: float) -> tuple[Segments | None, dict]:
    """Segments between consecutive windows of each recording.

    directions (K, D, 3): unit directions per window (NaN where missing); biases: B(T) (N_i, 3)
    per recording; t0, ts: temperature normalisation [°C]. Returns (Segments or None when none is
    usable, skipped counts by cause)."""
    skipped = {"too_long": 0, "gap": 0, "missing_samples": 0, "no_direction": 0, "small_rotation": 0}
    items = []
    order = sorted(range(len(windows)), key=lambda k: (windows[k].dataset, windows[k].start))
    for ka, kb in zip(order[:-1], order[1:]):
        a, b = windows[ka], windows[kb]
        if a.dataset != b.dataset or b.start <= a.stop:
            continue  # different recordings, or one rest cut in pieces: no motion between
        data = datasets[a.dataset]
        begin, end = _endpoints(a, b)
        both = np.all(np.isfinite(directions[ka]), axis=1) & np.all(np.isfinite(directions[kb]), axis=1)
        dt = np.diff(data.t[begin:end + 1])
        if data.t[end] - data.t[begin] > MAX_SEGMENT_S:
            skipped["too_long"] += 1
        elif np.any(dt > MAX_STEP_S):
            skipped["gap"] += 1
        elif not np.all(np.isfinite(data.gyr[begin:end + 1])):
            skipped["missing_samples"] += 1
        elif not both.any():
            skipped["no_direction"] += 1
        else:
            inc = _increments(data, begin, end, biases[a.dataset])
            if np.degrees(np.linalg.norm(inc.sum(axis=0))) < MIN_SEGMENT_ROTATION_DEG and \
                    np.degrees(np.sum(np.linalg.norm(inc, axis=1))) < MIN_SEGMENT_ROTATION_DEG:
                skipped["small_rotation"] += 1
                continue
            raw = _increments(data, begin, end, np.zeros_like(data.gyr))
            tn = normalised_temperature(data.temp[begin:end + 1], t0, ts)
            temp = data.temp[begin:end + 1]
            items.append((raw, inc, directions[ka], directions[kb], both, (a.dataset, begin, end),
                          0.5 * (tn[:-1] + tn[1:]),
                          float(np.nanmean(temp)) if np.isfinite(temp).any() else np.nan))
    if not items:
        return None, skipped
    raw, cor, tns = [it[0] for it in items], [it[1] for it in items], [it[6] for it in items]
    start = np.nan_to_num(np.array([it[2] for it in items]))
    end = np.nan_to_num(np.array([it[3] for it in items]))
    weight = np.array([it[4] for it in items], dtype=float)
    return Segments(raw, cor, tns, np.array([it[7] for it in items]), start, end, weight,
                    [it[5] for it in items]), skipped


def quaternion_increments(theta: torch.Tensor) -> torch.Tensor:
    """Unit quaternions [w, x, y, z] (..., 4) of rotation vectors theta (..., 3) rad: exp of half
    the angle, by Taylor series in a² (exact to < 1e-10 for |θ| < 1 rad, i.e. any physical rate
    at >= 50 Hz), smooth at θ = 0 (the padding) where sqrt would not be differentiable."""
    a2 = torch.sum(theta * theta, dim=-1, keepdim=True)
    # cos(a/2) = 1 - a²/8 + a⁴/384 - a⁶/46080 + a⁸/10321920, sin(a/2)/a = 1/2 - a²/48 + ... (Horner)
    cos_half = 1 + a2 * (-1 / 8 + a2 * (1 / 384 + a2 * (-1 / 46080 + a2 / 10321920)))
    sinc_half = 0.5 + a2 * (-1 / 48 + a2 * (1 / 3840 + a2 * (-1 / 645120 + a2 / 185794560)))
    return torch.cat([cos_half, sinc_half * theta], dim=-1)


def quaternion_product(p: torch.Tensor, q: torch.Tensor) -> torch.Tensor:
    """Hamilton product p ⊗ q of quaternions (..., 4)."""
    pw, px, py, pz = p.unbind(-1)
    qw, qx, qy, qz = q.unbind(-1)
    return torch.stack([pw * qw - px * qx - py * qy - pz * qz,
                        pw * qx + px * qw + py * qz - pz * qy,
                        pw * qy - px * qz + py * qw + pz * qx,
                        pw * qz + px * qy - py * qx + pz * qw], dim=-1)


def compose(q: torch.Tensor) -> torch.Tensor:
    """Ordered product q_0 ⊗ q_1 ⊗ ... ⊗ q_{L-1} along dim 1 of q (S, L, 4) -> (S, 4), by
    pairwise products (associativity), padding an odd length with the identity."""
    while q.shape[1] > 1:
        if q.shape[1] % 2:
            one = torch.zeros_like(q[:, :1])
            one[..., 0] = 1.0
            q = torch.cat([q, one], dim=1)
        q = quaternion_product(q[:, 0::2], q[:, 1::2])
    return q[:, 0]


def rotate_back(q: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """R(q)ᵀ v for unit quaternions q (S, 4) and vectors v (S, D, 3): the body-frame direction at
    the segment's end of a direction v fixed in the world, seen at its start."""
    q = q / torch.linalg.norm(q, dim=-1, keepdim=True)
    w, x, y, z = (c[:, None] for c in q.unbind(-1))
    vx, vy, vz = v.unbind(-1)
    # Rᵀ of the body -> world rotation of q (Hamilton): rows of R become columns
    rx = (1 - 2 * (y * y + z * z)) * vx + 2 * (x * y + w * z) * vy + 2 * (x * z - w * y) * vz
    ry = 2 * (x * y - w * z) * vx + (1 - 2 * (x * x + z * z)) * vy + 2 * (y * z + w * x) * vz
    rz = 2 * (x * z + w * y) * vx + 2 * (y * z - w * x) * vy + (1 - 2 * (x * x + y * y)) * vz
    return torch.stack([rx, ry, rz], dim=-1)


@dataclass(frozen=True)
class Batch:
    """Segments in torch form, bucketed by length (powers of two, so each bucket pads to at most
    twice its samples): increments per bucket [(S_b, 2^k, 3) rad] and their normalised
    temperatures [(S_b, 2^k, 1)], start/end directions (S, D, 3) and weights (S, D) in bucket
    order, and order (S,): the segment index of each row."""

    buckets: list
    tn: list
    start: torch.Tensor
    end: torch.Tensor
    weight: torch.Tensor
    order: np.ndarray


def make_batch(inc: list, tn: list, start: np.ndarray, end: np.ndarray, weight: np.ndarray) -> Batch:
    """Batch of segments: increments [(L_s, 3) rad] and temperatures [(L_s,)] per segment,
    directions (S, D, 3), weights (S, D)."""
    levels = np.array([int(np.ceil(np.log2(max(len(x), 1)))) for x in inc])
    order = np.argsort(levels, kind="stable")
    buckets, temps = [], []
    for level in np.unique(levels):
        rows = order[levels[order] == level]
        bucket = np.zeros((len(rows), 2 ** int(level), 3))  # zero rate = identity rotation
        temp = np.zeros((len(rows), 2 ** int(level), 1))
        for k, row in enumerate(rows):
            bucket[k, :len(inc[row])] = inc[row]
            temp[k, :len(tn[row]), 0] = tn[row]
        buckets.append(torch.from_numpy(bucket))
        temps.append(torch.from_numpy(temp))
    return Batch(buckets, temps, torch.from_numpy(start[order]), torch.from_numpy(end[order]),
                 torch.from_numpy(weight[order]), order)


def segment_residual(params: torch.Tensor, batch: Batch, degree: int = 0) -> torch.Tensor:
    """Predicted minus measured end directions (S, D, 3), bucket order, for A_g = I + params[:9]
    (row-major) and, when degree P > 0, the gain polynomial G_i = 1 + Σ_k g[i, k-1] Tn^k with
    g = params[9:].reshape(3, P), applied before A_g as in the runtime (x_c = A (G ⊙ (x - B)))."""
    a = torch.eye(3, dtype=torch.float64) + params[:9].reshape(3, 3)
    g = params[9:].reshape(3, degree) if degree else None
    quats = []
    for inc, tn in zip(batch.buckets, batch.tn):
        if g is not None:
            inc = inc * (1 + sum(g[:, k - 1] * tn ** k for k in range(1, degree + 1)))
        quats.append(compose(quaternion_increments(inc @ a.T)))
    return rotate_back(torch.cat(quats), batch.start) - batch.end


def _direction_error_deg(res: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """Angle [deg] (S, D) between predicted and measured unit directions from their difference."""
    return np.degrees(2 * np.arcsin(np.clip(np.linalg.norm(res, axis=-1) / 2, 0, 1))) * (weight > 0)


def _rms_deg(res: np.ndarray, weight: np.ndarray) -> float:
    """RMS direction error [deg] over the directions present."""
    err = _direction_error_deg(res, weight)
    return float(np.sqrt(np.sum(err ** 2) / max(weight.sum(), 1)))


def _lbfgs(batch: Batch, bar, start: np.ndarray, degree: int) -> torch.Tensor:
    """Least squares of Σ w ‖residual‖² over the parameters by L-BFGS from `start`."""
    params = torch.tensor(start, dtype=torch.float64, requires_grad=True)
    opt = torch.optim.LBFGS([params], lr=1.0, max_iter=LBFGS_ITERATIONS, history_size=20,
                            tolerance_grad=1e-12, tolerance_change=1e-16, line_search_fn="strong_wolfe")
    scale = 1.0 / float(batch.weight.sum())

    def closure():
        opt.zero_grad()
        loss = scale * torch.sum(batch.weight[..., None] * segment_residual(params, batch, degree) ** 2)
        loss.backward()
        bar.update(1)
        return loss
    opt.step(closure)
    return params.detach()


def _fit_once(batch: Batch, bar, start: np.ndarray, degree: int) -> tuple[np.ndarray, np.ndarray]:
    """(parameters (9 + 3P,), residual (S, D, 3) in bucket order) of one fit from `start`."""
    params = _lbfgs(batch, bar, start, degree)
    with torch.no_grad():
        res = segment_residual(params, batch, degree).numpy()
    return params.numpy(), res


def _jacobian(params: torch.Tensor, batch: Batch, degree: int) -> np.ndarray:
    """Jacobian (S*D*3, p) of the residual by central differences with step JACOBIAN_STEP (the
    residual is smooth; truncation ~step² ≈ 1e-12, far below any decision threshold)."""
    cols = []
    with torch.no_grad():
        for k in range(len(params)):
            step = torch.zeros(len(params), dtype=torch.float64)
            step[k] = JACOBIAN_STEP
            diff = (segment_residual(params + step, batch, degree)
                    - segment_residual(params - step, batch, degree))
            cols.append((diff / (2 * JACOBIAN_STEP)).reshape(-1).numpy())
    return np.column_stack(cols)


def _batch(seg: Segments, keep: np.ndarray, weight: np.ndarray, raw: bool = False) -> Batch:
    """Batch of the segments `keep` (S,) bool with weights (S, D), bias-corrected (or raw) increments."""
    inc = seg.raw if raw else seg.corrected
    rows = np.flatnonzero(keep)
    return make_batch([inc[k] for k in rows], [seg.tn[k] for k in rows], seg.start[keep], seg.end[keep],
                      weight[keep])


def _type_rms_rad(res: np.ndarray, present: np.ndarray) -> np.ndarray:
    """RMS direction error [rad] (D,) per direction type over the segments where it is present."""
    err = np.radians(_direction_error_deg(res, present))
    count = (present > 0).sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, np.sqrt(np.sum(err ** 2, axis=0) / count), np.nan)


def _segment_outliers(res: np.ndarray, present: np.ndarray) -> np.ndarray:
    """(S,) bool: segments whose error in any direction type exceeds the type's median +
    SEGMENT_OUTLIER_SIGMAS robust σ (at least MIN_SEGMENT_OUTLIER_DEG)."""
    err = _direction_error_deg(res, present)
    out = np.zeros(len(err), dtype=bool)
    for d in range(err.shape[1]):
        e = err[present[:, d] > 0, d]
        if e.size:
            limit = max(np.median(e) + SEGMENT_OUTLIER_SIGMAS * 1.4826 * np.median(np.abs(e - np.median(e))),
                        MIN_SEGMENT_OUTLIER_DEG)
            out |= (present[:, d] > 0) & (err[:, d] > limit)
    return out


def gain_degree(seg: Segments, requested: int) -> tuple[int, str]:
    """(degree P of the gain polynomial G(T), reason when lower than requested) from the distinct
    temperatures of the segments (their mean temperatures, °C)."""
    degree, reason = choose_degree(seg.temp, min(requested, MAX_DEGREE), len(seg.temp))
    return degree, reason.replace("bias", "gain") if reason else ""


def _names(degree: int) -> list[str]:
    """Parameter names: A_g entries row-major, then g[i, k-1] of Tn^k."""
    return ([f"A[{i},{j}]" for i in range(3) for j in range(3)]
            + [f"g{'xyz'[i]}·Tn^{k}" for i in range(3) for k in range(1, degree + 1)])


def _judge_fit(jac, res, used, sigma, degree) -> ModelCheck:
    """judge() of a gain fit with every row in units of its direction noise; a unit vector has
    2 degrees of freedom, so each of its 3 rows counts 2/3."""
    scale = np.repeat((used / np.nan_to_num(sigma, nan=1.0))[..., None], 3, axis=-1)
    dof = np.repeat((used * (2.0 / 3.0))[..., None], 3, axis=-1)
    return judge(jac * scale.reshape(-1, 1), (res * scale).ravel(), dof.ravel(), _names(degree), 0.0, 1.0,
                 MAX_CONDITION, MAX_GAIN_STD)


def fit_gyro_gain(seg: Segments | None, skipped: dict, noise: np.ndarray, degree: int, bar) -> GyroGain:
    """A_g (and G(T) of `degree`, when identifiable) from the segments (see the module docstring);
    A_g = I with the reason when the segments do not pin every entry to MAX_GAIN_STD.

    Each direction type d (gravity, field) is weighted by 1/σ_d² (maximum likelihood): σ_d starts
    at noise (D,) rad — the caller's estimate from the norm residuals — and is re-estimated from the
    type's residual RMS after a first fit of A_g (variance components), floored at
    DIRECTION_NOISE_FLOOR; outlier segments of that fit are dropped. Then G(T) + A_g is fitted and
    judged, and A_g alone when G(T) is not identifiable."""
    if seg is None:
        return GyroGain(np.eye(3), np.zeros((3, 0)), False,
                        "no usable motion between two rests (see segments_skipped)", 0, skipped, np.nan,
                        np.nan, np.nan, None, np.full(len(noise), np.nan))
    present = seg.weight
    sigma = np.maximum(np.nan_to_num(noise, nan=1.0), DIRECTION_NOISE_FLOOR)
    keep = np.ones(len(present), dtype=bool)
    batch = _batch(seg, keep, present / sigma ** 2)
    zero = torch.zeros(9, dtype=torch.float64)
    with torch.no_grad():
        rms_raw = _rms_deg(segment_residual(zero, _batch(seg, keep, present, raw=True)).numpy(),
                           present[batch.order])
        rms_bias = _rms_deg(segment_residual(zero, batch).numpy(), present[batch.order])
    params, res = _fit_once(batch, bar, np.zeros(9), 0)
    sigma = np.maximum(_type_rms_rad(res, present[batch.order]), DIRECTION_NOISE_FLOOR)
    keep[batch.order] = ~_segment_outliers(res, present[batch.order])
    skipped = dict(skipped, outliers=int((~keep).sum()))
    batch = _batch(seg, keep, present / np.nan_to_num(sigma, nan=1.0) ** 2)
    used = present[np.flatnonzero(keep)[batch.order]]  # presence in bucket order
    reasons = []
    for p in ([degree, 0] if degree else [0]):
        start = np.concatenate([params[:9], np.zeros(3 * p)])
        params_p, res = _fit_once(batch, bar, start, p)
        sigma_p = np.maximum(_type_rms_rad(res, used), DIRECTION_NOISE_FLOOR)
        check = _judge_fit(_jacobian(torch.from_numpy(params_p), batch, p), res, used, sigma_p, p)
        if check.accepted:
            why = "; ".join(reasons)
            return GyroGain(np.eye(3) + params_p[:9].reshape(3, 3), params_p[9:].reshape(3, p), True, why,
                            int(keep.sum()), skipped, rms_raw, rms_bias, _rms_deg(res, used), check,
                            np.degrees(sigma_p))
        reasons.append(f"{'G(T) of degree %d + ' % p if p else ''}A_g not identifiable from "
                       f"{int(keep.sum())} segments: {check.reason}")
    return GyroGain(np.eye(3), np.zeros((3, 0)), False, "; ".join(reasons) + "; A_g = I", int(keep.sum()),
                    skipped, rms_raw, rms_bias, rms_bias, check, np.degrees(sigma_p))


def fit_gyroscope(datasets: list[ImuData], windows: list[RestWindow], directions: np.ndarray,
                  noise: np.ndarray, bias: GyroBias, t0: float, ts: float, degree: int, bar) -> GyroGain:
    """Gains of the gyro from the motions between rests, with B(T) already removed.

    directions (K, 2, 3): unit gravity and field directions per window (NaN where missing);
    noise (2,): their expected error [rad] (see fit_gyro_gain); degree: largest G(T) degree.
    Gravity alone is tried first (Tedaldi et al.): the field direction carries the magnetometer's
    nonlinearity and the error of its alignment R (a few tenths of a degree, systematic) into A_g,
    so it is added only where gravity leaves A_g unidentified (rotations about the vertical), or
    used alone without an accelerometer."""
    with _torch_threads(TORCH_THREADS):
        biases = [bias_at(bias.b, d.temp, t0, ts) for d in datasets]
        seg, skipped = build_segments(datasets, windows, directions, biases, t0, ts)
        if seg is None:
            return fit_gyro_gain(seg, skipped, np.asarray(noise, dtype=float), 0, bar)
        p, why_degree = gain_degree(seg, degree)
        if not seg.weight[:, 1].any() or not seg.weight[:, 0].any():
            gain = fit_gyro_gain(seg, skipped, np.asarray(noise, dtype=float), p, bar)
        else:
            gravity = replace(seg, weight=seg.weight * np.array([1.0, 0.0]))
            gain = fit_gyro_gain(gravity, skipped, np.asarray(noise, dtype=float), p, bar)
            if not gain.fitted:
                both = fit_gyro_gain(seg, skipped, np.asarray(noise, dtype=float), p, bar)
                gain = both if both.fitted else gain
        return replace(gain, reason="; ".join(r for r in (why_degree, gain.reason) if r))


def earth_rate_report() -> dict:
    """What the earth rate does to the bias (JSON-ready)."""
    return {"earth_rate_rad_s": EARTH_RATE, "earth_rate_dps": float(np.degrees(EARTH_RATE)),
            "note": EARTH_RATE_NOTE}


def summarise(bias: GyroBias, gain: GyroGain, t0: float, ts: float) -> dict:
    """Report entries of the gyroscope fit (numpy values allowed)."""
    fitted = ("bias B(T) of degree %d" % bias.degree if bias.rests else "nothing") + (
        " + gains and misalignment A_g (9)" if gain.fitted else "") + (
        " + gain drift G(T) of degree %d" % gain.g.shape[1] if gain.g.shape[1] else "")
    out = {"unit": "rad/s", "fitted": fitted,
           "why_not_more": "; ".join(r for r in (bias.reason, gain.reason) if r),
           "degree": bias.degree, "temperature_clusters": bias.clusters, "bias": bias.b[:, 0],
           "bias_dps": np.degrees(bias.b[:, 0]), "bias_coefficients": bias.b, "t0_c": t0, "ts_c": ts,
           "gain_degree": gain.g.shape[1], "gain_coefficients": gain.g,
           "bias_rests": bias.rests, "bias_outliers": bias.dropped,
           "recording_bias_offsets_rad_s": bias.recording_offsets, "segments": gain.segments,
           "segments_skipped": gain.skipped, "max_segment_s": MAX_SEGMENT_S,
           "direction_noise_deg": dict(zip(("gravity", "field"), gain.direction_noise_deg)),
           "residual": {"rest_rate_rms_rad_s": {"before": bias.rms_before, "after": bias.rms_after},
                        "direction_error_rms_deg": {"before": gain.rms_raw_deg,
                                                    "bias_only": gain.rms_bias_deg,
                                                    "after": gain.rms_after_deg}}}
    noise = gain.direction_noise_deg
    used = [name for name, v in zip(("gravity", "field"), noise) if np.isfinite(v)]
    out["directions_used"] = " + ".join(used) or None
    out.update(earth_rate_report())
    out.update(gain_summary(gain.A))
    if gain.check is not None:
        out["jacobian_condition"] = gain.check.condition
        out["largest_std"] = {"parameter": gain.check.worst_param, "value": gain.check.worst_std}
    notes = [f"bias from {bias.rests} rests (degree {bias.degree}): rest-mean RMS {bias.rms_before:.2e} -> "
             f"{bias.rms_after:.2e} rad/s; {EARTH_RATE_NOTE}",
             f"gains {'fitted' if gain.fitted else 'not fitted'} from {gain.segments} rest-to-rest segments "
             f"(skipped: {gain.skipped}); direction error RMS {gain.rms_raw_deg:.2f}° raw, "
             f"{gain.rms_bias_deg:.2f}° bias removed, {gain.rms_after_deg:.2f}° calibrated"]
    if out["why_not_more"]:
        notes.append(f"not richer: {out['why_not_more']}")
    out["notes"] = notes
    return out
