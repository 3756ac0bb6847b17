"""The particle filter recovers from in-range magnetometer glitches (issue 15, item 5).

A fuzzing campaign found that a few samples of a wrong but plausible field (not NaN, not saturated)
made the Rao-Blackwellised filter declare a change of environment that never reverted: the hard
iron went from 0 to several µT and stayed there, and 8 of 14 fuzz episodes ended more than 2° off.
Cause (docs/magpf.md, "Glitches and the trained calibration"): four updates of clipped innovations
declared a change, from however few field directions (a stuck reading: one); the declared change
dropped the trained calibration for good and re-estimated from what followed — and a handheld
recording's field directions cover only a cap of the sphere, on which the hard iron along the cap's
axis and the soft iron trade off, so the re-estimate settled several µT off (and with it the
heading). The 9-state filter kept a wrong reading in its direction buffer for good when the motion
never returned to that direction.

Here a seeded glitch generator corrupts the magnetometer of the eval_handheld simulation (a
calibrated sensor: truth hard iron 0, the identity calibration held as the filter's prior), and the
whole C runtime runs it with the filter on, in both filter modes and both attitude modes.
"""
from __future__ import annotations

import numpy as np
import pytest

from contract import layout
from training import runtime
from training.data.reference import reference_quaternion_magnetic
from training.frames import quat_multiply
from training.models import pf_settings
from training.simulator import load_scenario, simulate

SCENARIOS = layout.__file__.rsplit("/contract/", 1)[0] + "/scenarios"
GLITCH_S = 60.0                  # s, time of the glitch of the recovery cases
#: Wrong but plausible fields: a random direction and a norm within ±NORM_SPREAD of |h_0|.
NORM_SPREAD = 0.5
BURST_SAMPLES = 5
HELD_S = 1.0                     # s, duration of the constant wrong field and of the dropout
KINDS = ("spike", "burst", "constant", "dropout", "disturbance")
#: Field noise per axis [µT] of the simulated calibrated magnetometer (gyro/acc as in
#: tests/test_attitude_recovery.py: the filter under test, not the calibration).
FIELD_NOISE_UT = 0.5
#: 10 s after the glitch (the recovery time of tests/test_attitude_recovery.py) the attitude error
#: over 70–80 s is at most twice the clean run's over the same window (same reasoning as there).
RECOVERY_WINDOW_S = (70.0, 80.0)
RECOVERY_RATIO = 2.0
#: Hard-iron bound 10 s after a glitch [µT]. Rao-Blackwellised mode holds the trained calibration
#: (the truth here) and must be back on it exactly. The 9-state filter adapts from the start and
#: on this recording's cap of field directions wanders by up to ~1 µT without any glitch (its
#: clean run: 0.85 µT at most); 1.5 µT (3 noise σ) still rejects a glitch it kept (old: 1–2 µT
#: lasting), and is 2 % of |h_0|, ~1.7° of heading at the most.
HARD_BOUND_UT = {"rao_blackwell": 0.0, "nine_state": 1.5}
FILTER_MODES = {"rao_blackwell": 1.0, "nine_state": 0.0}
ATTITUDE_MODES = {"euler": {"attitude_mode": 0.0, "rest_gyro_threshold": 0.0},
                  "quaternion": {"attitude_mode": 1.0}}
#: Fuzz campaign: episodes × glitches of random kinds at random times in FUZZ_SPAN_S; the issue's
#: figure is the attitude error at the end (mean over the last FUZZ_END_S), < 2° in every episode.
#: (The 9-state filter with the Euler fusion is the tightest pair: on the clean recording alone it
#: ends at 0.2–1.75° over filter seeds 1–14, its estimate wandering by ~0.5 µT.)
FUZZ_EPISODES = 14
FUZZ_GLITCHES = 6
FUZZ_SPAN_S = (10.0, 220.0)
FUZZ_END_S = 5.0
FUZZ_BOUND_DEG = 2.0


def wrong_field(rng: np.random.Generator, norm_ut: float) -> np.ndarray:
    """A plausible but wrong field [µT]: uniform direction, norm uniform in (1 ± NORM_SPREAD)·|h_0|."""
    v = rng.normal(size=3)
    return v / np.linalg.norm(v) * norm_ut * rng.uniform(1.0 - NORM_SPREAD, 1.0 + NORM_SPREAD)


def add_glitch(mag: np.ndarray, kind: str, start: int, rate_hz: float, norm_ut: float,
               rng: np.random.Generator) -> np.ndarray:
    """mag (N, 3) µT with one glitch at row `start`: a single wrong sample ("spike"), BURST_SAMPLES
    independent wrong samples ("burst"), HELD_S of one wrong constant field ("constant", a stuck
    reading), HELD_S of NaN ("dropout") or HELD_S of independent wrong samples ("disturbance": long and
    varied enough to be declared a change of environment)."""
    out = mag.copy()
    held = int(round(HELD_S * rate_hz))
    if kind == "spike":
        out[start] = wrong_field(rng, norm_ut)
    elif kind == "burst":
        out[start:start + BURST_SAMPLES] = [wrong_field(rng, norm_ut) for _ in range(BURST_SAMPLES)]
    elif kind == "constant":
        out[start:start + held] = wrong_field(rng, norm_ut)
    elif kind == "dropout":
        out[start:start + held] = np.nan
    elif kind == "disturbance":
        out[start:start + held] = [wrong_field(rng, norm_ut) for _ in range(held)]
    else:
        raise ValueError(f"unknown glitch kind '{kind}' (known: {', '.join(KINDS)})")
    return out


def fuzz_episode(mag: np.ndarray, seed: int, rate_hz: float, norm_ut: float) -> np.ndarray:
    """FUZZ_GLITCHES glitches of seeded random kinds at seeded random times in FUZZ_SPAN_S."""
    rng = np.random.default_rng(seed)
    starts = rng.uniform(*FUZZ_SPAN_S, size=FUZZ_GLITCHES)
    for start in np.sort(starts):
        mag = add_glitch(mag, KINDS[rng.integers(len(KINDS))], int(start * rate_hz), rate_hz, norm_ut, rng)
    return mag


def handheld():
    """eval_handheld with calibrated-grade sensors (gyro 0.03 °/s noise, 0.01 °/s bias; acc 0.02 m/s²
    noise and bias; field noise FIELD_NOISE_UT, no residual hard or soft iron)."""
    d = simulate(load_scenario(f"{SCENARIOS}/eval_handheld.toml"))
    rng = np.random.default_rng(0)
    n = len(d)
    unit = rng.normal(size=3)
    d.gyr = d.ref_gyr + np.radians(0.01) * np.sign(rng.normal(size=3)) + np.radians(0.03) * rng.normal(size=(n, 3))
    d.acc = d.ref_acc + 0.02 * unit / np.linalg.norm(unit) + 0.02 * rng.normal(size=(n, 3))
    d.mag = d.ref_mag + FIELD_NOISE_UT * rng.normal(size=(n, 3))
    return d


def sample_rate_hz(d) -> float:
    return float(1.0 / np.median(np.diff(d.t)))


def trained_pf_settings(d) -> dict:
    """The filter settings `train` derives from the clean field."""
    return pf_settings.pf_settings_from_calibration(d.mag, d.t, d.field_norm_ut, sample_rate_hz(d))


@pytest.fixture(scope="module")
def data():
    return handheld()


@pytest.fixture(scope="module")
def rate_hz(data) -> float:
    return sample_rate_hz(data)


@pytest.fixture(scope="module")
def pf(data) -> dict:
    return trained_pf_settings(data)


def run(d, pf: dict, mag: np.ndarray, filter_mode: str, attitude_mode: str):
    """(attitude error [°] per sample, hard-iron estimate (N, 3) [µT]) of the runtime on field mag."""
    x = d.inputs().copy()
    x[:, 6:9] = mag
    settings = layout.settings_array({"field_norm": d.field_norm_ut, "enable_pf": 1.0,
                                      "pf_rao_blackwell": FILTER_MODES[filter_mode],
                                      **ATTITUDE_MODES[attitude_mode], **pf})
    out = runtime.run_batch(np.array(layout.identity_coefficients()), np.array(settings), d.t, x)
    q = out[:, [layout.OUTPUTS.index(c) for c in ("q_w", "q_x", "q_y", "q_z")]]
    w = np.abs(quat_multiply(q, reference_quaternion_magnetic(d) * np.array([1.0, -1.0, -1.0, -1.0]))[:, 0])
    hard = out[:, [layout.OUTPUTS.index(f"hard_iron_{a}") for a in "xyz"]]
    return np.degrees(2.0 * np.arccos(np.clip(w, 0.0, 1.0))), hard


def window_mean(t, e, window) -> float:
    return float(e[(t >= window[0]) & (t < window[1])].mean())


def test_generator_is_seeded_and_in_range():
    mag = np.tile([30.0, 0.0, 40.0], (500, 1))
    a = fuzz_episode(mag, 3, 1.0, 50.0)
    np.testing.assert_array_equal(a, fuzz_episode(mag, 3, 1.0, 50.0))
    assert not np.array_equal(a, fuzz_episode(mag, 4, 1.0, 50.0))
    norms = np.linalg.norm(add_glitch(mag, "burst", 10, 100.0, 50.0, np.random.default_rng(0))[10:15], axis=1)
    assert np.all((norms >= 25.0) & (norms <= 75.0))
    stuck = add_glitch(mag, "constant", 10, 100.0, 50.0, np.random.default_rng(0))
    assert np.all(stuck[10:110] == stuck[10]) and np.all(stuck[110] == mag[110])
    assert np.isnan(add_glitch(mag, "dropout", 10, 100.0, 50.0, np.random.default_rng(0))[10:110]).all()


@pytest.fixture(scope="module")
def clean(data, pf):
    return {(f, a): run(data, pf, data.mag, f, a) for f in FILTER_MODES for a in ATTITUDE_MODES}


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("attitude_mode", ATTITUDE_MODES)
@pytest.mark.parametrize("filter_mode", FILTER_MODES)
def test_recovers_from_a_glitch_within_ten_seconds(data, rate_hz, pf, clean, filter_mode, attitude_mode, kind):
    k = int(np.searchsorted(data.t, GLITCH_S))
    mag = add_glitch(data.mag, kind, k, rate_hz, data.field_norm_ut, np.random.default_rng(7))
    e, hard = run(data, pf, mag, filter_mode, attitude_mode)
    ec, _ = clean[filter_mode, attitude_mode]
    after = int(np.searchsorted(data.t, RECOVERY_WINDOW_S[0]))
    assert np.abs(hard[after]).max() <= HARD_BOUND_UT[filter_mode], (kind, hard[after])
    recovery = window_mean(data.t, e, RECOVERY_WINDOW_S), window_mean(data.t, ec, RECOVERY_WINDOW_S)
    assert recovery[0] <= RECOVERY_RATIO * recovery[1], (kind, "70-80 s [deg] glitch/clean", recovery)


@pytest.mark.parametrize("attitude_mode", ATTITUDE_MODES)
@pytest.mark.parametrize("filter_mode", FILTER_MODES)
def test_fuzz_episodes_end_within_two_degrees(data, rate_hz, pf, filter_mode, attitude_mode):
    end = data.t >= data.t[-1] - FUZZ_END_S
    attitude, hard_iron = [], []
    for seed in range(FUZZ_EPISODES):
        mag = fuzz_episode(data.mag, seed, rate_hz, data.field_norm_ut)
        e, hard = run(data, pf, mag, filter_mode, attitude_mode)
        attitude.append(float(e[end].mean()))
        hard_iron.append(float(np.abs(hard[-1]).max()))
    assert max(hard_iron) <= HARD_BOUND_UT[filter_mode], hard_iron
    assert max(attitude) < FUZZ_BOUND_DEG, attitude
