"""Gyro gains, misalignment and gain drift A_g, G(T) from the rotation between rests and the closed turns.

With A_g a general 3x3 (gains, non-orthogonality and the rotation of the gyro axes to the
accelerometer frame: 9 unknowns), the rotation integrated from ω_c = A_g (G(T) ⊙ (ω − B(T))) over the
motion between two consecutive rests k, k+1 must carry every calibrated body-fixed-in-the-world
direction d from its value at rest k to its value at rest k+1 (training.selfcal.segments):

    ΔR_k = Π_j exp([ω_c,j Δt_j]x),   d_{k+1} = ΔR_kᵀ d_k

(Tedaldi, Pretto, Menegatti, ICRA 2014, §IV-D, eq. 14-17), and a closed turn must wind a whole number
of turns (training.selfcal.turns; the Ferraris protocol's known angle). Fitted by regularised least
squares (training.selfcal.regularised): the motions' information decides what is fitted and what is held
at A_g = I, G = 1; the rotations and their derivatives are in training.selfcal.rotations.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from contract.layout import MAX_DEGREE
from training.data.dataset import ImuData
from training.selfcal.regularised import Group, RegularisedFit, regularised_fit
from training.selfcal.rest import RestWindow
from training.selfcal.rotations import (attitudes, calibrated_increments, direction_jacobian, end_directions,
                                        rotation_jacobian, winding)
from training.selfcal.segments import Segments, build_segments
from training.selfcal.temperature import choose_degree
from training.selfcal.turns import TURN_FLOOR_RAD, TURN_SIGMA_RAD, ClosedTurn, count_full_turns, find_closed_turns

#: Prior widths of the gyro model (training.selfcal.regularised: a combination the motions determine
#: better than half its width is fitted from them alone, a weaker one is held near nominal): gain 10 %
#: (MEMS datasheets ±1-3 %); cross-axis 0.035 (2°: non-orthogonality, package misalignment and the
#: rotation of the gyro axes to the accelerometer's, datasheets ±1° each); gain drift over half the
#: temperature span 2 % (datasheets ±0.03 %/°C, 1 % over 35 °C).
PRIOR_GAIN = 0.1
PRIOR_CROSS = 0.035
PRIOR_GAIN_DRIFT = 0.02
#: The direction residual groups, in the order of the directions' second axis.
DIRECTION_GROUPS = ("gravity directions", "field directions")
#: Segments whose direction error after the first fit exceeds this many robust σ are dropped
#: (an undetected disturbance of the field, a bump at a rest) and the fit repeated ...
SEGMENT_OUTLIER_SIGMAS = 4.0
#: ... but never below this direction error [deg]: hand-placed rests scatter by a fraction of a
#: degree, which is noise, not an outlier.
MIN_SEGMENT_OUTLIER_DEG = 1.0
#: Smallest direction noise [rad] any direction type is trusted to: the mean of a 1 s rest of a
#: MEMS accelerometer (~100 µg/√Hz) points to ~1e-4 rad; the weights 1/σ² must stay finite.
DIRECTION_NOISE_FLOOR = 1e-4


@dataclass(frozen=True)
class GyroGain:
    """A_g (3, 3) (I when not fitted), gain polynomial g (3, P) (G_i = 1 + Σ_k g[i, k-1] Tn^k; P = 0
    when not fitted), fitted flag, reason (why not more), segments used and skipped (by cause),
    direction errors RMS [deg] raw / bias only / after, the regularised fit (parameters ± standard
    errors, which the prior held), the direction noise (D,) [deg] per direction type (gravity, field)
    that weighted the fit, the closed turns used as known angles, and the full turns about any axis
    (the ImuFusion protocol's turns from a corner)."""

    A: np.ndarray
    g: np.ndarray
    fitted: bool
    reason: str
    segments: int
    skipped: dict
    rms_raw_deg: float
    rms_bias_deg: float
    rms_after_deg: float
    fit: RegularisedFit | None
    direction_noise_deg: np.ndarray
    turns: tuple = ()
    full_turns: int = 0


@dataclass(frozen=True)
class Motions:
    """The segments a fit uses, zero-padded to one length L: bias-corrected increments inc (S, L, 3)
    [rad], normalised temperatures tn (S, L), unit directions at the start and end rests start, end
    (S, D, 3), present (S, D) bool, and the closed turns among them (their `segment` indexes rows here)."""

    inc: np.ndarray
    tn: np.ndarray
    start: np.ndarray
    end: np.ndarray
    present: np.ndarray
    turns: tuple


def motions(seg: Segments, keep: np.ndarray, turns: list[ClosedTurn], raw: bool = False) -> Motions:
    """Motions of the segments `keep` (S,) bool (raw: without the bias correction), with the closed
    turns among them re-indexed."""
    rows = np.flatnonzero(keep)
    source = seg.raw if raw else seg.corrected
    length = max(len(source[k]) for k in rows)
    inc, tn = np.zeros((len(rows), length, 3)), np.zeros((len(rows), length))
    for i, k in enumerate(rows):
        inc[i, :len(source[k])], tn[i, :len(seg.tn[k])] = source[k], seg.tn[k]
    index = {int(k): i for i, k in enumerate(rows)}
    kept = tuple(replace(t, segment=index[t.segment]) for t in turns if t.segment in index)
    return Motions(inc, tn, seg.start[keep], seg.end[keep], seg.weight[keep] > 0, kept)


def _split(theta: np.ndarray, degree: int) -> tuple[np.ndarray, np.ndarray]:
    """(A_g (3, 3), g (3, P)) of the parameter vector [A_g − I row-major, g axis-major]."""
    return np.eye(3) + theta[:9].reshape(3, 3), theta[9:].reshape(3, degree)


def direction_residual(m: Motions, theta: np.ndarray, degree: int) -> np.ndarray:
    """Predicted minus measured end directions (S, D, 3), zero where a direction is missing."""
    a, g = _split(theta, degree)
    p = attitudes(calibrated_increments(m.inc, m.tn, a, g))
    return (end_directions(p, m.start) - m.end) * m.present[..., None]


def _residual_function(m: Motions, degree: int):
    """fun(θ) -> (residual rows, Jacobian): the end directions (S·D·3 rows) then the closed turns'
    winding minus 2πn [rad] (one row each), for training.selfcal.regularised."""
    turn_rows = np.array([t.segment for t in m.turns], dtype=int)
    axis = np.array([t.axis for t in m.turns]).reshape(-1, 3)
    h0 = np.array([t.h0 for t in m.turns]).reshape(-1, 3)
    target = np.array([2 * np.pi * t.turns for t in m.turns])

    def fun(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        a, g = _split(theta, degree)
        p = attitudes(calibrated_increments(m.inc, m.tn, a, g))
        mask = m.present[..., None]
        r = (end_directions(p, m.start) - m.end) * mask
        d_phi = rotation_jacobian(p, m.inc, m.tn, a, g)
        jac = direction_jacobian(p, m.start, d_phi) * mask[..., None]
        rows, cols = [r.reshape(-1)], [jac.reshape(-1, len(theta))]
        if len(turn_rows):
            rows.append(winding(p[turn_rows], axis, h0) - target)
            cols.append(np.einsum("ta,tan->tn", axis, d_phi[turn_rows]))
        return np.concatenate(rows), np.concatenate(cols)
    return fun


def _groups(m: Motions, sigma: np.ndarray) -> list[Group]:
    """Residual groups of a gain fit: gravity and field directions (3 rows a segment, 2 dof where the
    direction is present, none where missing), closed-turn windings (1 row each)."""
    present = m.present.astype(float)
    rows = np.arange(present.size * 3).reshape(present.shape + (3,))
    groups = []
    for d, name in enumerate(DIRECTION_GROUPS):
        if present[:, d].any():
            start = sigma[d] if np.isfinite(sigma[d]) else 1e-2
            groups.append(Group(name, rows[:, d].ravel(), np.repeat(present[:, d] * (2.0 / 3.0), 3),
                                DIRECTION_NOISE_FLOOR, max(start, DIRECTION_NOISE_FLOOR)))
    if m.turns:
        n = len(m.turns)
        groups.append(Group("closed turns", rows.size + np.arange(n), np.ones(n), TURN_FLOOR_RAD, TURN_SIGMA_RAD,
                            fixed=True))
    return groups


def _prior(degree: int) -> tuple[np.ndarray, np.ndarray]:
    """(nominal θ0 = 0: A_g = I, G = 1; prior widths) of [A_g − I row-major, g axis-major]."""
    a_sigma = np.where(np.eye(3, dtype=bool), PRIOR_GAIN, PRIOR_CROSS).ravel()
    return np.zeros(9 + 3 * degree), np.concatenate([a_sigma, np.full(3 * degree, PRIOR_GAIN_DRIFT)])


def _direction_error_deg(res: np.ndarray, present: np.ndarray) -> np.ndarray:
    """Angle [deg] (S, D) between predicted and measured unit directions from their difference."""
    return np.degrees(2 * np.arcsin(np.clip(np.linalg.norm(res, axis=-1) / 2, 0, 1))) * present


def _rms_deg(res: np.ndarray, present: np.ndarray) -> float:
    """RMS direction error [deg] over the directions present."""
    err = _direction_error_deg(res, present)
    return float(np.sqrt(np.sum(err ** 2) / max(present.sum(), 1)))


def _segment_outliers(res: np.ndarray, present: np.ndarray) -> np.ndarray:
    """(S,) bool: segments whose error in any direction type exceeds the type's median +
    SEGMENT_OUTLIER_SIGMAS robust σ (at least MIN_SEGMENT_OUTLIER_DEG)."""
    err = _direction_error_deg(res, present)
    out = np.zeros(len(err), dtype=bool)
    for d in range(err.shape[1]):
        e = err[present[:, d], d]
        if e.size:
            limit = max(np.median(e) + SEGMENT_OUTLIER_SIGMAS * 1.4826 * np.median(np.abs(e - np.median(e))),
                        MIN_SEGMENT_OUTLIER_DEG)
            out |= present[:, d] & (err[:, d] > limit)
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


def fit_gyro_gain(seg: Segments | None, skipped: dict, noise: np.ndarray, degree: int,
                  turns: list[ClosedTurn] = ()) -> GyroGain:
    """A_g and G(T) of `degree` from the segments and the closed turns among them, by regularised least
    squares (training.selfcal.regularised): what the motions determine is fitted from them, the rest is
    held at A_g = I, G = 1 by the prior, and the report says which.

    Each residual group (gravity directions, field directions, closed turns) has its own noise, starting
    at noise (D,) rad for the directions — the caller's estimate from the norm residuals — and
    re-estimated from the fit (variance components); outlier segments of a first fit are dropped."""
    if seg is None:
        return GyroGain(np.eye(3), np.zeros((3, 0)), False,
                        "no usable motion between two rests (see segments_skipped)", 0, skipped, np.nan,
                        np.nan, np.nan, None, np.full(len(noise), np.nan))
    keep = np.ones(len(seg.weight), dtype=bool)
    theta0, prior = _prior(degree)
    raw, bias_only = motions(seg, keep, turns, raw=True), motions(seg, keep, turns)
    rms_raw = _rms_deg(direction_residual(raw, theta0, degree), raw.present)
    rms_bias = _rms_deg(direction_residual(bias_only, theta0, degree), bias_only.present)
    fit = None
    for first in (True, False):       # a first fit, then again without its outlier segments
        m = motions(seg, keep, turns)
        fit = regularised_fit(_residual_function(m, degree), theta0, prior, _names(degree), _groups(m, noise),
                              None if fit is None else fit.theta)
        if first:
            keep[np.flatnonzero(keep)] = ~_segment_outliers(direction_residual(m, fit.theta, degree), m.present)
    sigma = np.array([fit.sigma.get(name, np.nan) for name in DIRECTION_GROUPS])
    a, g = _split(fit.theta, degree)
    return GyroGain(a, g, True, "", int(keep.sum()), dict(skipped, outliers=int((~keep).sum())), rms_raw,
                    rms_bias, _rms_deg(direction_residual(m, fit.theta, degree), m.present), fit,
                    np.degrees(sigma), m.turns)


def fit_gyroscope(datasets: list[ImuData], windows: list[RestWindow], directions: np.ndarray,
                  noise: np.ndarray, biases: list[np.ndarray], t0: float, ts: float, degree: int) -> GyroGain:
    """Gains of the gyro from the motions between rests, with B(T) already removed.

    directions (K, 2, 3): unit gravity and field directions per window (NaN where missing);
    noise (2,): their expected error [rad] (see fit_gyro_gain); biases: B(T) (N_i, 3) rad/s per
    recording; degree: largest G(T) degree. Gravity alone (with the closed turns) is tried first
    (Tedaldi et al.): the field direction carries the magnetometer's nonlinearity and the error of its
    alignment R (a few tenths of a degree, systematic) into A_g, so it is added only where gravity
    leaves gain parameters held by the prior (rotations about the vertical without a known angle), and
    kept when it holds fewer; or used alone without an accelerometer."""
    seg, skipped = build_segments(datasets, windows, directions, biases, t0, ts)
    noise = np.asarray(noise, dtype=float)
    if seg is None:
        return fit_gyro_gain(seg, skipped, noise, 0)
    p, why_degree = gain_degree(seg, degree)
    turns = find_closed_turns(seg.corrected, seg.start[:, 0], seg.end[:, 0], seg.weight[:, 0] > 0)
    if not seg.weight[:, 1].any() or not seg.weight[:, 0].any():
        gain = fit_gyro_gain(seg, skipped, noise, p, turns)
    else:
        gravity = replace(seg, weight=seg.weight * np.array([1.0, 0.0]))
        gain = fit_gyro_gain(gravity, skipped, noise, p, turns)
        if gain.fit.held.any():
            both = fit_gyro_gain(seg, skipped, noise, p, turns)
            gain = both if both.fit.held.sum() < gain.fit.held.sum() else gain
    full = count_full_turns(seg.corrected, seg.start[:, 0], seg.end[:, 0], seg.weight[:, 0] > 0)
    return replace(gain, reason=why_degree, full_turns=full)
