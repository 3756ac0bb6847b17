"""Sizes of the undeclared effects of tests/effects.py against the noise floor (issue 14).

Simulates scenarios/variants/diag_effects.toml once, injects every effect of tests/effects.py
EFFECTS into the noise-free truth (effects.truth_as_raw: the difference is the effect alone, with
no noise and no declared sensor error) and prints per effect, on its target triad:

  rms       RMS of the injected effect over the whole recording (all samples, three axes)
  rms ho    the same on the held-out part (the last 30 % in time, as `imufmu diagnose` holds out)
  ac ho     held-out RMS after removing the per-axis held-out mean (what no refitted offset removes)
  σ         per-sample noise of the triad, measured on the simulated raw data: pooled scatter
            about a linear fit per axis within each rest window (≥ 1 s, 0.2 s trimmed at each
            end); the sensor TOML's density·√rate is printed below the table for comparison
  ratio     rms ho / σ
  ideal     best possible held-out reduction of the residual RMS if the effect were removed
            perfectly and only the noise remained: 1 − σ/√(σ² + rms_ho²)
  ideal ac  the same with ac ho (conservative: as if the diagnosis' offset had absorbed the mean)

The tests of `imufmu diagnose` ask for a ≥ 70 % held-out improvement; every effect here must
reach an ideal ≥ 85 % (checked at the end, exit status 1 otherwise).

Usage: .venv/bin/python benchmarks/effect_sizes.py
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))

from effects import EFFECTS, truth_as_raw  # noqa: E402

from training.data.dataset import ImuData  # noqa: E402
from training.simulator import load_scenario, simulate  # noqa: E402

SCENARIO = ROOT / "scenarios" / "variants" / "diag_effects.toml"
#: Held-out share at the end of the recording (training.diagnosis.diagnose.HOLDOUT_FRACTION).
HOLDOUT_FRACTION = 0.3
#: Required ideal held-out reduction [1].
MIN_IDEAL = 0.85
#: Rest windows shorter than this are not used to measure the noise [s]; trimmed at each end [s].
MIN_REST_S, REST_TRIM_S = 1.0, 0.2
#: Display unit per triad: (name, factor from SI).
UNITS = {"gyr": ("°/s", np.rad2deg(1.0)), "acc": ("m/s²", 1.0), "mag": ("µT", 1.0)}


def rest_runs(data: ImuData) -> list[slice]:
    """Index ranges where the body is still (true rate and specific force constant), trimmed."""
    still = np.linalg.norm(data.ref_gyr, axis=1) < 1e-12
    still[1:] &= np.linalg.norm(np.diff(data.ref_acc, axis=0), axis=1) < 1e-9
    edges = np.flatnonzero(np.diff(np.r_[0, still.astype(int), 0]))
    rate = 1.0 / np.median(np.diff(data.t))
    trim = int(round(REST_TRIM_S * rate))
    return [slice(a + trim, b - trim) for a, b in zip(edges[::2], edges[1::2])
            if (b - a) / rate >= MIN_REST_S + 2 * REST_TRIM_S]


def measured_sigma(data: ImuData, triad: str) -> float:
    """Per-sample noise σ [SI] of a raw triad: pooled residual of a per-axis line in time over
    each rest window (the line absorbs the bias and its slow temperature drift)."""
    x, squares, dof = getattr(data, triad), 0.0, 0
    for run in rest_runs(data):
        t = data.t[run] - data.t[run].mean()
        design = np.column_stack([np.ones_like(t), t])
        coef, *_ = np.linalg.lstsq(design, x[run], rcond=None)
        e = x[run] - design @ coef
        squares += float(np.sum(e * e))
        dof += e.size - 2 * x.shape[1]
    return float(np.sqrt(squares / dof))


def toml_sigma(scenario, triad: str) -> float:
    """σ = noise density · √rate [SI] from the sensor file."""
    return float(getattr(scenario.sensor, triad).noise_density * np.sqrt(scenario.rate_hz))


def rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x * x)))


def main() -> int:
    scenario = load_scenario(SCENARIO)
    data = simulate(scenario)
    base = truth_as_raw(data)
    holdout = data.t >= data.t[0] + (1.0 - HOLDOUT_FRACTION) * (data.t[-1] - data.t[0])
    sigma = {triad: measured_sigma(data, triad) for triad in UNITS}
    print(f"{SCENARIO.relative_to(ROOT)}: {len(data)} samples, {data.t[-1] - data.t[0]:.1f} s, "
          f"{data.temp[0]:.1f} -> {data.temp[-1]:.1f} °C, held-out t ≥ {data.t[holdout][0]:.1f} s, "
          f"{len(rest_runs(data))} rest windows for σ\n")
    header = (f"{'effect':24s} {'triad':5s} {'unit':5s} {'rms':>8s} {'rms ho':>8s} {'ac ho':>8s} "
              f"{'σ':>8s} {'ratio':>7s} {'ideal':>7s} {'ideal ac':>8s}")
    print(header)
    print("-" * len(header))
    failures = []
    for name, effect in EFFECTS.items():
        if effect.target is None:
            print(f"{name:24s} {'-':5s} {'-':5s} {'0':>8s}   (no effect)")
            continue
        unit, scale = UNITS[effect.target]
        diff = (getattr(effect(base), effect.target) - getattr(base, effect.target)) * scale
        ho = diff[holdout]
        s = sigma[effect.target] * scale
        e_all, e_ho, e_ac = rms(diff), rms(ho), rms(ho - ho.mean(axis=0))
        ideal, ideal_ac = (1.0 - s / np.hypot(s, e) for e in (e_ho, e_ac))
        print(f"{name:24s} {effect.target:5s} {unit:5s} {e_all:8.4f} {e_ho:8.4f} {e_ac:8.4f} "
              f"{s:8.4f} {e_ho / s:7.1f} {100 * ideal:6.1f}% {100 * ideal_ac:7.1f}%")
        if ideal < MIN_IDEAL:
            failures.append(name)
    print("\nσ measured at rest vs sensor file (density·√rate): "
          + ", ".join(f"{t} {sigma[t] * UNITS[t][1]:.4f} vs {toml_sigma(scenario, t) * UNITS[t][1]:.4f} "
                      f"{UNITS[t][0]}" for t in UNITS))
    if failures:
        print(f"ideal held-out reduction below {100 * MIN_IDEAL:.0f} %: {', '.join(failures)}")
        return 1
    print(f"every effect: ideal held-out reduction ≥ {100 * MIN_IDEAL:.0f} %")
    return 0


if __name__ == "__main__":
    sys.exit(main())
