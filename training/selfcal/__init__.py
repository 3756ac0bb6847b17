"""Self-calibration of a MEMS IMU + magnetometer from a raw log, without any reference.

From a recording of a still start, poses held a few seconds, rotations between them and a slow
tumble (docs/calibration.md), fit per triad the runtime's model x_c = A (x - B(T)) (G = 1) from
invariants only:

1. rests and hand-held holds, grouped into poses (rest.py);
2. gyro bias B(T) from the rest means (gyro.py);
3. accelerometer A (symmetric) and b(T) from the gravity norm at the poses (accel.py);
4. magnetometer hard/soft iron (and their temperature drift B(T), G(T)) from the field norm over
   the recording, then its rotation onto the accelerometer frame and the dip from the dip-angle
   invariant at the poses (magnet.py);
5. gyro gains and misalignment A_g (and the gain drift G(T)) from the rotation between
   consecutive rests (gyro.py).

Every stage fits only what the data identify (Jacobian condition and parameter standard errors)
and says in the report what it fitted and why not more. Deterministic: no randomness.
"""
from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np
from tqdm import tqdm

from training.data.dataset import ImuData
from training.data.earth import STANDARD_GRAVITY
from training.models.thermal import ThermalModel, apply_thermal
from training.selfcal import accel, gyro, gyro_gain, magnet
from training.selfcal.protocol import recognise, recording_spans
from training.selfcal.poses import count_poses, group_poses
from training.selfcal.rest import RestWindow, detect_rest
from training.selfcal.temperature import count_clusters, normalisation, temperature_span

__all__ = ["RestWindow", "SelfCalResult", "self_calibrate"]


@dataclass(frozen=True)
class SelfCalResult:
    """thermal: 'gyr', 'acc', 'mag' -> ThermalModel (disabled identity where nothing was
    identifiable); report: JSON-ready dict per triad plus 'rest' (see `self_calibrate`);
    rest_windows: every rest and hold found (RestWindow, for plots); rest_masks: per recording an
    (N,) bool array of the rest samples (holds excluded)."""

    thermal: dict
    report: dict
    rest_windows: list
    rest_masks: list


def self_calibrate(datasets: list[ImuData], *, field_norm: float | None, degree: int = 2,
                   gravity: float = STANDARD_GRAVITY, progress: bool = True) -> SelfCalResult:
    """Calibrate gyr, acc and mag of `datasets` (one sensor unit) from invariants.

    field_norm: local earth-field magnitude [µT] (sidecar earth_field.norm_ut, a geomagnetic
    model, ...); None: the recordings' own median norm about the hard-iron centre (the field is
    then calibrated in the sensor's own scale). degree: largest degree of the temperature
    polynomials B(T) and G(T) (fewer where the data do not pin them). gravity: local g [m/s²].

    Report per triad: unit; fitted (what); why_not_more; notes (sentences); rest_windows, holds,
    poses; degree; temperature_span_c and temperature_clusters; bias (3,) at t0 and
    bias_coefficients (3, P+1) in powers of Tn = (T - t0)/ts (t0_c, ts_c); gain_coefficients
    (3, Q) of G(T) (gyr, mag); scale_factors (gain of each raw axis), scale_factor_error_pct,
    nonorthogonality_deg, misalignment_deg (angle of each raw axis to the body axis); residual:
    {metric: {before, after}} — gyr: rest_rate_rms_rad_s, direction_error_rms_deg (also
    bias_only); acc: gravity_norm_rms_ms2; mag: field_norm_rms_ut, field_norm_spread (std/mean),
    dip_invariant_rms. mag also: field_norm_ut, field_norm_source, coverage, dip_deg,
    alignment_angle_deg. gyr also: the earth-rate note, segments used and skipped.
    """
    if not datasets:
        raise ValueError("self_calibrate: no recording given")
    t0, ts = normalisation([d.temp for d in datasets])
    bar = tqdm(datasets, desc="selfcal: rests and holds", disable=not progress)
    detections = [detect_rest(d, i) for i, d in enumerate(bar)]
    windows = group_poses([w for det in detections for w in det.windows])
    with _stage("selfcal: gyro bias B(T)", progress):
        bias = gyro.fit_gyro_bias(windows, t0, ts, degree)
    with _stage("selfcal: accelerometer (gravity norm)", progress):
        acc_fit = accel.fit_accelerometer(windows, gravity, t0, ts, degree)
        acc_model = _acc_model(acc_fit, t0, ts)
    with _stage("selfcal: magnetometer (field norm, dip)", progress):
        mag_fit, alignment, mag_model = _magnetometer(datasets, windows, acc_model, field_norm, t0, ts,
                                                      degree)
    directions = _directions(windows, acc_model, mag_fit, alignment, mag_model)
    with _stage("selfcal: gyro gains (rotation between rests, closed turns)", progress):
        noise = _direction_noise(acc_fit, mag_fit, gravity)
        biases = [gyro.bias_at(bias.b, d.temp, t0, ts) for d in datasets]
        gain = gyro_gain.fit_gyroscope(datasets, windows, directions, noise, biases, t0, ts, degree)
    gyr_model = _gyr_model(bias, gain, t0, ts)
    report = _report(datasets, detections, windows, bias, gain, acc_fit, mag_fit, alignment, gravity,
                     t0, ts)
    report["protocol"] = recognise(report, windows, recording_spans(datasets))
    return SelfCalResult({"gyr": gyr_model, "acc": acc_model, "mag": mag_model}, report, windows,
                         [det.mask for det in detections])


@contextmanager
def _stage(desc: str, progress: bool):
    """A one-step tqdm bar around a stage (completed when the block ends)."""
    with tqdm(total=1, desc=desc, disable=not progress) as bar:
        yield
        bar.update(1)


def _acc_model(fit: accel.AccelFit, t0: float, ts: float) -> ThermalModel:
    """ThermalModel of the accelerometer fit (disabled identity when nothing was fitted)."""
    if fit.level == "nothing":
        return ThermalModel.identity(enabled=False)
    return ThermalModel(True, t0, ts, fit.degree, fit.A, np.zeros((3, fit.degree)), fit.b)


def _gyr_model(bias: gyro.GyroBias, gain: gyro_gain.GyroGain, t0: float, ts: float) -> ThermalModel:
    """ThermalModel of the gyro: A_g, G(T) and B(T), the shorter polynomial padded with zeros to
    the longer one's degree (disabled identity when no rest was found)."""
    if bias.rests == 0 and not gain.fitted:
        return ThermalModel.identity(enabled=False)
    p = max(bias.degree, gain.g.shape[1])
    g, b = np.zeros((3, p)), np.zeros((3, p + 1))
    g[:, :gain.g.shape[1]], b[:, :bias.b.shape[1]] = gain.g, bias.b
    return ThermalModel(True, t0, ts, p, gain.A, g, b)


def _rest_means(windows: list[RestWindow], triad: str, model: ThermalModel) -> np.ndarray:
    """Calibrated window means (K, 3) of a triad (NaN rows where not recorded)."""
    raw = np.array([getattr(w, triad) for w in windows]).reshape(-1, 3)
    return apply_thermal(model, raw, np.array([w.temp for w in windows]))


def _unit(v: np.ndarray) -> np.ndarray:
    """Rows of v (K, 3) scaled to unit length (NaN stays NaN)."""
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _magnetometer(datasets, windows, acc_model, field_norm, t0, ts, degree):
    """(MagFit, Alignment or None, ThermalModel) of the magnetometer of all recordings."""
    mag = np.concatenate([d.mag for d in datasets])
    temp = np.concatenate([d.temp for d in datasets])
    fit = magnet.fit_magnetometer(mag, field_norm, temp, t0, ts, degree, [len(d) for d in datasets])
    if not np.isfinite(mag).all(axis=1).any() or not windows:
        return fit, None, fit.model()
    use = _undisturbed(windows, fit) & np.array([np.all(np.isfinite(w.acc)) for w in windows], dtype=bool)
    if not use.any():
        return fit, None, fit.model()
    field = _unit(_field_means(windows, fit))
    gravity = _unit(_rest_means(windows, "acc", acc_model))
    use &= _consistent_dip(gravity, field, use)
    if fit.level == "nothing":  # no calibration applied: the dip of the raw field, no rotation
        return fit, _raw_dip(gravity[use], field[use]), ThermalModel.identity(enabled=False)
    alignment = magnet.fit_alignment(gravity[use], field[use])
    return fit, alignment, fit.model(alignment.R)


def _raw_dip(gravity: np.ndarray, field: np.ndarray) -> magnet.Alignment:
    """Alignment R = I with the dip [°] of unit specific-force and field directions (K, 3): the median
    of asin(-f̂·ĥ) over the rests (no field calibration was applied, so no rotation either)."""
    s = -np.sum(gravity * field, axis=1)
    dip = float(np.degrees(np.arcsin(np.clip(np.median(s), -1.0, 1.0))))
    rms = float(np.sqrt(np.mean((s - np.sin(np.radians(dip))) ** 2)))
    return magnet.Alignment(np.eye(3), dip, False, len(s), rms, rms, None,
                            "no field calibration applied: R = I, dip of the raw field")


#: A rest whose dip (R = I) is further than DIP_OUTLIER_SIGMAS robust σ from the median dip of the
#: rests, and at least DIP_OUTLIER_FLOOR_DEG, saw a disturbed field direction (iron nearby turns the
#: field without changing its norm much: xio_handheld's disturbance moves the dip by 19°, its norm by
#: 1 %). A magnetometer misaligned to the accelerometer by α scatters the dip by at most ±α, a few
#: degrees for a MEMS package, so honest rests stay inside the floor.
DIP_OUTLIER_SIGMAS = 5.0
DIP_OUTLIER_FLOOR_DEG = 3.0


def _consistent_dip(gravity: np.ndarray, field: np.ndarray, use: np.ndarray) -> np.ndarray:
    """(K,) bool: rests whose dip asin(-f̂·ĥ) [°] from unit specific-force and field directions (K, 3)
    is within max(DIP_OUTLIER_SIGMAS robust σ, DIP_OUTLIER_FLOOR_DEG) of the median over `use`."""
    with np.errstate(invalid="ignore"):
        dip = np.degrees(np.arcsin(np.clip(-np.sum(gravity * field, axis=1), -1.0, 1.0)))
    ok = use & np.isfinite(dip)
    if ok.sum() < 3:
        return ok
    median = np.median(dip[ok])
    limit = max(DIP_OUTLIER_SIGMAS * 1.4826 * np.median(np.abs(dip[ok] - median)), DIP_OUTLIER_FLOOR_DEG)
    return ok & (np.abs(dip - median) <= limit)


def _field_means(windows: list[RestWindow], fit: magnet.MagFit) -> np.ndarray:
    """Field fit M (G(T) ⊙ (h - B(T))) of the window means (K, 3) µT (before the alignment R)."""
    raw = np.array([w.mag for w in windows]).reshape(-1, 3)
    return magnet.apply_field(fit, raw, np.array([w.temp for w in windows]))


def _undisturbed(windows: list[RestWindow], fit: magnet.MagFit) -> np.ndarray:
    """(K,) bool: windows whose calibrated field norm is within OUTLIER_SIGMAS robust σ of F."""
    norms = np.linalg.norm(_field_means(windows, fit), axis=1)
    limit = magnet.OUTLIER_SIGMAS * max(fit.sigma, 1e-12)
    with np.errstate(invalid="ignore"):
        return np.isfinite(norms) & (np.abs(norms - fit.field_norm) <= limit)


def _directions(windows, acc_model, mag_fit, alignment, mag_model) -> np.ndarray:
    """(K, 2, 3) unit directions per window for the gyro fit: calibrated specific force, and the
    calibrated field where it is trustworthy in the accelerometer frame (ellipsoid fitted, and
    aligned — or no accelerometer to align to) and undisturbed; NaN elsewhere."""
    acc = _unit(_rest_means(windows, "acc", acc_model))
    field = np.full_like(acc, np.nan)
    has_acc = np.isfinite(acc).all(axis=1).any()
    aligned = alignment is not None and alignment.fitted
    if mag_fit.level.startswith("hard + soft") and (aligned or not has_acc):
        ok = _undisturbed(windows, mag_fit)
        field[ok] = _unit(_rest_means(windows, "mag", mag_model))[ok]
    return np.stack([acc, field], axis=1)


def _direction_noise(acc_fit: accel.AccelFit, mag_fit: magnet.MagFit, gravity: float) -> np.ndarray:
    """First guess of the direction error [rad] of the gravity and field directions at the rests:
    their norm residual relative to the norm (a distortion that bends the norm by x % bends the
    direction by about as much); NaN when unknown (the gyro fit then re-estimates it)."""
    acc = acc_fit.rms_after if np.isfinite(acc_fit.rms_after) else acc_fit.rms_before
    return np.array([acc / gravity, mag_fit.rms_after / mag_fit.field_norm])


def _report(datasets, detections, windows, bias, gain, acc_fit, mag_fit, alignment, gravity, t0,
            ts) -> dict:
    """The JSON-ready report (see `self_calibrate`)."""
    rests = [w for w in windows if w.kind == "rest"]
    temps = np.array([w.temp for w in windows])
    common = {"rest_windows": len(rests), "holds": len(windows) - len(rests),
              "poses": count_poses(windows), "temperature_span_c": temperature_span(temps),
              "temperature_clusters": count_clusters(temps)}
    report = {"gyr": {**common, **gyro.summarise(bias, gain, t0, ts)},
              "acc": {**common, **accel.summarise(acc_fit, gravity, t0, ts)},
              "mag": {**common, **magnet.summarise(mag_fit, alignment)},
              "rest": {"windows": len(windows), "rests": len(rests), "holds": len(windows) - len(rests),
                       "poses": count_poses(windows),
                       "per_recording": [{"name": d.name, "samples": len(d),
                                          "rest_fraction": float(det.mask.mean()) if len(d) else 0.0,
                                          "windows": len(det.windows),
                                          "window_samples": det.window_samples,
                                          "noise_floor": det.noise_floor, "threshold": det.threshold,
                                          "hold_note": det.hold_note}
                                         for d, det in zip(datasets, detections)]}}
    return _json(report)


def _json(value):
    """value with numpy arrays/scalars turned into lists/floats and NaN/inf into None."""
    if isinstance(value, dict):
        return {str(k): _json(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json(v) for v in value]
    if isinstance(value, np.ndarray):
        return _json(value.tolist())
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if np.isfinite(value) else None
    return value
