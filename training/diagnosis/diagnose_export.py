"""Carrying a diagnosed effect into the artefact: bounded correction terms, a time shift, aux inputs.

- Every column of a 'terms' family becomes one term per (component, a, b); equal terms of one
  effect are merged. Each term's regressor s[a]·s[b] is clamped by the runtime to the range it had
  on the rows it was fitted on (lo, hi in the artefact), so no added term can drift outside the data
  (a `time` term holds its last fitted value after the fitted span: said in the notes).
- The per-component offset refitted with the effect becomes a constant term ('one') of the target
  triad, merged with an earlier one: the thermal model is never touched, so the signals the terms
  see in the runtime (the compensated triads before the terms) are exactly those of the fit.
- The linear calibration refitted with the effect (training.diagnosis.candidates.linear_refit)
  becomes terms of the target triad on its own components, merged with those of an earlier refit
  (their clamp ranges joined): the FMU gets the joint fit the diagnosis measured.
- A time-shift family sets the runtime's lag_<triad> [s] (sources/ImuAlign.h).
- An `aux_*` recording column gets the next free auxiliary FMU input (aux_1 … aux_4).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from contract.layout import INPUTS, TERMS_MAX
from training.artefact import ModelArtefact
from training.diagnosis.diagnose_fit import Fit, Residuals

AXES = ("x", "y", "z")
AUX_SLOTS = tuple(n for n in INPUTS if n.startswith("aux_"))


def aux_slots_needed(fit_or_candidates, artefact: ModelArtefact) -> list[str]:
    """Recording aux columns the candidates use that have no FMU input yet."""
    cands = getattr(fit_or_candidates, "candidates", fit_or_candidates)
    mapped = {a["column"] for a in artefact.aux_inputs}
    return sorted({s for c in cands for s in c.signals() if s.startswith("aux_") and s not in mapped})


def _aux_inputs(artefact: ModelArtefact, columns: list[str], aux_info: dict[str, dict]) -> list[dict]:
    """The artefact's aux input map with `columns` appended, unit and meaning from the sidecars'
    optional "aux" entries (ValueError when the slots run out)."""
    out = [dict(a) for a in artefact.aux_inputs]
    for column in columns:
        if len(out) == len(AUX_SLOTS):
            raise ValueError(f"no free auxiliary input for {column} (the FMU has {len(AUX_SLOTS)})")
        info = aux_info.get(column, {})
        out.append({"column": column, "unit": info.get("unit", ""), "meaning": info.get("meaning", "")})
    return out


def _slot(name: str | None, aux_inputs: list[dict]) -> str | None:
    """A recording aux column's FMU input name (other signals pass through)."""
    if name is None or not name.startswith("aux_"):
        return name
    return AUX_SLOTS[[a["column"] for a in aux_inputs].index(name)]


def _range(r: Residuals, a: str, b: str | None) -> tuple[float, float]:
    """(lo, hi) of s[a]·s[b] over the rows of the training blocks."""
    v = r.signals[a][r.fitted] * (1.0 if b is None else r.signals[b][r.fitted])
    v = v[np.isfinite(v)]
    return (float(v.min()), float(v.max())) if v.size else (0.0, 0.0)


def _column_terms(triad: str, pairs) -> dict[tuple[str, str, str | None], float]:
    """(component, a, b) -> coefficient of the term columns of (candidate, coefficients) pairs, merged."""
    terms: dict[tuple[str, str, str | None], float] = {}
    for candidate, coef in pairs:
        if candidate.kind != "terms":
            continue
        for column, beta in zip(candidate.columns, coef):
            for c, a, b, w in column:
                key = (f"{triad}_{AXES[c]}", a, b)
                terms[key] = terms.get(key, 0.0) + float(beta) * w
    return terms


def effect_terms(fit: Fit, r: Residuals) -> dict[tuple[str, str, str | None], float]:
    """(component, a, b) -> coefficient of every term column of the fit's families, merged."""
    return _column_terms(fit.target.split("_")[0], zip(fit.candidates, fit.coefficients()))


def refit_terms(fit: Fit) -> dict[tuple[str, str, str | None], float]:
    """(component, a, b) -> coefficient of the fit's linear refit (empty without one)."""
    if fit.refit is None:
        return {}
    return _column_terms(fit.target.split("_")[0], [(fit.refit, fit.refit_coefficients)])


def _refit_name(triad: str) -> str:
    return f"diagnose: {triad} linear calibration refit"


def term_count(fit: Fit, r: Residuals, artefact: ModelArtefact) -> int:
    """Terms of the artefact once the fit is added (offset and linear-refit terms merge with earlier ones)."""
    triad = fit.target.split("_")[0]
    have_one = {t["target"] for t in artefact.terms if t["a"] == "one"}
    new_one = sum(f"{triad}_{a}" not in have_one for a in AXES)
    have_refit = {(t["target"], t["a"], t["b"]) for t in artefact.terms if t["name"] == _refit_name(triad)}
    new_refit = sum(key not in have_refit for key in refit_terms(fit))
    return len(artefact.terms) + len(effect_terms(fit, r)) + new_one + new_refit


def _merged_refit(terms: list[dict], triad: str, fit: Fit, r: Residuals) -> list[dict]:
    """`terms` with the fit's linear refit added to the earlier refit terms of the triad (clamp ranges
    joined) or appended."""
    out = [dict(t) for t in terms]
    for (target, a, b), value in refit_terms(fit).items():
        lo, hi = _range(r, a, b)
        for t in out:
            if t["name"] == _refit_name(triad) and (t["target"], t["a"], t["b"]) == (target, a, b):
                t["coefficient"] += value
                t["lo"], t["hi"] = min(t["lo"], lo), max(t["hi"], hi)
                break
        else:
            out.append({"name": _refit_name(triad), "target": target, "a": a, "b": b, "coefficient": value,
                        "lo": lo, "hi": hi})
    return out


def refit_summary(fit: Fit) -> dict:
    """How far the joint refit moved the triad's gain matrix (rows: output component, columns: own
    component, in 1 = 100 %); {} without a refit."""
    terms = refit_terms(fit)
    if not terms:
        return {}
    triad = fit.target.split("_")[0]
    gain = [[terms.get((f"{triad}_{o}", f"{triad}_{i}", None), 0.0) for i in AXES] for o in AXES]
    return {"gain_change": gain}


def refit_note(fit: Fit) -> str:
    """One line: how far the joint refit moved the gain matrix, and why."""
    summary = refit_summary(fit)
    if not summary:
        return ""
    gain = np.asarray(summary["gain_change"])
    return (f"gain matrix refitted jointly with the effect (an effect also present in the calibration recording "
            f"bends the gain `train` fitted by its part linear in the signal): diagonal changed by "
            f"{np.round(100.0 * np.diag(gain), 3).tolist()} %, largest cross-axis change "
            f"{100.0 * float(np.max(np.abs(gain - np.diag(np.diag(gain))))):.3g} %")


def _offset_terms(terms: list[dict], triad: str, offset: np.ndarray, name: str) -> list[dict]:
    """`terms` with the offset (3,) added to the constant term of each component of the triad."""
    out = [dict(t) for t in terms]
    for c, value in enumerate(offset):
        target = f"{triad}_{AXES[c]}"
        for t in out:
            if t["target"] == target and t["a"] == "one":
                t["coefficient"] += float(value)
                break
        else:
            out.append({"name": name, "target": target, "a": "one", "b": None, "coefficient": float(value),
                        "lo": 1.0, "hi": 1.0})
    return out


def add_effect(artefact: ModelArtefact, fit: Fit, r: Residuals, label: str,
               aux_info: dict[str, dict] | None = None) -> ModelArtefact:
    """A new artefact carrying the fit: terms (bounded), offset, lag setting, aux inputs, notes."""
    triad = fit.target.split("_")[0]
    name = f"diagnose: {label} -> {fit.target}"
    aux_inputs = _aux_inputs(artefact, aux_slots_needed(fit, artefact), aux_info or {})
    new = [{"name": name, "target": target, "a": _slot(a, aux_inputs), "b": _slot(b, aux_inputs),
            "coefficient": value, **dict(zip(("lo", "hi"), _range(r, a, b)))}
           for (target, a, b), value in effect_terms(fit, r).items()]
    terms = _merged_refit(_offset_terms(artefact.terms, triad, fit.offset, f"diagnose: {triad} offset"), triad, fit, r) + new
    if len(terms) > TERMS_MAX:
        raise ValueError(f"{len(terms)} correction terms, at most {TERMS_MAX} fit in the runtime")
    settings = dict(artefact.settings)
    notes = list(artefact.notes) + [f"{name}: {len(new)} terms, each regressor clamped to its fitted range; "
                                    f"{triad} offset refitted by {np.round(fit.offset, 6).tolist()}"] + \
        ([f"{name}: {refit_note(fit)}"] if fit.refit is not None else [])
    for candidate, coef in zip(fit.candidates, fit.coefficients()):
        if candidate.kind == "lag":
            settings[f"lag_{triad}"] = settings.get(f"lag_{triad}", 0.0) - float(coef[0])
            notes.append(f"{name}: lag_{triad} = {settings[f'lag_{triad}']:.6g} s")
        if any(a == "time" for column in candidate.columns for _, a, _, _ in column):
            notes.append(f"{name}: the time term is clamped to the fitted span; after it, it holds its end value")
    return replace(artefact, terms=terms, settings=settings, notes=notes, aux_inputs=aux_inputs)

