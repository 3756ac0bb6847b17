"""Online learning of the gyro bias at rests (issue 33 item 3): what it buys and that it does no harm.

The main job's unit: `imufmu train`'s defaults on scenarios/calibration.toml (the mems_grade sensor,
seed 0). Evaluated with the batch runtime (= the FMU, tests/test_bias_learning.py) at train's settings,
bias learning on (the default) and off, on recordings simulated from scenarios/eval_handheld.toml
stretched to --minutes of hand-held motion, 20 s moves with --rest seconds of rest after each
(temperature -5 -> 45 °C). The rest detector needs ~3.5 s of stillness after a move (its 0.5 s low-pass
settles, then 1.5 s must hold), so the evaluation scenario's 3 s rests teach nothing:

1. **Run-to-run bias change**: the unit powered up with another bias — every raw gyro sample shifted by
   --shift times the rest noise σ (the per-sample standard deviation of the gyro at rest, measured on
   the recording's own rests with the reference), alternating sign per axis. Rate error (RMS of
   output − reference [°/s], per sample and of 1 s means) after 10 minutes, against "the unit
   calibrated that day": the same recording without the shift (its calibration is right), at the same
   setting of the learning.
2. **No harm**: a correctly calibrated unit over --hour minutes: the largest change learning makes to
   the rate (1 s means, against σ/√(rate·1 s), the noise of a 1 s mean, and against σ) and to the
   attitude (roll, pitch, yaw, against the attitude's own error RMS).

Usage: OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bias_learning.py [--minutes 20] [--hour 60] [--shift 5] [--rest 10]
"""
from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from contract.layout import OUTPUTS, settings_array  # noqa: E402
from training.artefact import coefficients_array, settings_dict  # noqa: E402
from training.evaluate import attitude_errors  # noqa: E402
from training.main_job import SCENARIO_DIR  # noqa: E402
from training.runtime import run_batch  # noqa: E402
from training.simulator import load_scenario, simulate  # noqa: E402
from training.simulator.segments import Handheld  # noqa: E402
from training.train import train  # noqa: E402

RATE = slice(OUTPUTS.index("rate_x"), OUTPUTS.index("rate_x") + 3)
SHIFT = OUTPUTS.index("bias_learning_shift")
#: The acceptance's time: the error is measured after this many seconds of use.
SETTLE_S = 600.0


def stretched(scenario, minutes: float, rest_s: float, move_s: float = 20.0):
    """The scenario with its hand-held segments stretched so that it lasts `minutes`, rest_s [s] rests
    after move_s [s] moves (same motion statistics; the other segments, the temperature ramp's end
    points and the sensor unchanged)."""
    handheld = [seg for seg in scenario.segments if isinstance(seg, Handheld)]
    other_s = sum(seg.duration_s for seg in scenario.segments if not isinstance(seg, Handheld))
    total = (60.0 * minutes - other_s) / len(handheld)
    return replace(scenario, segments=tuple(
        replace(seg, total_s=total, rest_s=rest_s, move_s=move_s) if isinstance(seg, Handheld) else seg
        for seg in scenario.segments))


def run(artefact, data, gyr_shift=None, **overrides) -> np.ndarray:
    """Batch-runtime outputs at train's settings with `overrides`, the raw gyro shifted by gyr_shift [rad/s]."""
    values = settings_dict(artefact)
    values.update(overrides)
    inputs = data.inputs()
    if gyr_shift is not None:
        inputs[:, 0:3] += gyr_shift
    return run_batch(coefficients_array(artefact), np.asarray(settings_array(values)), data.t, inputs)


def rest_sigma(data) -> float:
    """Per-sample σ [rad/s] of the raw gyro at the recording's rests (true rate 0), largest axis, about
    each rest's own mean (the bias is not noise)."""
    still = np.all(np.abs(data.ref_gyr) < 1e-9, axis=1)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], still.astype(int), [0]])))
    pieces = [data.gyr[a:b] - data.gyr[a:b].mean(axis=0) for a, b in zip(edges[::2], edges[1::2]) if b - a > 50]
    return float(np.max(np.std(np.concatenate(pieces), axis=0)))


def second_means(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    """1 s means of x (N, k)."""
    idx = np.floor(t - t[0]).astype(int)
    return np.array([x[idx == k].mean(axis=0) for k in np.unique(idx)])


def rate_errors(data, out, start_s: float) -> tuple[float, float]:
    """(per-sample RMS, RMS of 1 s means) of rate output − reference [°/s] from start_s on."""
    sel = data.t >= start_s
    e = out[sel, RATE] - data.ref_gyr[sel]
    return float(np.degrees(np.sqrt(np.mean(e ** 2)))), float(np.degrees(np.sqrt(np.mean(second_means(data.t[sel], e) ** 2))))


def run_to_run(artefact, data, shift_sigmas: float) -> None:
    sigma = rest_sigma(data)
    shift = shift_sigmas * sigma * np.array([1.0, -1.0, 1.0])
    print(f"rest noise σ {np.degrees(sigma):.4f} °/s per sample; power-up bias shifted by {shift_sigmas:g} σ = "
          f"{np.degrees(shift_sigmas * sigma):.4f} °/s per axis (+, −, +); bias_learning_limit "
          f"{np.degrees(artefact.settings.get('bias_learning_limit', np.nan)):.4f} °/s\n")
    print("| unit | bias learning | rate error after 10 min [°/s] | ÷ calibrated that day | 1 s means [°/s] "
          "| ÷ calibrated that day | learnt shift at the end [°/s] |")
    print("|---|---|---|---|---|---|---|")
    same_day = {on: run(artefact, data, bias_learning=float(on)) for on in (1, 0)}
    rows = [("calibrated that day", on, same_day[on]) for on in (1, 0)]
    rows += [("powered up with another bias", on, run(artefact, data, shift, bias_learning=float(on))) for on in (1, 0)]
    for label, on, out in rows:
        (sample, second), (ref_sample, ref_second) = (rate_errors(data, x, SETTLE_S) for x in (out, same_day[on]))
        print(f"| {label} | {'on' if on else 'off'} | {sample:.4f} | {sample / ref_sample:.2f} | {second:.4f} | "
              f"{second / ref_second:.2f} | {np.degrees(out[-1, SHIFT]):.4f} |")


def no_harm(artefact, data) -> None:
    sigma = rest_sigma(data)
    on, off = run(artefact, data, bias_learning=1.0), run(artefact, data, bias_learning=0.0)
    rate = np.degrees(np.max(np.abs(second_means(data.t, on[:, RATE] - off[:, RATE]))))
    sample = np.degrees(np.max(np.abs(on[:, RATE] - off[:, RATE])))
    e_on, e_off = np.degrees(attitude_errors(on, data)), np.degrees(attitude_errors(off, data))
    change = np.degrees(np.max(np.abs(np.angle(np.exp(1j * np.radians(e_on - e_off)))), axis=0))
    print(f"\ncorrectly calibrated unit, {data.t[-1] / 60:.0f} min, learning on vs off:")
    print(f"- rate: largest change of a 1 s mean {rate:.4f} °/s, of a sample {sample:.4f} °/s (rest noise σ "
          f"{np.degrees(sigma):.4f} °/s per sample, {np.degrees(sigma) / 10:.4f} °/s for a 1 s mean at 100 Hz)")
    print(f"- attitude: largest change roll / pitch / yaw {change[0]:.3f} / {change[1]:.3f} / {change[2]:.3f}°; "
          f"error RMS off {np.sqrt(np.nanmean(e_off ** 2, axis=0)).round(3).tolist()}°, on "
          f"{np.sqrt(np.nanmean(e_on ** 2, axis=0)).round(3).tolist()}°")
    print(f"- learnt shift at the end {np.degrees(on[-1, SHIFT]):.4f} °/s, largest {np.degrees(np.max(on[:, SHIFT])):.4f} °/s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=20.0, help="length of the run-to-run recording [min]")
    parser.add_argument("--hour", type=float, default=60.0, help="length of the no-harm recording [min]")
    parser.add_argument("--shift", type=float, default=5.0, help="power-up bias change in rest-noise σ")
    parser.add_argument("--rest", type=float, default=10.0, help="rest after every 20 s move [s]")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    artefact = train([simulate(load_scenario(SCENARIO_DIR / "calibration.toml"), seed=args.seed)], seed=args.seed,
                     progress=False)
    handheld = load_scenario(SCENARIO_DIR / "eval_handheld.toml")
    run_to_run(artefact, simulate(stretched(handheld, args.minutes, args.rest), seed=args.seed + 1), args.shift)
    no_harm(artefact, simulate(stretched(handheld, args.hour, args.rest), seed=args.seed + 2))


if __name__ == "__main__":
    main()
