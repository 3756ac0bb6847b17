"""Whether the field of the calibration recordings deserves to correct the heading (issue 29): the
setting mag_heading, 1 (9D) or 0 (6D, heading from the gyro alone).

A spread of the corrected field norm within NOISE_FACTOR times the sensor's own noise (from the
sample-to-sample differences of the norm, which a field fixed in the room does not change; a repeated
reading of a magnetometer slower than the IMU is not a new sample and left out) is noise,
not a non-uniform field: the magnetometer is kept. Beyond it, a field perturbation δB of no preferred direction changes the field norm by about its component along
the field, and turns the horizontal field — the heading — by about its horizontal perpendicular
component over the horizontal field strength. So the corrected field's relative norm spread σ (robust:
1.4826 · median absolute deviation, over every finite sample; the norm needs no attitude) means heading
errors of about σ / cos(dip). A 6D filter's heading instead drifts with the residual gyro bias b
(gyro_bias_residual): b · T after T seconds. The magnetometer is trusted when its heading error is
below the gyro's drift over the longest calibration recording (what the user records is what the FMU
will see): σ / cos(dip) < b · T. A field whose norm spreads widely — a robot cell, a vehicle, iron near
the sensor, or a magnetometer left uncalibrated — then falls back to 6D, and the note says why.
"""
from __future__ import annotations

import math

import numpy as np

from training.data.dataset import ImuData
from training.data.reference_field import robust_sigma
from training.models.thermal import ThermalModel, apply_thermal

#: Fewest finite field samples for a verdict.
MIN_FIELD_SAMPLES = 200
#: A norm spread up to this many times the sensor noise is noise (3σ: white noise alone exceeds it
#: with probability 0.3 %).
NOISE_FACTOR = 3.0


def relative_norm_spread(datasets: list[ImuData], mag: ThermalModel) -> tuple[float, float, int]:
    """(robust relative spread σ [1] of the corrected field norm, its white noise σ_n [1] from the
    differences of consecutive samples (robust, / √2), finite samples) over the recordings."""
    norms, steps = [], []
    for d in datasets:
        ok = np.all(np.isfinite(d.mag), axis=1)
        if ok.any():
            norm = np.linalg.norm(apply_thermal(mag, d.mag[ok], d.temp[ok]), axis=1)
            norms.append(norm)
            step = np.diff(norm)
            steps.append(step[step != 0.0])  # a repeated reading (a slower magnetometer held) is no new sample
    if not norms:
        return float("nan"), float("nan"), 0
    norm, step = np.concatenate(norms), np.concatenate(steps)
    median = float(np.median(norm))
    noise = robust_sigma(step) / np.sqrt(2.0) if step.size else 0.0
    return robust_sigma(norm) / median, noise / median, int(norm.size)


def longest_duration(datasets: list[ImuData]) -> float:
    """Duration [s] of the longest recording."""
    return max(float(d.t[-1] - d.t[0]) for d in datasets)


def mag_heading_setting(datasets: list[ImuData], mag: ThermalModel, settings: dict[str, float],
                        notes: list[str]) -> dict[str, float]:
    """{"mag_heading": 1.0 or 0.0} from the recordings' field (see the module), with a note saying
    why; {} when the recordings hold no field, or too few samples to judge (the default stays, noted)."""
    sigma, noise, samples = relative_norm_spread(datasets, mag)
    if samples == 0:
        return {}
    if samples < MIN_FIELD_SAMPLES:
        notes.append(f"mag_heading = 1 (the FMU's default): {samples} field samples, {MIN_FIELD_SAMPLES} needed "
                     "to judge the field's uniformity")
        return {}
    dip = float(settings["field_dip"])
    heading_error = math.degrees(sigma / max(math.cos(dip), 0.1))
    seconds = longest_duration(datasets)
    drift = math.degrees(float(settings["gyro_bias_residual"])) * seconds
    if sigma <= NOISE_FACTOR * noise:
        notes.append(f"mag_heading = 1: the magnetometer corrects the heading: the corrected field norm spreads "
                     f"by {100.0 * sigma:.2f} % (robust σ, {samples} samples), within {NOISE_FACTOR:g} × its "
                     f"noise {100.0 * noise:.2f} %: a uniform field")
        return {"mag_heading": 1.0}
    facts = (f"the corrected field norm spreads by {100.0 * sigma:.2f} % (robust σ, {samples} samples; noise "
             f"{100.0 * noise:.2f} %), "
             f"heading errors of about {heading_error:.2f}° at the dip {math.degrees(dip):.1f}°; the gyro alone "
             f"drifts by {drift:.2f}° over the {seconds:.0f} s of the longest recording at its residual bias "
             f"{math.degrees(float(settings['gyro_bias_residual'])):.4f} °/s")
    if heading_error < drift:
        notes.append(f"mag_heading = 1: the magnetometer corrects the heading: {facts}")
        return {"mag_heading": 1.0}
    notes.append(f"mag: warning: mag_heading = 0 (6D, the magnetometer is not used for the attitude): the field is "
                 f"too non-uniform to trust: {facts}; record in the field the FMU will see, away from iron, "
                 "or calibrate the magnetometer, to use it")
    return {"mag_heading": 0.0}
