"""Carrying a diagnosed effect into the artefact: bounded correction terms, a time shift, aux inputs.

- Every column of a 'terms' family becomes one term per (component, a, b); equal terms of one
  effect are merged. Each term's regressor s[a]·s[b] is clamped by the runtime to the range it had
  on the rows it was fitted on (lo, hi in the artefact), so no added term can drift outside the data
  (a `time` term holds its last fitted value after the fitted span: said in the notes).
- The per-component offset refitted with the effect becomes a constant term ('one') of the target
  triad, merged with an earlier one: the thermal model is never touched, so the signals the terms
  see in the runtime (the compensated triads before the terms) are exactly those of the fit.
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


def effect_terms(fit: Fit, r: Residuals) -> dict[tuple[str, str, str | None], float]:
    """(component, a, b) -> coefficient of every term column of the fit, merged."""
    triad = fit.target.split("_")[0]
    terms: dict[tuple[str, str, str | None], float] = {}
    for candidate, coef in zip(fit.candidates, fit.coefficients()):
        if candidate.kind != "terms":
            continue
        for column, beta in zip(candidate.columns, coef):
            for c, a, b, w in column:
                key = (f"{triad}_{AXES[c]}", a, b)
                terms[key] = terms.get(key, 0.0) + float(beta) * w
    return terms


def term_count(fit: Fit, r: Residuals, artefact: ModelArtefact) -> int:
    """Terms of the artefact once the fit is added (offset terms merge with earlier ones)."""
    triad = fit.target.split("_")[0]
    have_one = {t["target"] for t in artefact.terms if t["a"] == "one"}
    new_one = sum(f"{triad}_{a}" not in have_one for a in AXES)
    return len(artefact.terms) + len(effect_terms(fit, r)) + new_one


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
    terms = _offset_terms(artefact.terms, triad, fit.offset, f"diagnose: {triad} offset") + new
    if len(terms) > TERMS_MAX:
        raise ValueError(f"{len(terms)} correction terms, at most {TERMS_MAX} fit in the runtime")
    settings = dict(artefact.settings)
    notes = list(artefact.notes) + [f"{name}: {len(new)} terms, each regressor clamped to its fitted range; "
                                    f"{triad} offset refitted by {np.round(fit.offset, 6).tolist()}"]
    for candidate, coef in zip(fit.candidates, fit.coefficients()):
        if candidate.kind == "lag":
            settings[f"lag_{triad}"] = settings.get(f"lag_{triad}", 0.0) - float(coef[0])
            notes.append(f"{name}: lag_{triad} = {settings[f'lag_{triad}']:.6g} s")
        if any(a == "time" for column in candidate.columns for _, a, _, _ in column):
            notes.append(f"{name}: the time term is clamped to the fitted span; after it, it holds its end value")
    return replace(artefact, terms=terms, settings=settings, notes=notes, aux_inputs=aux_inputs)

