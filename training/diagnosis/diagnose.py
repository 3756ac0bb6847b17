"""`imufmu diagnose`: find the effect a trained model lacks, add it to the model, report before/after.

1. Run the model through the batch runtime (the FMU's C code) and form residuals of the
   compensated triads against the reference the data has (ref_gyr/acc/mag, or derived from ref_q
   by training.data.reference), or against an invariant without a reference: the field norm (sidecar
   norm, else the median on the training blocks) and the gravity norm at rest.
2. Split every recording into 3·BLOCKS contiguous blocks; every third is held out. Interleaved
   blocks keep the held-out rows inside the ranges the fit saw (a temperature ramp, a drift), so
   the bounded terms (training.diagnosis.diagnose_export) are judged where they are valid.
3. Fit every candidate family of training.diagnosis.candidates on the training blocks and score it on the
   held-out blocks (training.diagnosis.diagnose_fit: least squares, instruments for the target's own signal,
   a batch-means test with Bonferroni over the candidates). The best significant family is grown by
   forward selection: every other family of the same target is fitted jointly with the selected
   ones and the one that improves the held-out residual most is added while it is significant and
   explains at least MIN_EXPLAINED of what is left — so a lever arm with its centripetal part, or a
   g-sensitivity with a lag, is found as one effect.
   The same sweep runs with each trained neural stage that is on switched off (the ELM after the
   magnetometer, the PSO-BP network after the gyroscope: trained on calibration data that carried the
   effect, they learned part of it); its effect competes through the runtime (_proposals).
4. Carry the effect (training.diagnosis.diagnose_export), rerun the runtime, measure before/after on the
   held-out blocks, iterate.
"""
from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np

from contract.errors import DataError
from contract.layout import AUX_INPUTS, INPUTS, TERM_SIGNALS, TERMS_MAX, TRIAD_ORDER, settings_array
from contract.mounting import mount_matrix, settings_codes
from training.artefact import NEURAL_STAGES, ModelArtefact, coefficients_array, load_artefact, settings_dict
from training.data.dataset import ImuData
from training.data.earth import local_gravity
from training.data.io import read_imu_csv
from training.data.reference import derive_references
from training.diagnosis.candidates import (BIAS_MODEL, TRIAD_NAMES, build_candidates, central_differences,
                                           instrument_signals, triad_signals)
from training.diagnosis.diagnose_export import add_effect, aux_slots_needed, refit_note, refit_summary, term_count
from training.diagnosis.detection import Rule, detection_limits
from training.diagnosis.diagnose_fit import (Fit, Residuals, excitation, fit_candidates, metric, offset_fit,
                                             predict)
from training.diagnosis.effect_readings import DISPLAY, readings
from training.diagnosis import rate_means
from training.diagnosis.time_shift import WideShift, beyond_linear, scan_shift, shift_column, shifted
from training.main_job import recording_parameters
from training.runtime import run_batch, term_signals
from training.train import REFERENCE_OUTLIER_SIGMAS

#: Held-out blocks per recording; each recording is cut into 3·BLOCKS blocks and every third is held
#: out (a third of the rows). 16 blocks of a 150 s recording are ~3 s long, longer than the ~1 s
#: correlation time of handheld motion (0.1-1 Hz); 15 degrees of freedom keep the Bonferroni-
#: corrected t quantile moderate.
BLOCKS = 16
HOLDOUT_EVERY = 3
#: Regression rows are decimated to at most this rate [Hz] (BROAD is 286 Hz): the batch-means test
#: does not count rows as independent anyway.
REGRESSION_RATE_HZ = 50.0
#: Significance level after Bonferroni correction over the candidate count.
ALPHA = 0.01
#: A family must explain at least this share of the held-out residual it is compared with: below
#: it, a "significant" fit on tens of thousands of rows is too small to matter for any metric.
MIN_EXPLAINED = 0.05
#: Time is a last-resort regressor (a drift with time since power-on does not transfer between
#: power cycles): a family without `time` within this explained share of the best wins, and time
#: never joins a combination.
TIME_TIE = 0.02
#: Iterations of select -> grow -> add -> rerun (effects added).
MAX_ITERATIONS = 4
#: Effects that may fail through the runtime (not added, their families left out from then on) besides:
#: each costs a runtime run and a candidate sweep. They used to count as iterations, so a run of failing
#: families could end the loop before a real effect was tried (x-io handheld with an injected motor
#: current on the field norm: three field families failed, the current — 72 % explained, p 9e-5 —
#: was never tried).
MAX_REJECTED = 4
#: Families one effect may combine.
MAX_FAMILIES = 4
#: Rest detection for the gravity-norm invariant [rad/s].
REST_RATE = 0.05
_SLICES = {"gyr": slice(0, 3), "acc": slice(3, 6), "mag": slice(6, 9)}
_METRIC_NAMES = {"gyr": "rate error RMS", "acc": "specific-force error RMS", "mag": "field error RMS"}
_AUX_SLOTS = [n for n in INPUTS if n.startswith("aux_")]


def targets_of(data: ImuData) -> dict[str, str]:
    """target -> kind ('triad' or 'norm') for the residuals this recording supports."""
    out = {}
    for triad in TRIAD_ORDER:
        if not data.has(triad):
            continue
        ref = getattr(data, f"ref_{triad}")
        if ref is not None and np.isfinite(ref).any():
            out[triad] = "triad"
        elif triad in ("mag", "acc"):
            out[f"{triad}_norm"] = "norm"
    return out


def _reference_norm(target: str, data: ImuData, comp: np.ndarray, rows: np.ndarray) -> float:
    """Invariant magnitude: sidecar field norm / the recording's local gravity (training.data.earth.local_gravity:
    sidecar gravity_mps2, its site, else standard gravity), else the training-block median."""
    if target == "mag_norm" and data.field_norm_ut is not None:
        return data.field_norm_ut
    if target == "acc_norm":
        try:
            return local_gravity(data.meta)[0]
        except ValueError:
            pass
    return float(np.nanmedian(np.linalg.norm(comp[rows], axis=1)))


def _run(artefact: ModelArtefact, data: ImuData, terms: bool = True) -> np.ndarray:
    """Runtime outputs of `data` with the artefact (without its terms when terms=False), the three triads
    turned back into the sensor axes: the frame of the recording's references and of the correction
    terms, which the runtime applies before its mounting (sources/ImuPipeline.c). In the body axes a
    z-up board's (mount 1, −2, −3) terms were fitted in one frame and applied in the other: x-io with
    an injected motor current, the field norm 5.6 → 13.0 µT with the current's terms, 4.2 µT with their
    signs turned."""
    art = artefact if terms else replace(artefact, terms=[])
    values = settings_dict(art)
    values.update(recording_parameters(data))
    inputs = data.inputs([a["column"] for a in art.aux_inputs])
    out = run_batch(coefficients_array(art), np.asarray(settings_array(values)), data.t, inputs)
    mount = mount_matrix(settings_codes(values))
    for cols in _SLICES.values():
        out[:, cols] = out[:, cols] @ mount
    return out


def _blocks(t: np.ndarray) -> np.ndarray:
    """(N,) block index 0..3·BLOCKS−1 of every row by time."""
    span = max(t[-1] - t[0], 1e-9)
    return np.minimum((HOLDOUT_EVERY * BLOCKS * (t - t[0]) / span).astype(int), HOLDOUT_EVERY * BLOCKS - 1)


def holdout_rows(t: np.ndarray) -> np.ndarray:
    """(N,) bool: the rows of the held-out blocks of a recording with sample times t [s]."""
    return _blocks(t) % HOLDOUT_EVERY == HOLDOUT_EVERY - 1


def _signals(d: ImuData, out0: np.ndarray) -> dict[str, np.ndarray]:
    """Candidate signals of one recording: the runtime's term signals (from the compensated triads
    before the terms), the recording's aux columns and the central differences of the triads."""
    sig = term_signals(d.t, out0[:, :9], d.temp)
    signals = {name: sig[:, k] for k, name in enumerate(TERM_SIGNALS) if name not in _AUX_SLOTS}
    signals.update(d.aux)
    for triad, cols in _SLICES.items():
        dc = central_differences(out0[:, cols], d.t)
        signals.update({f"dc_{triad}_{a}": dc[:, k] for k, a in enumerate("xyz")})
    return signals


def _residual(target: str, kind: str, d: ImuData, out: np.ndarray, fitted: np.ndarray, smoothed: bool):
    """(residual (N, m), unit vectors (N, 3) or None) of one target. smoothed: the recording's rate
    reference is the smoothed derivative of its attitude reference (training.data.reference), so the
    compensated rate goes through the same filter and both are compared as window means
    (training.diagnosis.rate_means): unfiltered, the reference's smoothing of the motion is part of the
    residual (BROAD 02: 9.3, 3.0, 2.9 °/s RMS per axis unfiltered, 5.0, 1.4, 1.4 filtered), and sample
    by sample, its differentiated attitude noise (ibid.)."""
    triad = target.split("_")[0]
    comp = out[:, _SLICES[triad]]
    if kind == "triad":
        if smoothed and triad == rate_means.TRIAD:
            return rate_means.compared_residual(comp, getattr(d, f"ref_{triad}"), d.t), None
        return comp - getattr(d, f"ref_{triad}"), None
    norm = np.linalg.norm(comp, axis=1)
    r = norm - _reference_norm(target, d, comp, fitted)
    if triad == "acc":
        r = np.where(np.linalg.norm(out[:, 0:3], axis=1) < REST_RATE, r, np.nan)
    return _without_disturbances(r)[:, None], comp / norm[:, None]


def _without_disturbances(r: np.ndarray) -> np.ndarray:
    """A norm residual with NaN where it is further than REFERENCE_OUTLIER_SIGMAS robust standard
    deviations (1.4826 · MAD) from its median: an invariant only holds where nothing outside the
    sensor changes it (x-io's log: a 12 s magnetic disturbance lowers the field norm by 13 %, and
    the norm target would otherwise fit it with rate terms that distort every undisturbed field)."""
    ok = np.isfinite(r)
    if ok.sum() < 10:
        return r
    centre = np.median(r[ok])
    scale = 1.4826 * np.median(np.abs(r[ok] - centre))
    return np.where(np.abs(r - centre) <= REFERENCE_OUTLIER_SIGMAS * scale, r, np.nan)


def _scanned_shift_columns(parts: list[dict], triads: list[str]) -> dict[str, float]:
    """Replace the time-shift columns (dc_<triad>_*) of every triad with a reference by the column of the
    shift scanned over all recordings (training.diagnosis.time_shift); returns triad -> shift [s] of the
    triads whose shift is beyond the central difference's linear range."""
    rates = [1.0 / float(np.median(np.diff(p["t"]))) for p in parts]
    wide = {}
    for triad in triads:
        cols = _SLICES[triad]
        shift = scan_shift([(_as_residual(triad, p, p["out0"][:, cols]), p["res"][triad][0], p["train"], rate)
                            for p, rate in zip(parts, rates)], float(np.median(rates)))
        if beyond_linear(shift, float(np.median(rates))):
            wide[triad] = shift
        for p in parts:
            column = shift_column(p["out0"][:, cols], p["t"], shift)
            p["signals"].update({f"dc_{triad}_{a}": column[:, k] for k, a in enumerate("xyz")})
            p.setdefault("shifted", {})[triad] = shifted(p["out0"][:, cols], p["t"], shift)
    return wide


def _as_residual(triad: str, part: dict, x: np.ndarray) -> np.ndarray:
    """x (N, 3) of a triad as it reaches the recording's residual: as rate means when the rate reference is
    the derived one (_residual), else as is."""
    return rate_means.as_compared(x, part["t"]) if triad == rate_means.TRIAD and part["matched"][0] else x


def _wide_shift(triad: str, shift_s: float, parts: list[dict], signals: dict[str, np.ndarray],
                starts: np.ndarray) -> WideShift:
    """The WideShift of a triad: `signals` with its components (and their absolute values) shifted."""
    x = np.concatenate([p["shifted"][triad] for p in parts])
    moved = dict(signals)
    for k, name in enumerate(triad_signals(triad)):
        moved[name], moved[f"abs_{name}"] = x[:, k], np.abs(x[:, k])
    return WideShift(shift_s, moved, instrument_signals(moved, triad, starts))


def residuals(artefact: ModelArtefact, datasets: list[ImuData], targets: dict[str, str],
              smoothed: list[bool] | None = None) -> Residuals:
    """Residuals of every target and the candidate signals, stacked over the recordings; smoothed[k]:
    recording k's rate reference is derived from its attitude (load_recordings), see _residual."""
    parts = []
    smoothed = smoothed or [False] * len(datasets)
    for k, d in enumerate(datasets):
        out, out0 = _run(artefact, d), _run(artefact, d, terms=False)
        block, held = _blocks(d.t), holdout_rows(d.t)
        step = max(1, int(round(float(1.0 / np.median(np.diff(d.t))) / REGRESSION_RATE_HZ)))
        sampled = np.zeros(len(d), bool)
        sampled[::step] = True
        mask = np.ones(len(d), bool) if d.eval_mask is None else d.eval_mask.astype(bool)
        res = {t: _residual(t, kind, d, out, ~held, smoothed[k]) for t, kind in targets.items()}
        parts.append(dict(t=d.t, signals=_signals(d, out0), res=res, train=sampled & ~held, test=sampled & held,
                          holdout=held & mask, fitted=~held, out0=out0, matched=np.full(len(d), smoothed[k]),
                          block=np.where(held, k * HOLDOUT_EVERY * BLOCKS + block, -1)))
    wide_shifts = _scanned_shift_columns(parts, [t for t, kind in targets.items() if kind == "triad"])
    keys = set.intersection(*(set(p["signals"]) for p in parts))
    signals = {k: np.concatenate([p["signals"][k] for p in parts]) for k in sorted(keys)}
    starts = np.cumsum([0] + [len(d) for d in datasets[:-1]])
    residual = {t: np.concatenate([p["res"][t][0] for p in parts]) for t in targets}
    direction = {t: np.concatenate([p["res"][t][1] for p in parts]) for t in targets if targets[t] == "norm"}
    rows = {k: np.concatenate([p[k] for p in parts]) for k in ("train", "test", "holdout", "fitted", "block")}
    matched = np.concatenate([p["matched"] for p in parts])
    return Residuals(
        t=np.concatenate([p["t"] for p in parts]), starts=starts, signals=signals,
        instruments={triad: instrument_signals(signals, triad, starts) for triad in TRIAD_NAMES},
        residual=residual,
        direction=direction,
        excited=excitation(signals, residual, rows["train"], direction),
        wide_shifts={triad: _wide_shift(triad, s, parts, signals, starts) for triad, s in wide_shifts.items()},
        matched={t: matched for t, kind in targets.items() if kind == "triad" and t == rate_means.TRIAD and matched.any()},
        **rows)


def paired_metric(before: Residuals, after: Residuals, target: str) -> tuple[float, float]:
    """metric of a target before and after an effect, on the held-out rows where both residuals are
    finite. A norm residual leaves out its disturbed rows (_without_disturbances), judged anew on each
    residual: once an effect is corrected, rows it had pushed out come back, and the two metrics on their
    own rows compared different samples (x-io with an injected motor current: 5.4 → 9.1 µT though the
    current was being removed)."""
    both = np.all(np.isfinite(before.residual[target]), axis=1) & np.all(np.isfinite(after.residual[target]), axis=1)
    return tuple(metric(replace(r, holdout=r.holdout & both), target) for r in (before, after))


def metric_name(target: str, r: Residuals) -> str:
    """'rate error RMS (held-out), °/s' style name of the target's metric; 'rate error RMS of 1 s means'
    where its residual compares rate means (Residuals.matched, training.diagnosis.rate_means)."""
    triad = target.split("_")[0]
    means = f" of {rate_means.MEAN_WINDOW_S:g} s means" if target in r.matched else ""
    return (f"{'norm ' if target.endswith('_norm') else ''}{_METRIC_NAMES[triad]}{means} (held-out), "
            f"{DISPLAY[triad][0]}")


def _uses_time(fit: Fit) -> bool:
    return any("time" in c.signals() for c in fit.candidates)


def _carriable(fit: Fit, r: Residuals, artefact: ModelArtefact) -> bool:
    """The artefact has room for the fit's terms and aux inputs."""
    aux_free = len(_AUX_SLOTS) - len(artefact.aux_inputs)
    return term_count(fit, r, artefact) <= TERMS_MAX and len(aux_slots_needed(fit, artefact)) <= aux_free


def _select(fits: list[Fit], r: Residuals, artefact: ModelArtefact) -> tuple[Fit | None, list[str]]:
    """Best significant fit the FMU has room for, and notes on what was passed over."""
    notes = []
    ok = [f for f in fits if f.explained_fraction >= MIN_EXPLAINED and f.p_value < ALPHA]
    fitting = [f for f in ok if _carriable(f, r, artefact)]
    if len(fitting) < len(ok):
        notes.append(f"significant candidates needing more than the free {TERMS_MAX} term slots or "
                     f"{len(_AUX_SLOTS)} aux inputs were skipped")
    if not fitting:
        return None, notes
    best = max(fitting, key=lambda f: f.explained_fraction)
    if _uses_time(best):
        others = [f for f in fitting if not _uses_time(f) and f.explained_fraction >= best.explained_fraction - TIME_TIE]
        if others:
            alt = max(others, key=lambda f: f.explained_fraction)
            notes.append(f"'{alt.label}' chosen over 'time' ({alt.explained_fraction:.1%} vs "
                         f"{best.explained_fraction:.1%}): time is the last-resort regressor")
            best = alt
    return best, notes


def _additions(combo: Fit, candidates) -> list[tuple]:
    """What forward selection may add to `combo`: every other family of its target (no time, no shift) on
    its own, and train's bias model (candidates.BIAS_MODEL) as one step when neither of its families is in
    yet (a temperature-rate gyro bias in the calibration too, with the PSO-BP stage off: 77 % explained
    alone, 77 % with the temperature, 94 % with the temperature and its square, read within 0.5 %)."""
    others = [c for c in candidates if c.target == combo.target and c not in combo.candidates
              and "time" not in c.signals() and c.kind != "lag"]
    steps = [(c,) for c in others]
    bias = tuple(c for c in others if c.name in BIAS_MODEL)
    if len(bias) == len(BIAS_MODEL):
        steps.append(bias)
    return steps


def _grow(best: Fit, candidates, r: Residuals, base0: Fit, artefact: ModelArtefact) -> Fit:
    """Forward selection: add the family (or train's bias model, _additions) of the same target that
    improves the held-out residual most, while significant (Bonferroni over the additions tried) and
    explaining ≥ MIN_EXPLAINED. A time shift stands alone: its fit is linear in the lag, the runtime's
    shift is not (training.diagnosis.diagnose.refine_lag), so a family grown on its linearisation would
    fit the difference."""
    combo = best
    while len(combo.candidates) < MAX_FAMILIES and best.candidates[0].kind != "lag":
        steps = [s for s in _additions(combo, candidates) if len(combo.candidates) + len(s) <= MAX_FAMILIES]
        tries = [fit_candidates(combo.candidates + s, r, combo, base0, len(steps)) for s in steps]
        ok = [f for f in tries if f is not None and f.p_value < ALPHA and f.gain >= MIN_EXPLAINED
              and _carriable(f, r, artefact)]
        if not ok:
            return combo
        combo = max(ok, key=lambda f: f.gain)
    return combo


def _fitted_rms(artefact: ModelArtefact, datasets: list[ImuData], triad: str, smoothed: list[bool]) -> float:
    """RMS of a triad's residual against its reference over the training blocks of every recording."""
    sq, n = 0.0, 0
    for d, smooth in zip(datasets, smoothed):
        e = _residual(triad, "triad", d, _run(artefact, d), None, smooth)[0][~holdout_rows(d.t)]
        e = e[np.all(np.isfinite(e), axis=1)]
        sq, n = sq + float(np.sum(e * e)), n + e.size
    return np.sqrt(sq / max(n, 1))


def refine_lag(new: ModelArtefact, old: ModelArtefact, effect: Fit, datasets: list[ImuData],
               smoothed: list[bool]) -> ModelArtefact:
    """For a time shift, the lag that minimises the training-block residual through the runtime,
    searched within ±50 % of the linearised estimate's step (bounded Brent, to 0.01 sample)."""
    if effect.candidates[0].kind != "lag":
        return new
    from scipy.optimize import minimize_scalar
    name = f"lag_{effect.target}"
    start, step = old.settings.get(name, 0.0), new.settings[name] - old.settings.get(name, 0.0)
    lo, hi = sorted((start + 0.5 * step, start + 1.5 * step))

    def with_lag(tau: float) -> ModelArtefact:
        return replace(new, settings={**new.settings, name: float(tau)})

    best = minimize_scalar(lambda tau: _fitted_rms(with_lag(tau), datasets, effect.target, smoothed), bounds=(lo, hi),
                           method="bounded", options={"xatol": 0.01 / _rate(datasets)})
    return with_lag(best.x)


def _lag_changes(old: ModelArtefact, new: ModelArtefact) -> dict[str, float]:
    """triad -> lag [s] added between two artefacts (triads whose lag changed)."""
    out = {}
    for triad in TRIAD_NAMES:
        step = new.settings.get(f"lag_{triad}", 0.0) - old.settings.get(f"lag_{triad}", 0.0)
        if step != 0.0:
            out[triad] = step
    return out


def _candidate_json(f: Fit) -> dict:
    return {"name": f.label, "target": f.target, "regressors": [x for c in f.candidates for x in c.labels()],
            "explained_fraction": f.explained_fraction, "p_value": f.p_value}


def _rate(datasets: list[ImuData]) -> float:
    return float(1.0 / np.median(np.concatenate([np.diff(d.t) for d in datasets])))


def load_recordings(paths: list[Path]) -> tuple[list[ImuData], list[str], list[bool]]:
    """Read the recordings and derive missing references from ref_q: (recordings, notes saying what was
    derived, per recording whether its rate reference is the smoothed derivative of its attitude)."""
    datasets, notes, smoothed = [], [], []
    for p in paths:
        raw = read_imu_csv(p)
        data, derived = derive_references(raw)
        datasets.append(data)
        notes += [f"{data.name}: {n}" for n in derived]
        name = f"ref_{rate_means.TRIAD}"
        smoothed.append(getattr(raw, name) is None and getattr(data, name) is not None)
    return datasets, notes, smoothed


def _aux_info(datasets: list[ImuData]) -> dict[str, dict]:
    """Unit and meaning of aux columns from the sidecars' optional
    {"aux": {column: {"unit": "A", "meaning": "motor current"}}} (text entries only)."""
    out: dict[str, dict] = {}
    for d in datasets:
        aux = d.meta.get("aux")
        for column, info in (aux.items() if isinstance(aux, dict) else ()):
            if isinstance(info, dict):
                out.setdefault(column, {}).update({k: v for k, v in info.items()
                                                   if k in ("unit", "meaning") and isinstance(v, str)})
    return out


def _sweep(current: ModelArtefact, r: Residuals, targets: dict[str, str], rejected: set, desc: str,
           progress: bool) -> tuple[list[Fit], Fit | None, list[str]]:
    """One candidate sweep on `r`: (fits sorted by explained share, the best significant fit grown by
    forward selection or None, notes on what was passed over)."""
    from tqdm import tqdm
    candidates = [c for c in build_candidates(r.signals, list(targets)) if (c.target, c.name) not in rejected]
    base = {t: offset_fit(t, r) for t in targets}
    fits = [f for f in (fit_candidates((c,), r, base[c.target], base[c.target], len(candidates))
                        for c in tqdm(candidates, desc=desc, unit="family", disable=not progress, leave=False))
            if f is not None]
    fits.sort(key=lambda f: -f.explained_fraction)
    best, why = _select(fits, r, current)
    return fits, (None if best is None else _grow(best, candidates, r, base[best.target], current)), why


#: triad -> the settings of the stages after its calibration that carry an effect of the calibration data: the
#: neural stages it trained (training.artefact.NEURAL_STAGES) and, for the field, the particle filter, which
#: follows the hard and soft iron online: a switched current's field is a hard-iron change to it, and `train`
#: switches it on when the calibration recordings show such changes (BROAD with a motor current injected).
STAGES = {triad: (setting,) + (("enable_pf",) if triad == "mag" else ()) for triad, (_, setting) in NEURAL_STAGES.items()}


def _stages_off(artefact: ModelArtefact, triad: str) -> list[tuple[ModelArtefact, str]]:
    """(the artefact with one of the triad's STAGES switched off, its setting) for each that is on."""
    return [(replace(artefact, settings={**artefact.settings, setting: 0.0}), setting)
            for setting in STAGES.get(triad, ()) if artefact.settings.get(setting)]


def _proposals(current: ModelArtefact, r: Residuals, datasets: list[ImuData], targets: dict[str, str],
               smoothed: list[bool], rejected: dict[str, set], attempt: int, progress: bool):
    """(first sweep's fits, notes, proposals): each proposal (artefact, its residuals, effect, stage switched
    off or ''): the sweep on the current model and, per triad whose neural stage is on, the sweep with that
    stage off. A stage trained on calibration data that carried an effect learned part of it — the ELM a
    field-dependent soft iron or a late magnetometer, the PSO-BP network a temperature-rate bias — so the
    family reads only the remainder (a temperature-rate gyro bias: 0.0164 (°/s)/(°C/min) for 0.05, not
    significant), while with the stage off it reads the effect itself (0.0501) and the family, the linear
    refit and train's bias model leave less than the stage did (0.184 → 0.0304 °/s)."""
    fits, effect, notes = _sweep(current, r, targets, rejected[""], f"diagnose: candidates, iteration {attempt}",
                                 progress)
    out = [] if effect is None else [(current, r, effect, "")]
    for triad in STAGES:
        own = {t: kind for t, kind in targets.items() if t.split("_")[0] == triad}
        for off, setting in (_stages_off(current, triad) if own else []):
            r_off = residuals(off, datasets, own, smoothed)
            _, found, _ = _sweep(off, r_off, own, rejected[setting],
                                 f"diagnose: candidates with {setting} = 0, iteration {attempt}", progress)
            if found is not None:
                out.append((off, r_off, found, setting))
    return fits, notes, out


def _accepted(before: float, after: float, stage: str) -> bool:
    """An effect is kept when it lowers the held-out error through the runtime; one that switches a trained
    stage off must lower it by MIN_EXPLAINED of the squared error (what a family must explain to be
    selected), so that a stage is not traded for terms that merely match it."""
    return after < before if not stage else after * after <= (1.0 - MIN_EXPLAINED) * before * before


def _stage_note(stage: str, before: float, after: float) -> str:
    """The report's line for an effect that switched a trained stage off ('' when none did)."""
    what = ("the online filter followed part of this effect as a hard- or soft-iron change" if stage == "enable_pf"
            else "the trained stage had learned part of this effect from the calibration data")
    return (f"{stage} = 0: {what}; with it "
            f"off, the effect as fitted leaves {after:.4g} on the held-out rows against {before:.4g} with it on"
            if stage else "")


def _iterate(artefact: ModelArtefact, datasets: list[ImuData], targets: dict[str, str], max_iterations: int,
             progress: bool, smoothed: list[bool]):
    """Select, grow, add, rerun; returns (artefact, residuals, iterations, first ranking, plot data, notes)."""
    r = residuals(artefact, datasets, targets, smoothed)
    current, iterations, first, plot_data, notes = artefact, [], None, None, []
    rate, info = _rate(datasets), _aux_info(datasets)
    units = {k: v["unit"] for k, v in info.items() if "unit" in v}
    rejected: dict[str, set[tuple[str, str]]] = {"": set(), **{s: set() for ss in STAGES.values() for s in ss}}
    attempts = 0
    while len(iterations) < max_iterations and attempts < max_iterations + MAX_REJECTED:
        attempts += 1
        fits, why, proposals = _proposals(current, r, datasets, targets, smoothed, rejected, attempts, progress)
        first = fits if first is None else first
        notes += why
        if not proposals:
            break
        kept = []
        for art, rr, effect, stage in proposals:
            new = refine_lag(add_effect(art, effect, rr, effect.label, info), art, effect, datasets, smoothed)
            r_new = residuals(new, datasets, targets, smoothed)
            before, after = paired_metric(r, r_new, effect.target)
            if _accepted(before, after, stage):
                kept.append((art, rr, effect, stage, new, r_new, before, after))
                continue
            notes.append(f"'{effect.label}' on {effect.target}{f' with {stage} = 0' if stage else ''} explained "
                         f"{effect.explained_fraction:.1%} in the fit but did not lower the held-out error through "
                         f"the runtime ({before:.4g} → {after:.4g}{', by the share a stage must yield' if stage else ''})"
                         ": not added")
            rejected[stage] |= {(c.target, c.name) for c in effect.candidates}
        if not kept:
            continue
        art, rr, effect, stage, new, r_new, before, after = max(kept, key=lambda k: 1.0 - k[7] / k[6])
        iterations.append({"selected": {**_candidate_json(effect), "families": [c.name for c in effect.candidates],
                                        "terms": term_count(effect, rr, art) - len(art.terms),
                                        "offset": effect.offset.tolist(),
                                        "linear_refit": refit_summary(effect), "linear_refit_note": refit_note(effect),
                                        "stage_off": stage or None, "stage_note": _stage_note(stage, before, after),
                                        "readings": readings(effect, rate, units, _lag_changes(art, new))},
                           "target": effect.target, "metric": metric_name(effect.target, rr),
                           "before": before, "after": after,
                           "candidates": [_candidate_json(f) for f in fits[:10]]})
        plot_data = plot_data or (rr, r_new, effect, predict(effect, rr))
        current, r = new, r_new
    return current, r, iterations, first or [], plot_data, notes


#: The files `diagnose` writes into its folder (report.md by diagnose_report.write_report).
OUTPUT_FILES = ("model.json", "diagnosis.json", "report.md")

def _check_aux_columns(paths: list[Path], datasets: list[ImuData], artefact, model_path: Path) -> None:
    """DataError naming the recording, the column and the model when a recording lacks an auxiliary
    column the model's terms read."""
    for path, data in zip(paths, datasets):
        for k, aux in enumerate(artefact.aux_inputs):
            if aux["column"] not in data.aux:
                raise DataError(path, f"has no column '{aux['column']}', which the model {model_path} reads into "
                                      f"input {AUX_INPUTS[k]} (aux columns: {', '.join(data.aux) or 'none'})")


def diagnose(paths: list[Path], model_path: Path, out_dir: Path, seed: int = 0,
             max_iterations: int = MAX_ITERATIONS, plots: bool = True, progress: bool = True,
             limits: bool = True) -> dict:
    """Diagnose recordings `paths` with the artefact `model_path`; write out_dir/diagnosis.json,
    out_dir/model.json (the artefact carrying the effects found) and out_dir/report.md (+ PNG plots).
    limits: also state the detection limit of every family on what the loop left
    (training.diagnosis.detection; ~0.2 s per family).

    Returns the diagnosis.json document. Deterministic: least squares and fixed splits only; `seed`
    is recorded in the new artefact's provenance (nothing is drawn at random).
    """
    from training.diagnosis.diagnose_report import write_report
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    artefact = load_artefact(model_path)
    datasets, notes, smoothed = load_recordings([Path(p) for p in paths])
    _check_aux_columns([Path(p) for p in paths], datasets, artefact, model_path)
    targets = {}
    for d in datasets:
        targets.update(targets_of(d))
    r0 = residuals(artefact, datasets, targets, smoothed)
    start = {t: metric(r0, t) for t in targets}
    current, r, iterations, first_fits, plot_data, why = _iterate(artefact, datasets, targets, max_iterations, progress,
                                                                  smoothed)
    first = iterations[0] if iterations else None
    target = first["target"] if first else (first_fits[0].target if first_fits else next(iter(targets)))
    candidates = build_candidates(r.signals, list(targets)) if limits else []
    found_limits = detection_limits(r, candidates, Rule(MIN_EXPLAINED, ALPHA, len(candidates)), _rate(datasets),
                                    {k: v["unit"] for k, v in _aux_info(datasets).items() if "unit" in v}, progress)
    before, after = start[target], metric(r, target)
    result = {
        "target": target, "metric": metric_name(target, r0),
        "candidates": [_candidate_json(f) for f in first_fits],
        "selected": ({k: first["selected"][k] for k in ("name", "target", "regressors", "families", "readings")}
                     if first else None),
        "before": before, "after": after,
        "improvement_pct": 100.0 * (before - after) / before if first and before > 0 else 0.0,
        "iterations": iterations,
        "metrics_before": {t: start[t] for t in targets},
        "metrics_after": {t: metric(r, t) for t in targets},
        "metric_names": {t: metric_name(t, r0) for t in targets},
        "detection_limits": found_limits,
        "recordings": [{"name": d.name, "samples": len(d)} for d in datasets],
        "holdout": f"every {HOLDOUT_EVERY}rd of {HOLDOUT_EVERY * BLOCKS} contiguous blocks of each recording",
        "alpha_bonferroni": ALPHA, "min_explained": MIN_EXPLAINED,
        "regression_rate_hz": REGRESSION_RATE_HZ,
        "thermal_refitted": "no (each effect's offset is a constant correction term of its triad)",
        "test": (f"one-sided t test of held-out predictive accuracy: ln(SSE_base/SSE_candidate) over the {BLOCKS} "
                 "held-out blocks of each recording"),
        "model_in": str(model_path), "seed": seed, "notes": notes + why,
        "conclusion": ("nothing significant left" if not iterations else
                       f"added: {', '.join(s['selected']['name'] + ' -> ' + s['target'] for s in iterations)}"),
    }
    current.save(out_dir / OUTPUT_FILES[0])
    (out_dir / OUTPUT_FILES[1]).write_text(json.dumps(result, indent=2, ensure_ascii=False) + "\n", encoding="utf-8")
    write_report(out_dir, result, plot_data if plots else None)
    return result
