"""Held-out error of a calibration: refit on the first part of each recording, score the rest.

`train` reports, per triad, the error of the raw sensor and of a calibration fitted WITHOUT the last
HOLDOUT_FRACTION (in time) of every recording, on that last part: against the reference where the
triad has one, else against the invariants the self-calibration uses (true rate zero at rest,
|specific force| = g at rest, |field| = the field norm). The model written is fitted on everything;
this says how well the procedure carries over to data it did not see.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from training.data.dataset import ImuData
from training.data.reference_source import TriadReference
from training.models.thermal import ThermalModel, apply_thermal

#: Share of each recording (its end, in time) held out: a contiguous block, because neighbouring
#: samples repeat one another; a quarter still leaves three quarters of the poses to fit on.
HOLDOUT_FRACTION = 0.25
UNITS = {"gyr": "rad/s", "acc": "m/s²", "mag": "µT"}


def split(data: ImuData) -> tuple[ImuData, ImuData]:
    """(first 1 − HOLDOUT_FRACTION, last HOLDOUT_FRACTION) of a recording, by time."""
    cut = int(np.searchsorted(data.t, data.t[0] + (1.0 - HOLDOUT_FRACTION) * (data.t[-1] - data.t[0])))
    return data.slice(slice(0, cut)), data.slice(slice(cut, None))


def _rms(x: np.ndarray) -> float | None:
    """RMS over the finite entries, None when there are none."""
    x = np.asarray(x, dtype=np.float64)
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x ** 2))) if x.size else None


def reference_error(model: ThermalModel, tails: list[ImuData], triad: str) -> dict:
    """{'metric', 'before', 'after'}: RMS of raw − reference and calibrated − reference [unit] over the
    held-out tails (the tails carry ref_<triad>)."""
    raw = np.concatenate([getattr(d, triad) for d in tails])
    temp = np.concatenate([d.temp for d in tails])
    ref = np.concatenate([getattr(d, f"ref_{triad}") for d in tails])
    return {"metric": f"error against the reference RMS [{UNITS[triad]}]", "before": _rms(raw - ref),
            "after": _rms(apply_thermal(model, raw, temp) - ref)}


def _rest_means(d: ImuData, triad: str, model: ThermalModel) -> tuple[np.ndarray, np.ndarray]:
    """(raw, calibrated) means (K, 3) of `triad` over the rest windows of d (none: (0, 3) arrays)."""
    from training.selfcal.rest import detect_rest
    try:
        windows = detect_rest(d).windows
    except ValueError:
        windows = ()
    raw = np.array([getattr(w, triad) for w in windows]).reshape(-1, 3)
    return raw, apply_thermal(model, raw, np.array([w.temp for w in windows], dtype=float))


def invariant_error(model: ThermalModel, tails: list[ImuData], triad: str, field_norm: float | None,
                    gravity: float) -> dict:
    """{'metric', 'before', 'after'} of the invariant of `triad` over the held-out tails: the mean
    rate of each rest window [rad/s] (true rate zero), |mean specific force| − g of each rest window
    [m/s²], |h| − field_norm over every sample [µT]."""
    metric = {"gyr": "mean rate of the rest windows RMS [rad/s]",
              "acc": "|specific force| − g of the rest windows RMS [m/s²]",
              "mag": "|field| − field norm RMS [µT]"}[triad]
    if triad == "mag" and field_norm is None:
        return {"metric": metric, "before": None, "after": None}
    values = {"before": [], "after": []}
    for d in tails:
        if triad == "mag":
            pairs = (getattr(d, triad), apply_thermal(model, d.mag, d.temp))
        else:
            pairs = _rest_means(d, triad, model)
        for key, x in zip(("before", "after"), pairs):
            if triad == "gyr":
                values[key].append(x.ravel())
            else:
                values[key].append(np.linalg.norm(x, axis=1) - (field_norm if triad == "mag" else gravity))
    return {"metric": metric, **{k: _rms(np.concatenate(v)) if v else None for k, v in values.items()}}


def held_out(datasets: list[ImuData], refs: dict[str, TriadReference], fit_reference, fit_selfcal,
             field_norm: float | None, gravity: float, step=lambda: None) -> dict[str, dict]:
    """Per triad {'holdout', 'metric', 'before', 'after'} on the last HOLDOUT_FRACTION of every
    recording, for a calibration fitted on the rest. fit_reference(TriadReference) -> ThermalModel
    refits a referenced triad; fit_selfcal(list[ImuData]) -> {triad: ThermalModel} self-calibrates;
    step() is called after the self-calibration (if any) and after each triad (len(refs) + 1 calls)."""
    out = {}
    blind = [t for t, r in refs.items() if r.source == "none"]
    heads_tails = [split(d) for d in datasets]
    selfcal = fit_selfcal([h for h, _ in heads_tails]) if blind else {}
    step()
    for triad, ref in refs.items():
        if ref.source == "none":
            score = invariant_error(selfcal[triad], [t for _, t in heads_tails], triad, field_norm, gravity)
        else:
            parts = [split(d) for d in ref.datasets]
            model = fit_reference(replace(ref, datasets=tuple(h for h, _ in parts)))
            score = reference_error(model, [t for _, t in parts], triad)
        out[triad] = {"holdout": f"last {HOLDOUT_FRACTION:.0%} of each recording, calibration fitted on the rest",
                      **score}
        step()
    return out
