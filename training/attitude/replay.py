"""Attitude-filter settings chosen by replaying the calibration recordings that carry an attitude
reference (issue 29): the trained model runs through the C pipeline (training.runtime.run_batch, the
FMU's code) once per candidate value, and the value with the lower total attitude error against the
reference is written. Without a reference the FMU's default stays, and a note says so.

The candidates are physical alternatives the data decide between, not a search grid:

- gyro_hold: whether a rate sample is the mean over the interval before it (MEMS decimation filters;
  the FMU's default, as real recordings show: BROAD's 20 trials, inclination 0.90° → 0.72°) or an
  instantaneous value (the simulator's samples), integrated with the trapezoidal rule.
- motion_bias: whether the gyro's error in motion is worth estimating from the inclination correction
  (sources/ImuMotionBias.h: a real gyro's scale-factor and cross-axis residuals show there; BROAD's
  20 trials, inclination 0.719° → 0.695°) or the rest estimate alone is better (a gyro whose errors
  the calibration removed, where the estimate only adds the correction's noise).
"""
from __future__ import annotations

import numpy as np

from training.data.dataset import ImuData

#: Setting -> the values replayed, the FMU's default first (a tie keeps it).
CANDIDATES = {"gyro_hold": (1.0, 0.0), "motion_bias": (1.0, 0.0)}
#: How the notes of keep_better_attitude begin (the calibration summary opens with them).
REFERENCE_JUDGED = "ATTITUDE REFERENCE USED TO JUDGE, NOT TO CALIBRATE"
REFERENCE_KEPT = "calibration derived from the attitude reference kept"
REFERENCE_DECISIONS = (REFERENCE_JUDGED, REFERENCE_KEPT)
#: Fewest reference samples (summed over the recordings) for a replay to decide.
MIN_REFERENCE_SAMPLES = 1000


def referenced(datasets: list[ImuData]) -> list[ImuData]:
    """The recordings with an attitude reference."""
    return [d for d in datasets if d.ref_q is not None and np.isfinite(d.ref_q).all(axis=1).any()]


def _squared_errors(coefficients: np.ndarray, settings: dict[str, float], data: ImuData) -> np.ndarray:
    """Squared total attitude errors [rad²] of the pipeline against the recording's reference, over
    its eval_mask samples with a finite reference."""
    from contract.layout import OUTPUTS, settings_array
    from training.data.reference import reference_quaternion_magnetic
    from training.frames import quat_multiply
    from training.data.dataset import recording_parameters
    from contract.mounting import array_codes
    from training.mounting import body_references
    from training.runtime import run_batch
    s = np.asarray(settings_array({**settings, **recording_parameters(data)}))
    out = run_batch(coefficients, s, data.t, data.inputs([]))
    q_est = out[:, [OUTPUTS.index(n) for n in ("q_w", "q_x", "q_y", "q_z")]]
    q_ref = reference_quaternion_magnetic(body_references(data, array_codes(s)))
    w = quat_multiply(q_est, q_ref * np.array([1.0, -1.0, -1.0, -1.0]))[:, 0]
    mask = np.isfinite(q_ref).all(axis=1) & np.isfinite(w)
    if data.eval_mask is not None:
        mask &= data.eval_mask.astype(bool)
    return (2.0 * np.arccos(np.clip(np.abs(w[mask]), 0.0, 1.0))) ** 2


def replay_rmse(coefficients: np.ndarray, settings: dict[str, float], datasets: list[ImuData]) -> float:
    """Total attitude RMSE [°] over every reference sample of `datasets`."""
    errors = np.concatenate([_squared_errors(coefficients, settings, d) for d in datasets])
    return float(np.rad2deg(np.sqrt(np.mean(errors)))) if errors.size else float("nan")


def choose_by_replay(coefficients: np.ndarray, settings: dict[str, float], datasets: list[ImuData],
                     notes: list[str]) -> dict[str, float]:
    """The settings with every CANDIDATES entry set to the value whose replay of the referenced
    recordings gives the lowest total attitude RMSE (one setting at a time, in CANDIDATES order);
    a note per setting says what was replayed and measured, or why the default stays."""
    chosen = dict(settings)
    sets = referenced(datasets)
    samples = sum(int(np.isfinite(d.ref_q).all(axis=1).sum()) for d in sets)
    for name, values in CANDIDATES.items():
        if samples < MIN_REFERENCE_SAMPLES:
            notes.append(f"{name} = {values[0]:g} (the FMU's default): no attitude reference to replay "
                         f"({samples} reference samples, {MIN_REFERENCE_SAMPLES} needed)")
            continue
        scores = {v: replay_rmse(coefficients, {**chosen, name: v}, sets) for v in values}
        best = min(values, key=lambda v: (scores[v], values.index(v)))
        chosen[name] = best
        measured = ", ".join(f"{v:g}: {scores[v]:.3f}°" for v in values)
        notes.append(f"{name} = {best:g}: chosen by replaying {len(sets)} recording(s) with an attitude "
                     f"reference through the FMU's filter (total attitude RMSE {measured})")
    return chosen


def keep_better_attitude(with_reference, without_reference, datasets: list[ImuData]):
    """Of two models of the same recordings — one calibrated from references derived from their
    attitude reference, one as if they had none — the one whose attitude replays closer to that
    reference (replay_rmse over every referenced recording; a tie keeps the first). The kept model's
    notes open with both figures; when the model without the reference wins, it says loudly that the
    reference-derived calibration was not exported."""
    from training.artefact import coefficients_array, settings_dict
    sets = referenced(datasets)
    scores = [replay_rmse(coefficients_array(a), settings_dict(a), sets) for a in (with_reference, without_reference)]
    figures = (f"total attitude RMSE against the reference over {len(sets)} recording(s): "
               f"{scores[0]:.3f}° with the calibration derived from the attitude reference, "
               f"{scores[1]:.3f}° with the one fitted without it")
    if scores[1] < scores[0]:
        without_reference.notes.insert(0, f"{REFERENCE_JUDGED}: the calibration fitted without it gives the better attitude ({figures}); the "
                                          "reference-derived calibration is NOT exported")
        return without_reference
    with_reference.notes.insert(0, f"{REFERENCE_KEPT}: it gives the better "
                                   f"attitude ({figures})")
    return with_reference
