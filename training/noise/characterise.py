"""Noise characterisation of still data: per axis white noise density N, bias instability B and
random walk K (rate random walk for the gyro) from the pooled Allan deviation of every still stretch
(training.noise.allan), with 68 % confidence intervals and a support flag per figure.

Still stretches: a static log (sidecar "reference": "static") is still throughout, cut at its time
gaps; any other recording gives its rests (training.selfcal.rest.detect_rest). Each stretch loses
its mean (after the reference signal ref_gyr/ref_acc/ref_mag when the recording has it), so only the
noise remains. A bias that drifts with temperature inside a stretch stays in and shows as random
walk or a ramp: characterise at a steady temperature.

How much still data each figure needs (a stretch of length L gives τ up to L/9):
    N  a few hundred samples (1 s at 100 Hz gives N within ~10 %); short rests pool.
    B  the flicker floor must dominate the curve (white and random walk below it) over a factor
       FLOOR_SPAN in τ: stretches of ≥ 9 · FLOOR_SPAN · τ_w, τ_w = (N / 0.664 B)² where the white
       line meets the floor (mems_grade gyro with B = 0.002 °/s: τ_w = 5 s, so ≥ 90 s).
    K  the random walk line must dominate from τ_c to 3 τ_c (τ_c: where it meets the rest) and the
       data themselves rise there (slope ≥ RANDOM_WALK_MIN_SLOPE over the last factor 3 in τ, and
       over at least RANDOM_WALK_FROM_BOTTOM in τ after the curve's bottom):
       stretches of ≥ 27 τ_c (mems_grade gyro: τ_c ≈ 130 s with that floor, so ≥ 1 h; 3 h for K
       within ~20-40 %).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from training.data.dataset import ImuData
from training.noise.allan import (ALPHA, CONFIDENCE, DOMINANT_SHARE, EDF_CAP, MIN_CLUSTERS, AllanCurve, AllanFit,
                                  allan_curve, fit_allan)

#: The block's format (the contract with the virtual-sensor FMU).
FORMAT = "imufusion-noise/1"
TRIADS = ("gyr", "acc", "mag")
#: Unit of each triad's samples.
UNITS = {"gyr": "rad/s", "acc": "m/s²", "mag": "µT"}
#: Figure -> unit pattern ({u}: the triad's unit) and its column in the Allan fit.
FIGURES = {"noise_density": ("{u}/√Hz", 0), "bias_instability": ("{u}", 1), "random_walk": ("{u}/√s", 2)}
#: B is supported when the floor dominates the model over at least this factor in τ ...
FLOOR_SPAN = 2.0
#: ... and K when the random walk dominates from τ_c up to RANDOM_WALK_SPAN · τ_c (IEEE 952 reads the
#: +1/2 line well inside its region).
RANDOM_WALK_SPAN = 3.0
#: ... and the data's own log-log slope over that last factor in τ is at least this (a random walk dominating
#: there gives ≥ +0.35; a flat floor whose last points scatter up, or a flicker process still rising below
#: its flat range, gives a K the fit invents: 10 min of the benchmark grades, K +160…+440 % without this).
RANDOM_WALK_MIN_SLOPE = 0.2
#: ... and the data's longest τ is at least this factor beyond the τ of the curve's bottom: a short record
#: shows a floor and the start of the walk over less than a decade, and the fit then trades the two (10 min
#: of the benchmark grades: K +110…+290 % "supported" on 6 of 54 axes without this rule).
RANDOM_WALK_FROM_BOTTOM = 5.0
#: N's CI is read nearest this τ [s] (IEEE 952: the −1/2 line at τ = 1 s) among the white-dominated τ
#: with at least EDF_CAP degrees of freedom (short rests: the longest such τ is well below 1 s).
N_READ_TAU_S = 1.0
#: Fewest τ points for any figure.
MIN_TAUS = 3
#: A run of consecutive τ spanning at least this factor in τ (the τ grid has 12 per decade, and
#: neighbouring τ share most of their data: a short run is one event) whose data lie outside their CI
#: around the model, all on one side, ...
CORRELATED_SPAN = 4.0
#: ... and deviate from it by more than this fraction flags a correlated component (Gauss–Markov bump,
#: ramp) the model lacks. (The main job's 256 short rests wobble by 10-15 % over a factor 2-3 around
#: τ = 0.5 s, where only a few long rests remain: no component worth a note.)
CORRELATED_MIN_DEVIATION = 0.2
#: The progress bar appears when the characterisation lasts longer than this [s].
PROGRESS_DELAY_S = 2.0
#: The rates of several recordings pool when they agree to this fraction.
RATE_TOLERANCE = 0.01


@dataclass(frozen=True)
class AxisNoise:
    """One axis: its pooled Allan curve (None without still data), fit (None likewise), the three
    figures as the block writes them, and a note on a correlated component ('' when none shows)."""

    curve: AllanCurve | None
    fit: AllanFit | None
    figures: dict
    correlated: str = ""


@dataclass
class NoiseResult:
    """The characterisation: `block` (the model.json "noise" block, imufusion-noise/1), per triad the
    three AxisNoise, and notes (skipped recordings, correlated components)."""

    block: dict
    axes: dict[str, list[AxisNoise]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class _Stretch:
    """Samples [start, stop) of recording `data` that are still."""

    data: ImuData
    start: int
    stop: int


def _rate(data: ImuData) -> float:
    """Nominal rate [Hz]: the sidecar's rate_hz, else 1 / the median step."""
    rate = data.meta.get("rate_hz")
    if isinstance(rate, (int, float)) and rate > 0:
        return float(rate)
    return float(1.0 / np.median(np.diff(data.t))) if len(data) > 1 else 0.0


def still_stretches(datasets: list[ImuData]) -> tuple[list[_Stretch], float, str, list[str]]:
    """The still stretches of the recordings at the first recording's rate, that rate [Hz], the
    one-line source text and notes (recordings skipped for another rate)."""
    from training.data.reference_source import is_static
    from training.selfcal.rest import contiguous_blocks, detect_rest
    stretches, parts, notes = [], [], []
    rate = _rate(datasets[0]) if datasets else 0.0
    for index, data in enumerate(datasets):
        if len(data) < 2 or abs(_rate(data) - rate) > RATE_TOLERANCE * rate:
            notes.append(f"noise: {data.name} left out: its rate {_rate(data):.4g} Hz is not {rate:.4g} Hz")
            continue
        if is_static(data):
            found = [_Stretch(data, a, b) for a, b in contiguous_blocks(data.t) if b - a >= 2]
            kind = "static"
        else:
            try:
                found = [_Stretch(data, w.start, w.stop) for w in detect_rest(data, index).rests]
            except ValueError:
                found = []
            kind = "rests"
        seconds = sum(s.stop - s.start for s in found) / rate if rate > 0 else 0.0
        parts.append(f"{data.name}: {kind}, {len(found)} stretch{'es' if len(found) != 1 else ''}, {seconds:.1f} s")
        stretches += found
    total = sum(s.stop - s.start for s in stretches) / rate if rate > 0 else 0.0
    source = "; ".join(parts) + f" — {total:.1f} s still in total"
    return stretches, rate, source, notes


def _axis_pieces(stretches: list[_Stretch], triad: str, axis: int) -> list[np.ndarray]:
    """The noise of one axis in each stretch: raw minus the reference (when recorded), cut at
    non-finite samples, each piece's mean removed later by allan_curve."""
    pieces = []
    for s in stretches:
        x = getattr(s.data, triad)[s.start:s.stop, axis].astype(float)
        ref = getattr(s.data, f"ref_{triad}", None)
        if ref is not None and np.all(np.isfinite(ref[s.start:s.stop, axis])):
            x = x - ref[s.start:s.stop, axis]
        finite = np.isfinite(x)
        edges = np.flatnonzero(np.diff(np.concatenate([[0], finite.astype(int), [0]])))
        pieces += [x[a:b] for a, b in zip(edges[::2], edges[1::2])]
    return pieces


def quantisation_lsb(datasets: list[ImuData], triad: str) -> float | None:
    """The quantisation step [u] the raw values of `triad` show: the smallest step between distinct
    values, when every value is a multiple of it (to 1 % of it) and the values repeat (fewer distinct
    values than a quarter of the samples); else None."""
    values = np.concatenate([getattr(d, triad).ravel() for d in datasets])
    values = values[np.isfinite(values)]
    distinct = np.unique(values)
    if distinct.size < 2 or distinct.size > values.size / 4:
        return None
    steps = np.diff(distinct)
    q = float(np.median(steps[steps < 1.5 * steps.min()]))
    if q <= 0.0:
        return None
    residual = np.abs(distinct / q - np.round(distinct / q))
    return q if float(np.max(residual)) < 0.01 else None


def _ci(curve: AllanCurve, fit: AllanFit, figure: str, value: float, tau: float) -> list[float]:
    """68 % interval of a figure read at `tau`: the Allan deviation's χ² interval there (allantools,
    edf of the figure's noise type), scaled to the figure (each figure is proportional to σ where its
    term dominates)."""
    import allantools
    j = int(np.argmin(np.abs(curve.taus - tau)))
    edf = float(curve.edf(ALPHA[figure])[j])
    dev = float(np.sqrt(fit.avar(curve.taus[j:j + 1])[0]))
    lo, hi = allantools.confidence_interval(dev, max(edf, 1.0), ci=CONFIDENCE)
    return [value * lo / dev, value * hi / dev]


def _figure(unit: str, value: float = 0.0, ci=(0.0, 0.0), supported: bool = False, why: str = "") -> dict:
    """One figure as the block writes it (value and CI finite)."""
    value = float(value) if np.isfinite(value) else 0.0
    ci = [float(c) if np.isfinite(c) else value for c in ci]
    return {"value": value, "ci": ci, "unit": unit, "supported": bool(supported), "why": "" if supported else why}


def _dominant_range(curve: AllanCurve, fit: AllanFit, column: int) -> np.ndarray:
    """The τ [s] of the curve where the fit's term `column` is at least DOMINANT_SHARE of the model."""
    parts = fit.parts(curve.taus)
    return curve.taus[parts[:, column] >= DOMINANT_SHARE * parts.sum(axis=1)]


def _crossing(fit: AllanFit, column: int) -> float:
    """Smallest τ [s] (on a fine grid to 10^6 s) where term `column` reaches DOMINANT_SHARE of the model;
    inf when it never does."""
    grid = np.logspace(-3, 6, 1801)
    parts = fit.parts(grid)
    hit = np.flatnonzero(parts[:, column] >= DOMINANT_SHARE * parts.sum(axis=1))
    return float(grid[hit[0]]) if hit.size and fit.coefficients[column] > 0 else float("inf")


def axis_figures(curve: AllanCurve | None, triad: str, longest_s: float) -> AxisNoise:
    """The three figures of one axis from its pooled curve, each flagged when the data cannot support it."""
    u = UNITS[triad]
    units = {name: pattern.format(u=u) for name, (pattern, _) in FIGURES.items()}
    if curve is None or curve.taus.size < MIN_TAUS:
        why = (f"too little still data: the longest still stretch is {longest_s:.3g} s, N needs "
               f"≥ {MIN_CLUSTERS * MIN_TAUS} samples in one")
        return AxisNoise(curve, None, {k: _figure(units[k], why=why) for k in FIGURES})
    fit = fit_allan(curve)
    tau_max = float(curve.taus[-1])
    figures = {}
    # N: the −1/2 line, read nearest τ = 1 s where white noise dominates
    white = _dominant_range(curve, fit, 0)
    n_value = fit.noise_density
    if white.size:
        edf = curve.edf(0)[np.isin(curve.taus, white)]
        pinned = white[edf >= EDF_CAP] if np.any(edf >= EDF_CAP) else white[[int(np.argmax(edf))]]
        tau_n = float(pinned[np.argmin(np.abs(np.log(pinned / N_READ_TAU_S)))])
        figures["noise_density"] = _figure(units["noise_density"], n_value,
                                           _ci(curve, fit, "noise_density", n_value, tau_n), True)
    else:
        figures["noise_density"] = _figure(units["noise_density"], n_value, [n_value, n_value], False,
                                           f"white noise dominates nowhere in τ = {curve.taus[0]:.3g}…{tau_max:.3g} s")
    # B: the floor, where it dominates over FLOOR_SPAN in τ
    b_value = fit.bias_instability
    floor = _dominant_range(curve, fit, 1) if fit.floor else np.zeros(0)
    if floor.size and floor[-1] >= FLOOR_SPAN * floor[0]:
        tau_b = float(floor[np.argmax(fit.parts(floor)[:, 1] / fit.avar(floor))])
        figures["bias_instability"] = _figure(units["bias_instability"], b_value,
                                              _ci(curve, fit, "bias_instability", b_value, tau_b), True)
    else:
        tau_w = (fit.noise_density / (0.664 * b_value)) ** 2 if b_value > 0 else float("inf")
        need = (f"; the floor would show from τ ≈ {tau_w:.3g} s, needing still stretches of ≥ "
                f"{MIN_CLUSTERS * FLOOR_SPAN * tau_w:.3g} s" if np.isfinite(tau_w) else "")
        figures["bias_instability"] = _figure(
            units["bias_instability"], b_value, [b_value, b_value], False,
            f"no flicker floor over a factor {FLOOR_SPAN:g} in τ up to {tau_max:.3g} s (longest still stretch "
            f"{longest_s:.3g} s){need}")
    # K: the +1/2 line, where it dominates from τ_c to RANDOM_WALK_SPAN · τ_c
    k_value = fit.random_walk
    tau_c = _crossing(fit, 2)
    rising = _end_slope(curve)
    bottom = float(curve.taus[int(np.argmin(curve.adev))])
    if (np.isfinite(tau_c) and tau_max >= RANDOM_WALK_SPAN * tau_c and rising >= RANDOM_WALK_MIN_SLOPE
            and tau_max >= RANDOM_WALK_FROM_BOTTOM * bottom):
        walk = _dominant_range(curve, fit, 2)
        tau_k = float(walk[-1]) if walk.size else tau_max
        figures["random_walk"] = _figure(units["random_walk"], k_value,
                                         _ci(curve, fit, "random_walk", k_value, tau_k), True)
    elif np.isfinite(tau_c) and tau_max >= RANDOM_WALK_SPAN * tau_c and rising >= RANDOM_WALK_MIN_SLOPE:
        figures["random_walk"] = _figure(
            units["random_walk"], k_value, [k_value, k_value], False,
            f"the curve's bottom is at τ = {bottom:.3g} s and its longest τ {tau_max:.3g} s: the rise after the bottom "
            f"must span a factor {RANDOM_WALK_FROM_BOTTOM:g} to tell a random walk from a floor (still stretches of "
            f"≥ {MIN_CLUSTERS * RANDOM_WALK_FROM_BOTTOM * bottom:.3g} s; the longest is {longest_s:.3g} s)")
    elif np.isfinite(tau_c) and tau_max >= RANDOM_WALK_SPAN * tau_c:
        figures["random_walk"] = _figure(
            units["random_walk"], k_value, [k_value, k_value], False,
            f"the curve does not rise at its longest τ (slope {rising:+.2f} over τ = {tau_max / RANDOM_WALK_SPAN:.3g}…"
            f"{tau_max:.3g} s, a random walk gives ≥ {RANDOM_WALK_MIN_SLOPE:g}): longer still stretches than the "
            f"longest, {longest_s:.3g} s, are needed")
    elif np.isfinite(tau_c):
        figures["random_walk"] = _figure(
            units["random_walk"], k_value, [k_value, k_value], False,
            f"random walk needs τ ≥ {RANDOM_WALK_SPAN:g}·τc = {RANDOM_WALK_SPAN * tau_c:.3g} s of still data "
            f"(stretches of ≥ {MIN_CLUSTERS * RANDOM_WALK_SPAN * tau_c:.3g} s); the longest still stretch is "
            f"{longest_s:.3g} s")
    else:
        figures["random_walk"] = _figure(units["random_walk"], 0.0, [0.0, 0.0], False,
                                         f"no random walk visible up to τ = {tau_max:.3g} s (longest still stretch "
                                         f"{longest_s:.3g} s)")
    return AxisNoise(curve, fit, figures, _correlated(curve, fit))


def _end_slope(curve: AllanCurve) -> float:
    """Log-log slope of the data's Allan deviation over its last factor RANDOM_WALK_SPAN in τ (nan with
    fewer than 3 points there)."""
    end = curve.taus >= curve.taus[-1] / RANDOM_WALK_SPAN
    if np.count_nonzero(end) < 3:
        return float("nan")
    return float(np.polyfit(np.log(curve.taus[end]), np.log(curve.adev[end]), 1)[0])


def _correlated(curve: AllanCurve, fit: AllanFit) -> str:
    """A note when consecutive τ over a factor CORRELATED_SPAN lie outside their CI on one side of the
    model, by more than CORRELATED_MIN_DEVIATION: a correlated component (Gauss–Markov bump, rate ramp)
    the three-term model lacks."""
    model = np.sqrt(fit.avar(curve.taus))
    ci = curve.ci(fit.dominant_alpha(curve.taus))
    far = np.abs(curve.adev / model - 1.0) > CORRELATED_MIN_DEVIATION
    side = np.where(far & (ci[:, 0] > model), 1, np.where(far & (ci[:, 1] < model), -1, 0))
    start = 0
    for j in range(1, side.size + 1):
        if j < side.size and side[j] == side[start]:
            continue
        if side[start] != 0 and curve.taus[j - 1] >= CORRELATED_SPAN * curve.taus[start]:
            what = "above" if side[start] > 0 else "below"
            return (f"a correlated component (Gauss–Markov bump or ramp) the model lacks: the curve lies {what} "
                    f"the fit beyond its CI at τ = {curve.taus[start]:.3g}…{curve.taus[j - 1]:.3g} s")
        start = j
    return ""


def characterise(datasets: list[ImuData], progress: bool = False) -> NoiseResult:
    """The noise characterisation of the recordings' still data (module docstring): the
    imufusion-noise/1 block plus the curves and fits behind it. Triads absent from every recording
    are left out. Never raises on data without still stretches: every figure is then flagged.
    progress: a progress bar over the axes, shown when the work lasts over PROGRESS_DELAY_S."""
    from tqdm import tqdm
    stretches, rate, source, notes = still_stretches(datasets)
    lengths = [s.stop - s.start for s in stretches]
    still_s = float(sum(lengths) / rate) if rate > 0 else 0.0
    longest_s = float(max(lengths, default=0) / rate) if rate > 0 else 0.0
    block = {"format": FORMAT, "source": source, "rate_hz": float(rate), "still_seconds": still_s,
             "longest_still_seconds": longest_s, "triads": {}}
    result = NoiseResult(block, {}, notes)
    triads = [t for t in TRIADS if any(d.has(t) for d in datasets)]
    bar = tqdm(total=3 * len(triads), desc="Allan deviation", unit="axis", disable=not progress,
               delay=PROGRESS_DELAY_S)
    for triad in triads:
        axes = []
        for i in range(3):
            axes.append(axis_figures(allan_curve(_axis_pieces(stretches, triad, i), rate) if rate > 0 else None,
                                     triad, longest_s))
            bar.update()
        result.axes[triad] = axes
        block["triads"][triad] = {"unit": UNITS[triad], "lsb": quantisation_lsb(datasets, triad),
                                  "axes": [a.figures for a in axes]}
        for i, a in enumerate(axes):
            if a.correlated:
                result.notes.append(f"noise: {triad} {'xyz'[i]}: {a.correlated}")
    bar.close()
    return result

