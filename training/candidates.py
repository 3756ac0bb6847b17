"""The candidate library of `imufmu diagnose`: generic effects built from the signals a recording has.

A candidate is a target (a residual: a triad against its reference, or a norm invariant) and a
group of regressors. Each regressor is a product s[a]·s[b] of signals (b may be None): the
correction-term vocabulary training.layout.TERM_SIGNALS (what the FMU can carry) or an `aux_*`
column (what it cannot). The groups are not a list of known answers but every family of the
issue: temperature, its rate, time, each triad linear (specific force, angular rate, field), its
squares and pairwise products, its time derivative (a time shift / lag between sensors), and each
aux column alone and together. A group is fitted per target component with one coefficient per
regressor (plus a per-component offset), so it becomes 3·k terms of the artefact.

Regressors from the target's own triad are not offered: the runtime forms them from the
compensated output that the added terms and the refitted offset change (so a fit of them does not
carry over to the runtime; e.g. mag_x² moves by 2·c·mag_x when the offset moves by c), their
backward differences share the target's white noise, and at rest they are a mere proxy of the
target's own drift.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .layout import TERM_SIGNALS

TRIAD_NAMES = {"gyr": "angular rate", "acc": "specific force", "mag": "field"}
AXES = ("x", "y", "z")
#: A regressor counts as present when it is finite on at least this share of the rows.
MIN_FINITE_SHARE = 0.9


@dataclass(frozen=True)
class Candidate:
    """One candidate effect: `regressors` are (a, b | None) signal-name pairs."""

    name: str
    target: str
    regressors: tuple[tuple[str, str | None], ...]

    @property
    def carriable(self) -> bool:
        """True when every regressor is in the FMU's term vocabulary (no aux_* column)."""
        return all(a in TERM_SIGNALS and (b is None or b in TERM_SIGNALS) for a, b in self.regressors)

    def labels(self) -> list[str]:
        """Regressors as text: 'acc_x' or 'gyr_x*gyr_y'."""
        return [a if b is None else f"{a}*{b}" for a, b in self.regressors]


def _triad(prefix: str) -> list[str]:
    return [f"{prefix}_{a}" for a in AXES]


def _groups(signals: dict[str, np.ndarray]) -> list[tuple[str, list[tuple[str, str | None]]]]:
    """(name, regressors) of every family whose signals are present."""
    groups: list[tuple[str, list[tuple[str, str | None]]]] = [
        ("temperature", [("temp", None)]), ("temperature squared", [("temp", "temp")]),
        ("temperature rate", [("temp_rate", None)]), ("time", [("time", None)])]
    for triad, label in TRIAD_NAMES.items():
        s = _triad(triad)
        groups += [(label, [(c, None) for c in s]),
                   (f"{label} squared", [(c, c) for c in s]),
                   (f"{label} pairwise products", [(s[0], s[1]), (s[0], s[2]), (s[1], s[2])]),
                   (f"{label} time derivative (lag)", [(f"d_{c}", None) for c in s])]
    aux = sorted(k for k in signals if k.startswith("aux_"))
    groups += [(name, [(name, None)]) for name in aux]
    if len(aux) > 1:
        groups.append(("all aux columns", [(name, None) for name in aux]))
    return groups


def _present(signals: dict[str, np.ndarray], name: str) -> bool:
    """Signal exists, is mostly finite and varies."""
    v = signals.get(name)
    if v is None:
        return False
    ok = np.isfinite(v)
    return ok.mean() >= MIN_FINITE_SHARE and float(np.ptp(v[ok])) > 0.0


def build_candidates(signals: dict[str, np.ndarray], targets: list[str]) -> list[Candidate]:
    """Every candidate (target × family) whose regressors are present in `signals` (name -> (N,))."""
    out = []
    for target in targets:
        for name, regs in _groups(signals):
            triad = target.split("_")[0]
            if any(x is not None and x.removeprefix("d_").startswith(f"{triad}_") for reg in regs for x in reg):
                continue   # the target's own triad: see the module docstring
            if all(_present(signals, a) and (b is None or _present(signals, b)) for a, b in regs):
                out.append(Candidate(name, target, tuple(regs)))
    return out


def regressor_matrix(candidate: Candidate, signals: dict[str, np.ndarray], rows: np.ndarray) -> np.ndarray:
    """(len(rows), k) columns s[a]·s[b] of the candidate's regressors at `rows`."""
    cols = [signals[a][rows] * (1.0 if b is None else signals[b][rows]) for a, b in candidate.regressors]
    return np.column_stack(cols)
