"""Every attitude mode recovers from a transient within a bounded time (issue 15, item 4).

On the eval_handheld scenario the gyro or the clock glitches once at 60 s: (a) one gyro sample of
34.9 rad/s (2000 °/s, a typical MEMS full scale) on one axis, (b) five such samples in a row,
(c) 1 s of rows dropped (the next sample comes 1 s late and the motion in between was never
measured), (d) one sample whose time stamp jumps by 1 s while every sample is kept (the rate of
that sample is integrated over 1 s although the body turned only for one sample interval), (e) the
same with a jump of one hour (a logger paused mid-file). Each
is run in every attitude mode through the batch runtime, with the identity model on sensors at
the residual error level of a calibrated MEMS unit (as tests/test_runtime.py's accuracy tests:
the attitude filter is under test, not the calibration).

The adaptive-gain Euler fusion used to lock up after such a glitch (its measurement variance
tracked the innovation² of its own error, the gain fell to ~1e-4): 19° over 70–80 s after one
spike, 100° after five, and still 11° / 93° after three minutes (clean: 0.9° / 1.6°).
"""
from __future__ import annotations

import numpy as np
import pytest

from contract import layout
from training import runtime
from training.data.reference import reference_quaternion_magnetic
from training.frames import quat_multiply
from training.main_job import SCENARIO_DIR
from training.simulator import load_scenario, simulate

GLITCH_S = 60.0                  # s, time of the glitch
SPIKE_RATE = 34.9                # rad/s, 2000 °/s: the full scale of common MEMS gyros
GAP_S = 1.0                      # s, rows dropped (c) / time jump (d)
#: Window right after recovery: 10 s after the glitch is the recovery time the docs promise.
RECOVERY_WINDOW_S = (70.0, 80.0)
#: Over 70–80 s the error may be at most twice the clean run's over the same window: the filter
#: restarts its corrections from accelerometer/magnetometer readings taken during motion, whose
#: linear-acceleration error (1.5 m/s² RMS in this scenario, several degrees of tilt) is averaged
#: down over the next seconds but not completely within 10 s; the clean run's error there is
#: about 0.7° (Euler) and 1.6° (quaternion), so 2x leaves 0.7–1.6° of such residual and rejects
#: any lock-up (the old Euler fusion: 19–100°).
RECOVERY_RATIO = 2.0
#: Window long after the glitch: nothing of it may remain. The state after a glitch is not the
#: clean run's state (other gains and low-pass histories), so the error follows a different but
#: equally good path: 1.5x allows for that and still rejects a lasting offset (old: 7–60x).
SETTLED_WINDOW_S = (180.0, 240.0)
SETTLED_RATIO = 1.5
#: Euler mode as the method defines it (tests/test_runtime.py EULER_METHOD), its rates integrated with
#: the trapezoidal rule its additions were measured with (gyro_hold = 0: with 1 the trapezoid addition
#: has nothing to act on); quaternion mode with every setting at its default.
MODES = {"euler": {"attitude_mode": 0.0, "rest_gyro_threshold": 0.0, "gyro_hold": 0.0},
         "quaternion": {"attitude_mode": 1.0}}
CASES = ("spike", "five_spikes", "rows_dropped", "time_jump", "hour_gap")
#: s, the clock of case (e) jumps by an hour (a logger paused mid-file; issue 15: "a 1-h gap is
#: reported and the attitude after it is as good as at the start").
HOUR_S = 3600.0


@pytest.fixture(scope="module")
def data():
    """eval_handheld with calibrated-grade sensor errors: gyro white noise 0.03 °/s per sample and
    residual bias 0.01 °/s, acc noise and bias 0.02 m/s², field noise and offset 0.5 µT."""
    d = simulate(load_scenario(SCENARIO_DIR / "eval_handheld.toml"))
    rng = np.random.default_rng(0)

    def unit():
        v = rng.normal(size=3)
        return v / np.linalg.norm(v)
    n = len(d)
    d.gyr = d.ref_gyr + np.radians(0.01) * np.sign(rng.normal(size=3)) \
        + np.radians(0.03) * rng.normal(size=(n, 3))
    d.acc = d.ref_acc + 0.02 * unit() + 0.02 * rng.normal(size=(n, 3))
    d.mag = d.ref_mag + 0.5 * unit() + 0.5 * rng.normal(size=(n, 3))
    return d


def glitched(d, case: str):
    """(runtime times, runtime inputs, trajectory times, kept rows) of one glitch case."""
    t, x, keep = d.t.copy(), d.inputs().copy(), np.ones(len(d), bool)
    k = int(np.searchsorted(d.t, GLITCH_S))
    if case == "spike":
        x[k, 0] = SPIKE_RATE
    elif case == "five_spikes":
        x[k:k + 5, 0] = SPIKE_RATE
    elif case == "rows_dropped":
        keep &= (d.t < GLITCH_S) | (d.t >= GLITCH_S + GAP_S)
    elif case == "time_jump":
        t[k:] += GAP_S           # the clock jumps; the samples and their truth stay the same
    elif case == "hour_gap":
        t[k:] += HOUR_S
    elif case != "clean":
        raise ValueError(case)
    return t[keep], x[keep], d.t[keep], keep


def total_error_deg(d, mode: str, case: str):
    """Trajectory times [s] and total attitude error [°] (angle of q_est ⊗ q_ref⁻¹) of one run."""
    t, x, t_traj, keep = glitched(d, case)
    settings = np.array(layout.settings_array({"field_norm": d.field_norm_ut, **MODES[mode]}))
    out = runtime.run_batch(np.array(layout.identity_coefficients()), settings, t, x)
    cols = [layout.OUTPUTS.index(c) for c in ("q_w", "q_x", "q_y", "q_z")]
    q_ref_inv = reference_quaternion_magnetic(d)[keep] * np.array([1.0, -1.0, -1.0, -1.0])
    w = np.abs(quat_multiply(out[:, cols], q_ref_inv)[:, 0])
    return t_traj, np.degrees(2.0 * np.arccos(np.clip(w, 0.0, 1.0)))


def window_mean(t, e, window):
    m = (t >= window[0]) & (t < window[1])
    return float(e[m].mean())


@pytest.fixture(scope="module")
def clean(data):
    return {mode: total_error_deg(data, mode, "clean") for mode in MODES}


@pytest.mark.parametrize("case", CASES)
@pytest.mark.parametrize("mode", MODES)
def test_recovers_within_ten_seconds(data, clean, mode, case):
    t, e = total_error_deg(data, mode, case)
    tc, ec = clean[mode]
    recovery = window_mean(t, e, RECOVERY_WINDOW_S), window_mean(tc, ec, RECOVERY_WINDOW_S)
    settled = window_mean(t, e, SETTLED_WINDOW_S), window_mean(tc, ec, SETTLED_WINDOW_S)
    assert recovery[0] <= RECOVERY_RATIO * recovery[1], (mode, case, "70-80 s [deg] glitch/clean", recovery)
    assert settled[0] <= SETTLED_RATIO * settled[1], (mode, case, "180-240 s [deg] glitch/clean", settled)


BROAD_FAST_TRANSLATION = "18_undisturbed_fast_translation_with_breaks_B.csv.gz"
#: °: total RMSE bound of the Euler fusion with rest bias on BROAD's fast-translation trial 18. Before
#: the recovery bound it scored 1.30° (VQF 9D 0.81°); counting every rate change between two samples
#: as a possible glitch raised its gain through the whole fast motion and gave 36.2°. 3° leaves room
#: for the method's own variations and fails any gain that trusts the accelerometer during motion.
BROAD_EULER_BOUND_DEG = 3.0


def test_the_glitch_bound_ignores_smooth_fast_motion_on_measured_data(broad_trial):
    from training.bench import bench
    from training.data.io import read_imu_csv
    data = read_imu_csv(broad_trial(BROAD_FAST_TRANSLATION))
    q = bench.run_imufusion(data, bench.ABLATION["Euler adaptive gains + rest bias"])
    assert bench.broad_errors(q, data)["total"] < BROAD_EULER_BOUND_DEG
