"""The numpy twin of the quaternion attitude filter (training.models.attitude_twin) equals the C filter the FMU
runs, sample for sample, on a real recording (BROAD: hand-held motion, rests, an undisturbed field) and
on a simulated one whose field is disturbed part of the time, for both gyro_hold rules, in 6D
(mag_heading = 0) and without the bias estimate in motion (motion_bias = 0); the output mag_disturbed equals the twin's rejection flag. The C filter runs
inside the pipeline with the identity calibration, so its inputs are the raw samples.

Bound: 1e-9 rad between the two attitudes. Both compute the same double-precision operations in a
different order; over 6 000 samples the rounding differences stay below 1e-12 rad, while any change of
a formula, constant or branch moves the attitude by far more (a constant changed in its 4th digit:
> 1e-6 rad)."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from contract import layout
from training.models import attitude_twin
from training.runtime import run_batch

from rigid_motion import FIELD_NED, ideal_readings

ROOT = Path(__file__).resolve().parents[1]
BROAD = ROOT.parent / "shared" / "data" / "broad" / "04_undisturbed_slow_rotation_with_breaks_A.csv.gz"
BOUND_RAD = 1e-9
#: Twin constant -> (C file, macro): the values must agree.
CONSTANTS = {
    "GRAVITY": ("ImuAttitude.h", "IMU_ATTITUDE_GRAVITY"),
    "REST_BIAS_TIME": ("ImuAttitude.c", "IMU_ATTITUDE_REST_BIAS_TIME"),
    "REST_FILTER_TIME": ("ImuRestDetector.h", "IMU_REST_FILTER_TIME"),
    "REST_MIN_TIME": ("ImuRestDetector.h", "IMU_REST_MIN_TIME"),
    "UNTRACKED_MOTION": ("ImuAttitudePrivate.h", "IMU_ATTITUDE_UNTRACKED_MOTION"),
    "RESTART_VARIANCE": ("ImuAttitudePrivate.h", "IMU_ATTITUDE_RESTART_VARIANCE"),
    "MISSING_STEPS": ("ImuAttitudeStep.c", "IMU_ATTITUDE_MISSING_STEPS"),
    "SMOOTH_ANGULAR_ACCEL": ("ImuAttitudeStep.c", "IMU_ATTITUDE_SMOOTH_ANGULAR_ACCEL"),
    "MAG_NORM_TOLERANCE": ("ImuAttitudeQuaternion.c", "IMU_ATTITUDE_MAG_NORM_TOLERANCE"),
    "MAG_DIP_TOLERANCE": ("ImuAttitudeQuaternion.c", "IMU_ATTITUDE_MAG_DIP_TOLERANCE"),
    "MAG_RECOVERY": ("ImuAttitudeQuaternion.c", "IMU_ATTITUDE_MAG_RECOVERY"),
    "MAG_MIN_CLEAN_TIME": ("ImuAttitudePrivate.h", "IMU_ATTITUDE_MAG_MIN_CLEAN_TIME"),
    "STEP_HISTORY": ("ImuGuard.h", "IMU_GUARD_STEP_HISTORY"),
    **{name: ("ImuMotionBias.c", f"IMU_MOTION_BIAS_{name[5:]}") for name in (
        "BIAS_SIGMA_INIT", "BIAS_FORGETTING_TIME", "BIAS_SIGMA_MOTION", "BIAS_VERTICAL_FORGETTING", "BIAS_CLIP")},
}


def _c_outputs(settings: dict, t, gyr, acc, mag) -> np.ndarray:
    """The C pipeline's outputs with the identity calibration and without the bias learning (a stage before
    the attitude filter, tests/test_bias_learning.py), so the filter sees the raw samples as the twin does."""
    inputs = np.zeros((len(t), len(layout.INPUTS)))
    inputs[:, 0:3], inputs[:, 3:6], inputs[:, 6:9], inputs[:, 9] = gyr, acc, mag, 25.0
    return run_batch(layout.identity_coefficients(), layout.settings_array({**settings, "bias_learning": 0.0}), t,
                     inputs)


def _angle(q1: np.ndarray, q2: np.ndarray) -> float:
    """Largest rotation angle [rad] between two quaternion series (from the vector part of q1* ⊗ q2,
    precise near 0 where arccos is not)."""
    from training.frames import quat_multiply
    d = quat_multiply(q1 * np.array([1.0, -1.0, -1.0, -1.0]), q2)
    return float(np.max(2.0 * np.arctan2(np.linalg.norm(d[:, 1:], axis=1), np.abs(d[:, 0]))))


def _broad_slice():
    if not BROAD.exists():
        pytest.fail(f"{BROAD} is missing: the tests need ../shared beside the repository")
    from training.data.io import read_imu_csv
    d = read_imu_csv(BROAD).slice(slice(0, 6000))
    return d.t - d.t[0], d.gyr, d.acc, d.mag, {"field_norm": float(np.median(np.linalg.norm(d.mag, axis=1)))}


def _disturbed_simulation():
    """A still start, turns and tilts, a field 30 % stronger for 10 s (a nearby magnet: longer than the
    8 s mag_reject_time, so it is accepted in the end), again for 6 s after 3 s of clean field (the
    rejection budget left then depends on the recovery) and for 1 s after 3 s more (rejected, and for
    IMU_ATTITUDE_MAG_MIN_CLEAN_TIME after it). One sample is stamped 10 µs after the one before it (a
    short step is not the nominal step) and the time after another runs one step late (a lost sample: a step of two nominal ones)."""
    rng = np.random.default_rng(7)
    n, dt = 6000, 0.01
    t = np.arange(n) * dt
    rate = np.zeros((n, 3))
    rate[300:, 0] = 0.8 * np.sin(0.9 * t[300:])
    rate[300:, 2] = 1.2 * np.sin(0.37 * t[300:] + 0.4)
    _, acc, mag = ideal_readings(rate, dt)
    mag[3000:4000] *= 1.3
    mag[4300:4900] *= 1.3
    mag[5200:5300] *= 1.3
    gyr = rate + 0.01 + 0.002 * rng.standard_normal((n, 3))
    acc = acc + 0.05 * rng.standard_normal((n, 3))
    mag = mag + 0.3 * rng.standard_normal((n, 3))
    t[1500] = t[1499] + 1e-5
    t[2500:] += dt
    return t, gyr, acc, mag, {"field_norm": float(np.linalg.norm(FIELD_NED)),
                              "field_dip": float(np.arctan2(FIELD_NED[2], FIELD_NED[0])), "mag_reject_time": 8.0}


@pytest.mark.parametrize("options", [{"gyro_hold": 1.0}, {"gyro_hold": 0.0}, {"mag_heading": 0.0},
                                     {"motion_bias": 0.0}, {"acc_norm_tolerance": 0.008}],
                         ids=["gyro_hold", "trapezoid", "6D", "rest_bias_only", "acc_norm_tolerance"])
@pytest.mark.parametrize("recording", [_broad_slice, _disturbed_simulation], ids=["broad", "disturbed"])
def test_twin_equals_the_c_filter(recording, options):
    t, gyr, acc, mag, extra = recording()
    settings = {**layout.settings_defaults(), **extra, **options, "attitude_mode": 1.0}
    out = _c_outputs(settings, t, gyr, acc, mag)
    q_c = out[:, [layout.OUTPUTS.index(n) for n in ("q_w", "q_x", "q_y", "q_z")]]
    q_c = q_c * np.where(q_c[:, :1] < 0.0, -1.0, 1.0)
    f = attitude_twin.QuaternionFilter(settings)
    steps = np.diff(t, prepend=t[0])
    nominal = attitude_twin.nominal_steps(steps)
    q_twin, disturbed = [], []
    for k in range(len(t)):
        q_twin.append(f.update(gyr[k], acc[k], mag[k], float(steps[k]), nominal[k]))
        disturbed.append(float(f.mag_disturbed))
    assert _angle(q_c, np.array(q_twin)) < BOUND_RAD
    assert np.array_equal(out[:, layout.OUTPUTS.index("mag_disturbed")], np.array(disturbed))


def test_the_disturbed_field_is_rejected_and_said():
    """The simulated magnet (field 30 % too strong) is rejected for mag_reject_time, then accepted; the
    second one is rejected again, the third, short one until the field has been clean for 0.5 s (the
    cases the comparison above covers, checked to be exercised), and
    the FMU's output mag_disturbed is 1 exactly while a field is rejected."""
    t, gyr, acc, mag, extra = _disturbed_simulation()
    settings = {**layout.settings_defaults(), **extra, "attitude_mode": 1.0}
    f = attitude_twin.QuaternionFilter(settings)
    rejected = []
    steps = np.diff(t, prepend=t[0])
    nominal = attitude_twin.nominal_steps(steps)
    for k in range(len(t)):
        f.update(gyr[k], acc[k], mag[k], float(steps[k]), nominal[k])
        rejected.append(f.mag_rejected)
    rejected = np.array(rejected)
    said = _c_outputs(settings, t, gyr, acc, mag)[:, layout.OUTPUTS.index("mag_disturbed")]
    assert np.all(said[3010:3790] == 1.0) and np.all(said[3900:4000] == 0.0) and np.all(said[:3000] == 0.0)
    assert np.all(rejected[3010:3790] > 0.0) and rejected[3999] >= 8.0   # budget used up: accepted
    assert rejected[4299] < 4.0                                           # recovered in the clean 3 s
    assert np.all(rejected[4310:4400] > rejected[4299])                   # rejected again
    assert np.all(said[5201:5345] == 1.0) and np.all(said[5355:5500] == 0.0)  # and 0.5 s after it ends


@pytest.mark.parametrize("name", sorted(CONSTANTS))
def test_twin_constants_equal_the_c_sources(name):
    path, macro = CONSTANTS[name]
    text = (ROOT / "sources" / path).read_text()
    match = re.search(rf"#define {macro} ([0-9.eE+-]+)", text)
    assert match, f"{macro} not found in sources/{path}"
    assert float(match.group(1)) == getattr(attitude_twin, name)
