"""What a calibration left out, loudly: every triad the recordings contain that `train` left wholly or
partly uncalibrated, why, and what to record to fix it.

A triad is *uncalibrated* when the recordings hold it but its model is the identity (nothing could be
fitted, or the fit lost to the raw sensor on held-out data); *partly calibrated* when its bias, gains or
cross-axis terms were not all determined: a self-calibrated parameter the regularised fit held at nominal
(training.selfcal.regularised), a referenced triad fitted for its bias only, or a magnetometer fitted as a
sphere. Temperature terms do not count: a recording at one temperature determines the model at that
temperature, and the calibrated range says where it holds (docs/fmu.md, "Calibrated range").

`imufmu train` opens its summary with these, repeats them in its WARNINGS, and exits with
EXIT_INCOMPLETE unless --allow-partial is given (training.cli).
"""
from __future__ import annotations

from dataclasses import dataclass

from contract.layout import TRIAD_ORDER

#: Exit status of `imufmu train` when the model was written but a recorded triad is not fully
#: calibrated (without --allow-partial): distinct from 1 (an error) and 2 (a usage error).
EXIT_INCOMPLETE = 3
#: Exit status of a verb that did part of what was asked (e.g. `imufmu fleet train` with some units
#: trained and some failed): the same number, documented in the README's exit-status table.
EXIT_PARTIAL = EXIT_INCOMPLETE
NAMES = {"gyr": "gyroscope", "acc": "accelerometer", "mag": "magnetometer"}
#: What to record, per kind of missing parameter.
ADVICE = {
    "acc": "record at least 9 well-spread poses held still 2-5 s each (faces and corners), or the six faces of a box",
    "gyr bias": "record the sensor lying still for at least 1-2 s (at the start and end of every session)",
    "gyr gain": "record moves that turn the sensor about its {axis} axis between two rests while that axis is not "
                "vertical, or a full turn about {axis} held vertical and put back where it started",
    "gyr cross": "record moves about every axis between rests (a multi-pose session, docs/calibration.md)",
    "gyr stops": "stop still for 1-2 s at least every 30 s of motion (a robot or vehicle: between moves about every "
                 "axis), so that the motion between two rests can be integrated",
    "mag": "record a slow tumble in which every face, edge and corner points down in turn, away from iron",
    "reference": "record motion about every axis while the reference runs",
}


@dataclass(frozen=True)
class Gap:
    """A recorded triad not fully calibrated: triad, 'uncalibrated' or 'partly calibrated', what is
    missing, why, and what to record."""

    triad: str
    kind: str
    missing: str
    reason: str
    advice: str

    def headline(self) -> str:
        """What is missing, without the reason and advice (the summary's opening block)."""
        return f"{NAMES[self.triad]} {self.kind} — {self.missing}"

    def text(self) -> str:
        """One line for the summary and the warnings (a note that `is_gap` recognises)."""
        return (f"{self.triad}: warning: {NAMES[self.triad]} {self.kind} — {self.missing}; {self.reason}; "
                f"to fix it: {self.advice}")


def is_gap(note: str) -> bool:
    """True for a note written by Gap.text."""
    return ": warning: " in note and any(f"{NAMES[t]} {kind} — " in note for t in NAMES
                                         for kind in ("uncalibrated", "partly calibrated"))


def gap_headline(note: str) -> str:
    """The headline part of a Gap.text note (up to the reason)."""
    return note.split(": warning: ", 1)[1].split("; ", 1)[0]


def _held_advice(triad: str, held: list[str]) -> str:
    """What to record for the held parameters of a self-calibrated triad."""
    if triad == "acc":
        return ADVICE["acc"]
    axes = [label.split()[-1] for label in held if label.startswith("gain ")]
    parts = [ADVICE["gyr gain"].format(axis=", ".join(axes))] if axes else []
    if any(label.startswith("cross-axis") for label in held):
        parts.append(ADVICE["gyr cross"])
    return "; ".join(parts) or ADVICE["gyr cross"]


def _selfcal_gap(triad: str, stats: dict) -> Gap | None:
    """The gap of a self-calibrated triad (held parameters; a gyro without rests; a sphere-only
    magnetometer), or None."""
    if triad == "mag":
        fitted = str(stats.get("fitted", ""))
        if fitted.startswith("hard iron only"):
            return Gap(triad, "partly calibrated", "soft iron, scale and misalignment not fitted (hard iron only)",
                       stats.get("why_not_more") or "the field directions do not cover the sphere", ADVICE["mag"])
        return None
    held = [label for label in stats.get("held") or [] if "Tn^" not in label]
    if triad == "gyr" and not int(stats.get("bias_rests") or 0):
        return Gap(triad, "partly calibrated", "bias not fitted (no rest found)",
                   stats.get("why_not_more") or "no rest", ADVICE["gyr bias"])
    if not held:
        return None
    every = len(held) == len(_model_labels(stats))
    if every and triad == "acc":
        return Gap(triad, "uncalibrated", "every bias, gain and cross-axis term held at nominal",
                   stats.get("why_not_more") or "the rests do not determine them", ADVICE["acc"])
    what = "gains and cross-axis terms" if every else ", ".join(held)
    if triad == "gyr" and not int(stats.get("segments") or 0):
        return Gap(triad, "partly calibrated", f"held at nominal (not determined by the recording): {what}",
                   f"no move between two rests could be used ({_skipped_text(stats)})", ADVICE["gyr stops"])
    return Gap(triad, "partly calibrated", f"held at nominal (not determined by the recording): {what}",
               "the rests and motions recorded do not determine them", _held_advice(triad, held))


def _skipped_text(stats: dict) -> str:
    """Why the rest-to-rest segments were skipped, from the gyro report's segments_skipped counts."""
    why = {"too_long": f"longer than {stats.get('max_segment_s', 30):g} s", "gap": "a gap in the time stamps",
           "missing_samples": "missing gyro samples", "no_direction": "no gravity direction at a rest",
           "small_rotation": "turned less than 10°", "outliers": "inconsistent with the others"}
    counts = {k: v for k, v in (stats.get("segments_skipped") or {}).items() if v}
    return ", ".join(f"{n} {why.get(k, k)}" for k, n in counts.items()) or "only one rest"


def _model_labels(stats: dict) -> list[str]:
    """The labels of a self-calibrated triad's bias, gain and cross-axis parameters (no temperature
    terms; the gyro without any fit: its nine gain and cross-axis entries)."""
    params = stats.get("parameters")
    if params is None:
        return list(stats.get("held") or [])
    return [p["label"] for p in params if "Tn^" not in p["label"]]


def _gap(triad: str, model_enabled: bool, stats: dict, notes: list[str]) -> Gap | None:
    """The gap of one recorded triad, or None when it is fully calibrated."""
    if not model_enabled:
        loud = [n.split(": ", 1)[1] for n in notes if n.startswith(f"{triad}: NOT EXPORTED")]
        reason = loud[0] if loud else next((n.split(": ", 1)[1] for n in notes if n.startswith(f"{triad}:")),
                                           "nothing could be fitted")
        return Gap(triad, "uncalibrated", "exported as the identity (raw readings pass through)", reason,
                   ADVICE["mag" if triad == "mag" else "acc" if triad == "acc" else "gyr cross"])
    if stats.get("reference", "none") != "none":
        if stats.get("bias_only"):
            return Gap(triad, "partly calibrated", "gains and cross-axis terms not fitted (bias only)",
                       "the reference hardly moves along every axis" if stats.get("weakest_excitation") is not None
                       else "the gain/bias fit lost to the raw sensor on held-out data", ADVICE["reference"])
        return None
    return _selfcal_gap(triad, stats)


def calibration_gaps(thermal: dict, fit_stats: dict, notes: list[str], recorded: set[str]) -> list[Gap]:
    """Every recorded triad (`recorded`: triads with a finite sample in some recording) that is not fully
    calibrated, in TRIAD_ORDER."""
    return [gap for triad in TRIAD_ORDER if triad in recorded
            and (gap := _gap(triad, thermal[triad].enabled, fit_stats.get(triad, {}), notes)) is not None]


def recorded_triads(datasets) -> set[str]:
    """Triads with at least one finite sample in some recording."""
    return {t for t in TRIAD_ORDER if any(d.has(t) for d in datasets)}
