"""The motions between consecutive rests, as the gyro gain fit integrates them.

Between two consecutive rests (or holds) k, k+1 of one recording the gyro turns the sensor from the
pose of rest k to that of rest k+1; every calibrated body-fixed-in-the-world direction d (specific force
at rest, the field when calibrated) measured at both ends checks the integrated rotation (Tedaldi,
Pretto, Menegatti, ICRA 2014, §IV-D). A segment is kept when it is short enough that the residual bias
does not dominate, has no gap, has a direction at both ends, and turns enough to carry signal.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from training.data.dataset import ImuData
from training.models.thermal import normalised_temperature
from training.selfcal.rest import RestWindow

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
    its mean direction; a hold drifts slowly, so its middle does. (From the middle of each rest
    instead, the gyro's noise over half of each rest is integrated too: on the simulated Ferraris
    session the z gain came out 0.04 % off instead of 0.07 %, on the simulated protocol the held-out
    figures moved by ±0.002°; the rest's end was kept.)"""
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
