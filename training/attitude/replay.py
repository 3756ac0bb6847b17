"""Attitude-filter settings chosen by replaying the calibration recordings that carry an attitude
reference (issue 29): the trained model runs through the C pipeline (training.runtime.run_batch, the
FMU's code) once per candidate value, and the value with the lower total attitude error against the
reference on every recording replaced the default (lower_on_every). Without a reference the FMU's
default stays, and a note says so. The same rule decides, per triad, whether a calibration derived from
the attitude reference is exported (triads_the_reference_improves).

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
from contract.layout import TRIAD_ORDER

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


def _rmse_deg(squared: np.ndarray) -> float:
    """RMS [°] of squared angles [rad²]; NaN when there are none."""
    return float(np.rad2deg(np.sqrt(np.mean(squared)))) if squared.size else float("nan")


def replayed(coefficients: np.ndarray, settings: dict[str, float],
             datasets: list[ImuData]) -> tuple[list[float], float]:
    """(total attitude RMSE [°] of each recording of `datasets` against its own reference, the same
    over all their reference samples), from one run of the pipeline per recording."""
    errors = [_squared_errors(coefficients, settings, d) for d in datasets]
    return [_rmse_deg(e) for e in errors], _rmse_deg(np.concatenate(errors) if errors else np.zeros(0))


def lower_on_every(candidate: list[float], incumbent: list[float]) -> bool:
    """True when `candidate`'s error is lower than `incumbent`'s on every recording. A replay changes
    what `train` writes only then: the recordings are the only independent trials it has, and a change
    that helps one of them and harms another is not shown to help the user's next recording (BROAD
    01 + 02, no reference: motion_bias = 0 won the pooled replay, 1.209° vs 1.302°, on trial 01 alone,
    and lowered the inclination on only 5 of the 20 trials against VQF's, 14 with the default)."""
    return len(candidate) == len(incumbent) > 0 and all(c < i for c, i in zip(candidate, incumbent))


def _figures(values: tuple, per: dict[float, list[float]], sets: list[ImuData]) -> str:
    """Per recording: 'name: a° / b°' over `values`, for the notes."""
    return "; ".join(f"{d.name}: " + " / ".join(f"{per[v][k]:.3f}°" for v in values) for k, d in enumerate(sets))


def choose_by_replay(coefficients: np.ndarray, settings: dict[str, float], datasets: list[ImuData],
                     notes: list[str]) -> dict[str, float]:
    """The settings with every CANDIDATES entry replayed through the FMU's filter on the referenced
    recordings (one setting at a time, in CANDIDATES order): the alternative with the lowest total
    attitude RMSE replaces the FMU's default only when it is lower on every recording (lower_on_every);
    a note per setting says what was replayed and measured, or why the default stays."""
    chosen = dict(settings)
    sets = referenced(datasets)
    samples = sum(int(np.isfinite(d.ref_q).all(axis=1).sum()) for d in sets)
    for name, values in CANDIDATES.items():
        if samples < MIN_REFERENCE_SAMPLES:
            notes.append(f"{name} = {values[0]:g} (the FMU's default): no attitude reference to replay "
                         f"({samples} reference samples, {MIN_REFERENCE_SAMPLES} needed)")
            continue
        runs = {v: replayed(coefficients, {**chosen, name: v}, sets) for v in values}
        per, scores = {v: r[0] for v, r in runs.items()}, {v: r[1] for v, r in runs.items()}
        challenger = min(values[1:], key=lambda v: (scores[v], values.index(v)))
        best = challenger if lower_on_every(per[challenger], per[values[0]]) else values[0]
        chosen[name] = best
        measured = ", ".join(f"{v:g}: {scores[v]:.3f}°" for v in values)
        why = ("" if best != values[0] or scores[challenger] >= scores[values[0]] else
               f"; the FMU's default stays: {challenger:g} is lower in total but not on every recording")
        notes.append(f"{name} = {best:g}: chosen by replaying {len(sets)} recording(s) with an attitude "
                     f"reference through the FMU's filter (total attitude RMSE {measured}; per recording, "
                     f"{' / '.join(f'{v:g}' for v in values)}: {_figures(values, per, sets)}){why}")
    return chosen


def _with_triad(model, source, triad: str):
    """`model` with `triad`'s calibration (and the neural stage that follows it: ELM after the
    magnetometer, PSO-BP after the gyroscope) taken from `source`."""
    from dataclasses import replace
    from training.artefact import NEURAL_STAGES
    stage = NEURAL_STAGES.get(triad)
    changes = {"thermal": {**model.thermal, triad: source.thermal[triad]}}
    if stage is not None:
        changes[stage[0]] = getattr(source, stage[0])
        changes["settings"] = {**model.settings, stage[1]: source.settings.get(stage[1], 0.0)}
    return replace(model, **changes)


def triads_the_reference_improves(with_reference, without_reference,
                                  datasets: list[ImuData]) -> tuple[tuple[str, ...], list[str]]:
    """Of the triads calibrated from references derived from the attitude reference (fit_stats
    'reference' == 'attitude'), those whose reference-derived calibration, put alone into the model
    fitted without the reference (at its settings), brings every referenced recording's attitude
    closer to the reference (lower_on_every); and a note per triad with the figures. A derived
    reference carries the reference system's own errors (timing, lever arm, marker alignment, the
    differentiation's noise): BROAD 01 + 02's rate reference, 1.4 °/s RMS from the gyro, fitted
    cross-axis terms of 0.1° that lowered trial 01's replay and raised 02's."""
    from training.artefact import coefficients_array, settings_dict
    from training.completeness import NAMES
    settings = settings_dict(without_reference)
    every = referenced(datasets)
    base = replayed(coefficients_array(without_reference), settings, every)[0]
    sets = [d for d, b in zip(every, base) if np.isfinite(b)]
    base = [b for b in base if np.isfinite(b)]
    derived = [t for t in TRIAD_ORDER if with_reference.fit_stats.get(t, {}).get("reference") == "attitude"]
    if not sets:
        return tuple(derived), [f"{REFERENCE_KEPT} for the {', '.join(NAMES[t] for t in derived)}, not judged: no "
                                "recording has a reference sample inside its eval_mask to replay"]
    kept, notes = [], []
    for triad in derived:
        hybrid = _with_triad(without_reference, with_reference, triad)
        scores = replayed(coefficients_array(hybrid), settings, sets)[0]
        figures = ("total attitude RMSE against the reference, self-calibrated / reference-derived: "
                   + _figures((0, 1), {0: base, 1: scores}, sets))
        if lower_on_every(scores, base):
            kept.append(triad)
            notes.append(f"{REFERENCE_KEPT} for the {NAMES[triad]}: every recording's attitude is closer "
                         f"to the reference with it ({figures})")
        else:
            notes.append(f"{REFERENCE_JUDGED} for the {NAMES[triad]}: its reference-derived calibration "
                         f"does not bring every recording closer to the reference ({figures}); it is NOT "
                         f"exported, the {NAMES[triad]} is self-calibrated")
    return tuple(kept), notes
