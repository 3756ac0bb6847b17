"""Gyroscope bias B(T) from the rests, and gains + misalignment from the rotation between rests.

Bias: at rest the true rate is zero, so every rest-window mean is B(T) at the window's
temperature, plus the earth rate projected on the sensor axes (|Ω| = 7.292e-5 rad/s =
0.0042 °/s at most per axis, depending on pose and latitude) — too small to separate from the
bias without knowing the poses in the earth frame, so it is absorbed in B (its pose average).

Gains, misalignment and their drift come from the motions between rests: training.selfcal.gyro_gain.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from training.selfcal.accel import gain_summary
from training.selfcal.gyro_gain import GyroGain
from training.selfcal.regularised import parameter_label, uncertainty_report
from training.selfcal.rest import RestWindow
from training.selfcal.segments import MAX_SEGMENT_S
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
@dataclass(frozen=True)
class GyroBias:
    """B(T): coefficients b (3, P+1) rad/s in powers of Tn, degree P, reason the degree is lower
    than requested, distinct temperature clusters, rests used / dropped as outliers, RMS of the
    rest means before (raw) and after [rad/s], the mean residual (R, 3) rad/s of each
    recording's rests (their spread is the run-to-run bias no B(T) can hold), and the standard error
    (3,) rad/s of the bias at t0 (the rests' scatter about B(T) over the dof, through the design)."""

    b: np.ndarray
    degree: int
    reason: str
    clusters: int
    rests: int
    dropped: int
    rms_before: float
    rms_after: float
    recording_offsets: np.ndarray
    se: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))


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
                    float(np.sqrt(np.mean(g[keep] ** 2))), float(np.sqrt(np.mean(after ** 2))), offsets,
                    _bias_se(powers(temp[keep], t0, ts, p), after))


def _bias_se(design: np.ndarray, residual: np.ndarray) -> np.ndarray:
    """Standard error (3,) of the constant term of a least-squares B(T) with design (K, P+1) and
    residuals (K, 3): σ² (XᵀX)⁻¹[0, 0], σ² per axis over K − (P+1) dof; NaN without a spare rest."""
    dof = len(design) - design.shape[1]
    if dof < 1:
        return np.full(3, np.nan)
    sigma2 = np.sum(residual ** 2, axis=0) / dof
    return np.sqrt(sigma2 * np.linalg.pinv(design.T @ design)[0, 0])


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
           "bias_dps": np.degrees(bias.b[:, 0]), "bias_se": bias.se, "bias_coefficients": bias.b, "t0_c": t0, "ts_c": ts,
           "gain_degree": gain.g.shape[1], "gain_coefficients": gain.g,
           "bias_rests": bias.rests, "bias_outliers": bias.dropped,
           "recording_bias_offsets_rad_s": bias.recording_offsets, "segments": gain.segments,
           "segments_skipped": gain.skipped, "max_segment_s": MAX_SEGMENT_S,
           "direction_noise_deg": dict(zip(("gravity", "field"), gain.direction_noise_deg)),
           "full_turns": gain.full_turns,
           "closed_turns": [{"turns": t.turns, "raw_deg": t.raw_deg, "axis_tilt_deg": t.axis_tilt_deg,
                             "axis": t.axis} for t in gain.turns],
           "residual": {"rest_rate_rms_rad_s": {"before": bias.rms_before, "after": bias.rms_after},
                        "direction_error_rms_deg": {"before": gain.rms_raw_deg,
                                                    "bias_only": gain.rms_bias_deg,
                                                    "after": gain.rms_after_deg}}}
    noise = gain.direction_noise_deg
    used = [name for name, v in zip(("gravity", "field"), noise) if np.isfinite(v)]
    out["directions_used"] = " + ".join(used + (["closed turns"] if gain.turns else [])) or None
    out.update(earth_rate_report())
    out.update(gain_summary(gain.A))
    if gain.fit is not None:
        out.update(uncertainty_report(gain.fit, lambda th: _derived(th), 9 + 3 * gain.g.shape[1]))
    else:
        out["held"] = [parameter_label(f"A[{i},{j}]") for i in range(3) for j in range(3)]
    notes = [f"bias from {bias.rests} rests (degree {bias.degree}): rest-mean RMS {bias.rms_before:.2e} -> "
             f"{bias.rms_after:.2e} rad/s; {EARTH_RATE_NOTE}",
             f"gains {'fitted' if gain.fitted else 'not fitted'} from {gain.segments} rest-to-rest segments "
             f"(skipped: {gain.skipped}) and {len(gain.turns)} closed turns; direction error RMS "
             f"{gain.rms_raw_deg:.2f}° raw, {gain.rms_bias_deg:.2f}° bias removed, {gain.rms_after_deg:.2f}° calibrated"]
    if gain.turns:
        notes.append("closed turns taken as whole turns (the known angle): " + ", ".join(
            f"{t.turns:+d} × 360° (raw {t.raw_deg:.1f}°, axis {t.axis_tilt_deg:.1f}° from vertical)" for t in gain.turns))
    if out.get("held"):
        notes.append("held at nominal by the prior (the motions do not determine them): " + ", ".join(out["held"]))
    if out["why_not_more"]:
        notes.append(f"not richer: {out['why_not_more']}")
    out["notes"] = notes
    return out


def _derived(theta: np.ndarray) -> dict[str, np.ndarray]:
    """The reported quantities of a gain parameter vector: scale factors and non-orthogonality [deg]
    (for their standard errors by linear propagation)."""
    summary = gain_summary(np.eye(3) + theta[:9].reshape(3, 3))
    return {"scale_factors": np.array(summary["scale_factors"]),
            "nonorthogonality_deg": np.array(list(summary["nonorthogonality_deg"].values()))}
