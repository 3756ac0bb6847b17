"""The candidate library of `imufmu diagnose`: generic effects built from the signals a recording has.

A candidate is a target (a residual: a triad against its reference, or a norm invariant) and a
*family* of columns. A column is a vector effect on the target triad with one unknown coefficient:
a sum of weighted products w·s[a]·s[b] per target component (b may be None). Free families have one
column per (component, regressor), so every component gets its own coefficient; structured families
share a coefficient across components where physics says so (a lever arm r has three unknowns, not
27; a time shift has one). Every fitted column becomes correction terms of the artefact (a term per
(component, a, b)), except a time shift, which becomes the runtime's `lag_<triad>` setting.

The families are not a list of known answers but every family of the issue, built for each target
from whatever signals are present:

- temperature, its square, its rate low-passed over 10 s and over 1 s, time (last resort, see
  training.diagnosis.diagnose);
- each *other* triad: linear, squared, signed square (x·|x|), pairwise products, time derivative;
- the target's *own* triad: squared, signed square, cross-axis products (its linear part is the
  thermal model's gain matrix). The runtime forms these from the compensated signal before the
  correction terms (sources/ImuTerms.h), exactly what the fit sees. They share the target's noise,
  so they are fitted with instruments (training.diagnosis.diagnose_fit);
- the target's own time shift (a lag against the reference), when the target has a reference: its
  column is the difference over the whole-sample shift scanned up to ±0.5 s, or the central difference
  when the scan finds none (training.diagnosis.time_shift);
- a lever arm of the accelerometer, ω̇×r + ω×(ω×r);
- every `aux_*` column alone (except the reference's `aux_pos_*`); several join one effect only by
  forward selection, each column on its own held-out merit (a family of all columns together took a
  decoy column along: a supply-voltage gyro bias beside an irrelevant fan-speed column, 53 % lower).

Every family of a target with a reference is fitted jointly with the triad's linear calibration
(`linear_refit`: the gain matrix, beside the offset): an effect that
was also in the calibration recording bent the linear fit `train` made (a rate nonlinearity k·ω·|ω|
fitted by a gain alone shifts the gain by k times the calibration's mean |ω|), so the family alone
would read that bent remainder; refitted together, it reads the effect itself.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

TRIAD_NAMES = {"gyr": "angular rate", "acc": "specific force", "mag": "field"}
AXES = ("x", "y", "z")
#: A signal counts as present when it is finite on at least this share of the rows.
MIN_FINITE_SHARE = 0.9
#: Samples each side of the current one left out of an instrument, and samples averaged beyond
#: them: the instrument of a signal at sample k is the mean over k−HOLE−SPAN..k−HOLE−1 and
#: k+HOLE+1..k+HOLE+SPAN. A sensor's white noise, or noise coloured by its low-pass filter over up
#: to HOLE samples, at k is then independent of the instrument, while the motion (≤ a few Hz at
#: ≥ 50 Hz) is not.
INSTRUMENT_HOLE = 2
INSTRUMENT_SPAN = 4
#: Aux columns that belong to the reference, not to the sensor's surroundings: the optical
#: marker position that comes with ref_q (shared/ARCHITECTURE.md). A system simulation has no such
#: input, so they are never candidates.
REFERENCE_AUX = "aux_pos_"
#: Half-width [samples] of the central difference behind the time-shift column (it leaves out the
#: current sample, whose noise the target shares).
SHIFT_HALF_WIDTH = 2

#: One column: ((component 0..2 of the target triad, signal a, signal b | None, weight), ...).
Column = tuple[tuple[int, str, str | None, float], ...]


@dataclass(frozen=True)
class Candidate:
    """One candidate family on one target: `columns` each carry one unknown coefficient.

    kind: 'terms' (exported as correction terms) or 'lag' (one column, exported as the time shift
    of the target triad); own: uses the target's own triad (fitted with instruments)."""

    name: str
    target: str
    columns: tuple[Column, ...]
    kind: str = "terms"
    own: bool = False

    @property
    def triad(self) -> str:
        return self.target.split("_")[0]

    def labels(self) -> list[str]:
        """Distinct regressors as text, in order: 'acc_x', 'gyr_x*gyr_y'."""
        out = []
        for column in self.columns:
            for _, a, b, _ in column:
                label = a if b is None else f"{a}*{b}"
                if label not in out:
                    out.append(label)
        return out

    def signals(self) -> set[str]:
        return {x for column in self.columns for _, a, b, _ in column for x in (a, b) if x is not None}


def triad_signals(prefix: str) -> list[str]:
    return [f"{prefix}_{a}" for a in AXES]


def _free(regressors: list[tuple[str, str | None]]) -> tuple[Column, ...]:
    """One column per (component, regressor): every component its own coefficient."""
    return tuple(((c, a, b, 1.0),) for c in range(3) for a, b in regressors)


def _triad_families(source: str, own: bool) -> list[tuple[str, list[tuple[str, str | None]]]]:
    """(name, regressors) of the free families of one source triad."""
    s, label = triad_signals(source), TRIAD_NAMES[source]
    families = [(f"{label} squared", [(c, c) for c in s]),
                (f"{label} signed square", [(c, f"abs_{c}") for c in s]),
                (f"{label} pairwise products", [(s[0], s[1]), (s[0], s[2]), (s[1], s[2])])]
    if not own:
        families = [(label, [(c, None) for c in s])] + families + [
            (f"{label} time derivative", [(f"d_{c}", None) for c in s])]
    return families


def lever_arm_columns() -> tuple[Column, ...]:
    """Columns of r_x, r_y, r_z in ω̇×r + ω×(ω×r) (specific force of a point at r from the centre
    of rotation), with ω̇ the runtime's backward difference d_gyr and ω the compensated rate:
    ω×(ω×r) = ω(ω·r) − r|ω|²."""
    w, d = triad_signals("gyr"), [f"d_gyr_{a}" for a in AXES]
    columns = []
    for j in range(3):
        col = []
        for i in range(3):
            k = 3 - i - j
            if i == j:
                col += [(i, w[m], w[m], -1.0) for m in range(3) if m != i]
            else:
                sign = 1.0 if (i, j) in ((0, 1), (1, 2), (2, 0)) else -1.0   # (ω̇×r)_i = ε_ikj ω̇_k r_j
                col += [(i, w[i], w[j], 1.0), (i, d[k], None, -sign)]
        columns.append(tuple(col))
    return tuple(columns)


def time_shift_column(triad: str) -> tuple[Column, ...]:
    """The one column of a time shift: the central difference of the triad (x(t) − x(t − τ) ≈ τ·ẋ)."""
    return (tuple((c, f"dc_{triad}_{a}", None, 1.0) for c, a in enumerate(AXES)),)


#: The families of `train`'s bias model B(T) (a polynomial of degree ≤ 2 in the temperature): an effect in the
#: calibration recording bends them together, so forward selection also tries them as one step
#: (training.diagnosis.diagnose._grow): one at a time, neither lowers the held-out error enough.
BIAS_MODEL = ("temperature", "temperature squared")


def _families(target: str, signals: dict[str, np.ndarray]) -> list[Candidate]:
    """Every family for one target (before the presence check)."""
    triad, has_reference = target.split("_")[0], not target.endswith("_norm")
    out = [Candidate(n, target, _free(r)) for n, r in (
        (BIAS_MODEL[0], [("temp", None)]), (BIAS_MODEL[1], [("temp", "temp")]),
        ("temperature rate", [("temp_rate", None)]), ("temperature rate (1 s)", [("temp_rate_fast", None)]),
        ("time", [("time", None)]))]
    for source in TRIAD_NAMES:
        own = source == triad
        out += [Candidate(n, target, _free(r), own=own) for n, r in _triad_families(source, own)]
    if has_reference:
        out.append(Candidate(f"{TRIAD_NAMES[triad]} time shift", target, time_shift_column(triad), kind="lag"))
    if triad == "acc":
        out.append(Candidate("lever arm", target, lever_arm_columns()))
    aux = sorted(k for k in signals if k.startswith("aux_") and not k.startswith(REFERENCE_AUX))
    out += [Candidate(name, target, _free([(name, None)])) for name in aux]
    return out


#: Name of the linear calibration refitted with every family (linear_refit).
LINEAR_REFIT = "linear calibration"


def linear_refit(target: str, signals: dict[str, np.ndarray]) -> Candidate | None:
    """The linear calibration refitted with every family of a target: a column per (component, own
    component), the gain matrix's change; for a norm target the symmetric part only, a column per pair of
    components (a norm is blind to a rotation: |(I + W)·x| = |x| to first order for W skew), which the
    directions must determine (training.diagnosis.diagnose_fit.excitation). None when the triad's signals are
    missing. The bias's temperature terms are not in it: they are the families "temperature" and
    "temperature squared", selected or grown like any other, so that a bias(T) the calibration lacks is
    reported as an effect. (In the refit they also read an effect linear in the temperature rate against a
    temperature ramp: a gyro bias of 0.05 (°/s)/(°C/min) in the calibration and the test recording read 0.012.)"""
    triad = target.split("_")[0]
    names = triad_signals(triad)
    if not all(_present(signals, s) for s in names):
        return None
    if target.endswith("_norm"):
        return Candidate(LINEAR_REFIT, target, _symmetric(names), own=True)
    return Candidate(LINEAR_REFIT, target, _free([(s, None) for s in names]), own=True)


def _symmetric(names: list[str]) -> tuple[Column, ...]:
    """One column per pair i <= j of a symmetric matrix change: component i from signal j and j from i."""
    return tuple(((i, names[j], None, 1.0),) if i == j else ((i, names[j], None, 1.0), (j, names[i], None, 1.0))
                 for i in range(3) for j in range(i, 3))


def _present(signals: dict[str, np.ndarray], name: str) -> bool:
    """Signal exists, is mostly finite and varies."""
    v = signals.get(name)
    if v is None:
        return False
    ok = np.isfinite(v)
    return ok.mean() >= MIN_FINITE_SHARE and float(np.ptp(v[ok])) > 0.0


def build_candidates(signals: dict[str, np.ndarray], targets: list[str]) -> list[Candidate]:
    """Every candidate (target × family) whose signals are present in `signals` (name -> (N,))."""
    return [c for target in targets for c in _families(target, signals)
            if all(_present(signals, s) for s in c.signals())]


def column_effects(candidate: Candidate, signals: dict[str, np.ndarray], rows: np.ndarray) -> np.ndarray:
    """(len(rows), J, 3) effect of every column (coefficient 1) on the target triad at `rows`."""
    out = np.zeros((int(np.count_nonzero(rows)) if rows.dtype == bool else len(rows), len(candidate.columns), 3))
    for j, column in enumerate(candidate.columns):
        for c, a, b, w in column:
            out[:, j, c] += w * signals[a][rows] * (1.0 if b is None else signals[b][rows])
    return out


def instrument_signals(signals: dict[str, np.ndarray], triad: str, starts: np.ndarray) -> dict[str, np.ndarray]:
    """`signals` with the triad's components (and their absolute values) replaced by their
    instruments: the mean of the neighbours INSTRUMENT_HOLE+1..INSTRUMENT_HOLE+INSTRUMENT_SPAN
    samples away on each side, within each recording (`starts`: first row of every recording)."""
    out = dict(signals)
    bounds = list(starts) + [len(next(iter(signals.values())))]
    for name in triad_signals(triad):
        if name not in signals:
            continue
        x = signals[name]
        smooth = np.concatenate([_neighbour_mean(x[a:b]) for a, b in zip(bounds[:-1], bounds[1:])])
        out[name], out[f"abs_{name}"] = smooth, np.abs(smooth)
    return out


def _neighbour_mean(x: np.ndarray) -> np.ndarray:
    """Mean of the samples HOLE+1..HOLE+SPAN away on both sides (NaN where a side is missing)."""
    n, lo, hi = len(x), INSTRUMENT_HOLE + 1, INSTRUMENT_HOLE + INSTRUMENT_SPAN
    acc, count = np.zeros(n), np.zeros(n)
    for k in range(lo, hi + 1):
        for shift in (k, -k):
            v = np.full(n, np.nan)
            if shift > 0:
                v[shift:] = x[:-shift]
            else:
                v[:shift] = x[-shift:]
            ok = np.isfinite(v)
            acc[ok] += v[ok]
            count[ok] += 1
    return np.where(count == 2 * INSTRUMENT_SPAN, acc / np.maximum(count, 1), np.nan)


def central_differences(x: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(N, 3) central difference (x[k+h] − x[k−h]) / (t[k+h] − t[k−h]), h = SHIFT_HALF_WIDTH; NaN at the ends."""
    h = SHIFT_HALF_WIDTH
    out = np.full(x.shape, np.nan)
    if len(t) > 2 * h:
        out[h:-h] = (x[2 * h:] - x[:-2 * h]) / (t[2 * h:] - t[:-2 * h])[:, None]
    return out
