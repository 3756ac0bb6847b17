"""Which reference calibrates each triad: reference columns, an attitude reference, a static log, or none.

A user's calibration recordings carry whatever they could measure. Per triad, `train` takes the
best source that any recording offers, in this order (SOURCES):

- ``columns``  — the recording has ``ref_gyr_*`` / ``ref_acc_*`` / ``ref_mag_*`` (rate table, simulator);
- ``attitude`` — the recording has ``ref_q`` (sidecar ``"reference"``: ``optical`` motion capture,
  ``robot`` kinematics, ``gnss-ins``): rate, field and, with ``aux_pos_*``, specific-force references are
  derived by `training.data.reference.derive_references`, the same code path that `imufmu diagnose`
  uses; the field only when the earth field in the reference's frame is known
  (`training.data.reference_field`: a frame turned by an unknown angle has it estimated from the
  magnetometer, or gets no field reference);
- ``static``   — the sidecar says ``"reference": "static"``: the true rate is zero; gravity and field
  are constant in the body, so only the temperature drift of their biases is identifiable — used for
  the accelerometer and magnetometer only when every recording is static (a recording with motion
  identifies far more of them by self-calibration);
- ``none``     — self-calibration from invariants (`training.selfcal`).

Only the recordings that provide the chosen source are used for that triad's reference fit.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from training.data.dataset import TRIADS, ImuData
from training.data.reference import derive_references

SOURCES = ("columns", "attitude", "static", "none")
#: What each source means, for the printed summary and calibration.md.
SOURCE_TEXT = {"columns": "reference columns in the recording",
               "attitude": "derived from the attitude reference ref_q",
               "static": "static log (true rate zero; gravity and field constant in the body)",
               "none": "no reference: self-calibration from invariants"}


@dataclass(frozen=True)
class TriadReference:
    """The reference chosen for one triad: `source` (one of SOURCES), the recordings that carry it
    (ref_<triad> filled, in the triad's unit) and what was derived, as notes."""

    triad: str
    source: str
    datasets: tuple[ImuData, ...]
    notes: tuple[str, ...] = ()


def strip_references(data: ImuData) -> ImuData:
    """The recording as a user without any reference has it: no ref_* columns, no eval mask,
    sidecar reference 'none'."""
    meta = {**data.meta, "reference": "none"}
    return replace(data, ref_q=None, ref_gyr=None, ref_acc=None, ref_mag=None, eval_mask=None, meta=meta)


def is_static(data: ImuData) -> bool:
    """True when the sidecar declares the recording static ("reference": "static")."""
    return str(data.meta.get("reference", "")).lower() == "static"


def _static_reference(data: ImuData, triad: str) -> np.ndarray | None:
    """The reference of `triad` in a static log: zero rate for the gyro; for acc and mag the
    recording's mean (constant in the body), so that only the bias's temperature drift is fitted."""
    raw = getattr(data, triad)
    finite = np.all(np.isfinite(raw), axis=1)
    if not finite.any():
        return None
    ref = np.zeros_like(raw) if triad == "gyr" else np.tile(raw[finite].mean(axis=0), (len(data), 1))
    ref[~finite] = np.nan
    return ref


def _with_reference(data: ImuData, triad: str, static_only: bool) -> tuple[ImuData | None, str | None, list[str]]:
    """(data with ref_<triad> filled, its source, notes) or (None, None, []) when the recording
    offers no reference for the triad; static_only: every recording of the set is static."""
    name = f"ref_{triad}"
    if getattr(data, name) is not None and np.isfinite(getattr(data, name)).any():
        return data, "columns", []
    if data.ref_q is not None:
        derived, notes = derive_references(data)
        if getattr(derived, name) is not None and np.isfinite(getattr(derived, name)).any():
            return derived, "attitude", [f"{data.name}: {n}" for n in notes if n.startswith(name)]
    if is_static(data) and (triad == "gyr" or static_only):
        ref = _static_reference(data, triad)
        if ref is not None:
            return replace(data, **{name: ref}), "static", []
    return None, None, []


def choose_reference(datasets: list[ImuData], triad: str) -> TriadReference:
    """The best reference source for `triad` over the recordings (SOURCES order) and the recordings
    that carry it; source 'none' with every recording when none carries a reference."""
    if triad not in TRIADS:
        raise ValueError(f"unknown triad '{triad}' (known: {', '.join(TRIADS)})")
    offered: dict[str, list[ImuData]] = {s: [] for s in SOURCES}
    notes: dict[str, list[str]] = {s: [] for s in SOURCES}
    static_only = all(is_static(d) for d in datasets)
    for data in datasets:
        with_ref, source, derived = _with_reference(data, triad, static_only)
        if source is not None:
            offered[source].append(with_ref)
            notes[source] += derived
    for source in SOURCES[:-1]:
        if offered[source]:
            return TriadReference(triad, source, tuple(offered[source]), tuple(notes[source]))
    return TriadReference(triad, "none", tuple(datasets))
