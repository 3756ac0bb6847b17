"""Simulator: determinism, self-consistent truth, each sensor error term, scenario files, errors."""
from __future__ import annotations

from dataclasses import fields, is_dataclass, replace
from pathlib import Path

import numpy as np
import pytest

from contract.errors import ScenarioError
from training.data.earth import GRAVITY_NED, STANDARD_GRAVITY
from training.data.io import read_imu_csv, write_imu_csv
from training.frames import (quat_conjugate, quat_from_rotvec, quat_multiply, quat_to_matrix, quat_to_rotvec,
                             rotate_to_body)
from training.main_job import SCENARIO_DIR
from training.simulator import load_scenario, simulate, simulate_to_dir

SCENARIO_FILES = sorted(SCENARIO_DIR.glob("*.toml"))
DPS = np.pi / 180.0

#: LSBs so small that quantisation is invisible next to the bounds below [rad/s, m/s², µT].
FINE_LSB = {"gyr": "lsb_dps = 1e-9\nrange_dps = 2000.0",
            "acc": "lsb_ms2 = 1e-9\nrange_ms2 = 200.0",
            "mag": "lsb_ut = 1e-9\nrange_ut = 2000.0"}
#: The shared sensor's LSBs, for the error-free test (quantisation is all that remains).
REAL_LSB = {"gyr": "lsb_dps = 0.0152587890625\nrange_dps = 500.0",
            "acc": "lsb_ms2 = 0.00239420166015625\nrange_ms2 = 78.4532",
            "mag": "lsb_ut = 0.05\nrange_ut = 800.0"}

HANDHELD = """
[[segment]]
type = "handheld"
duration_s = 12.0
rest_s = 1.0
move_s = 4.5
ramp_s = 0.5
rate_rms_dps = 40.0
accel_rms_ms2 = 1.5
band_hz = [0.1, 1.0]
"""
POSITIONS = """
[[segment]]
type = "positions"
attitudes_deg = [[0, 0, 0], [90, 0, 180], [180, 90, 0], [45, 45, 30], [300, -60, -120], [0, 0, 0]]
hold_s = 1.0
move_s = 1.0
"""
ROTATIONS = """
[[segment]]
type = "rotations"
axes = ["x", "y", "z"]
rates_dps = [100.0, -100.0]
angle_deg = 180.0
ramp_s = 0.5
rest_s = 0.5
"""
FIGURE8 = """
[[segment]]
type = "figure8"
length_m = 4.0
width_m = 2.0
period_s = 10.0
laps = 1
ramp_s = 1.0
"""


def hold(duration_s: float, temp_end_c: float | None = None) -> str:
    """A [[segment]] hold, optionally ramping to temp_end_c."""
    ramp = "" if temp_end_c is None else f"temp_end_c = {temp_end_c}\n"
    return f'\n[[segment]]\ntype = "hold"\nduration_s = {duration_s}\n{ramp}'


def scenario_text(segments: str, errors: dict[str, str] | None = None, lsb=FINE_LSB,
                  rate_hz: float = 100.0, temp_c: float = 25.0, start: str = "") -> str:
    """A complete scenario with an inline sensor: `errors` holds extra TOML lines per triad."""
    errors = errors or {}
    sensor = "".join(f"\n[sensor.{k}]\n{lsb[k]}\n{errors.get(k, '')}\n" for k in ("gyr", "acc", "mag"))
    return (f'[scenario]\nname = "test"\nrate_hz = {rate_hz}\nseed = 7\n\n'
            f"[earth_field]\nnorm_ut = 50.0\ndip_deg = 60.0\ndeclination_deg = 3.0\n\n"
            f"[start]\ntemp_c = {temp_c}\n{start}\n"
            f'[sensor]\nname = "test_sensor"\n{sensor}{segments}')


def write(tmp_path: Path, text: str, name: str = "scenario.toml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def run(tmp_path: Path, *args, seed: int | None = None, **kwargs):
    """Load and simulate an inline scenario."""
    return simulate(load_scenario(write(tmp_path, scenario_text(*args, **kwargs))), seed)


def angle_between(q1: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """Rotation angle [rad] between two attitude series (N, 4)."""
    return np.linalg.norm(quat_to_rotvec(quat_multiply(quat_conjugate(q1), q2)), axis=1)


# ----------------------------------------------------------------------------- determinism

NOISY = {"gyr": "noise_density_dps_per_sqrt_hz = 0.003\nbias_walk_dps_per_sqrt_s = 2e-4",
         "acc": "noise_density_ms2_per_sqrt_hz = 1e-3",
         "mag": "noise_density_ut_per_sqrt_hz = 0.01"}


def test_same_seed_gives_identical_arrays_and_file_bytes(tmp_path):
    path = write(tmp_path, scenario_text(HANDHELD, NOISY))
    a, b = simulate(load_scenario(path), 3), simulate(load_scenario(path), 3)
    for name in ("t", "gyr", "acc", "mag", "temp", "ref_q", "ref_gyr", "ref_acc", "ref_mag"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    file_a, file_b = write_imu_csv(a, tmp_path / "a.csv.gz"), write_imu_csv(b, tmp_path / "b.csv.gz")
    assert file_a.read_bytes() == file_b.read_bytes()
    assert (tmp_path / "a.json").read_bytes() == (tmp_path / "b.json").read_bytes()


def test_seed_none_uses_the_scenario_seed_and_other_seeds_differ(tmp_path):
    scenario = load_scenario(write(tmp_path, scenario_text(HANDHELD, NOISY)))
    default, same, other = simulate(scenario), simulate(scenario, 7), simulate(scenario, 8)
    assert np.array_equal(default.gyr, same.gyr)
    assert not np.array_equal(default.gyr - default.ref_gyr, other.gyr - other.ref_gyr)
    assert default.meta["source"] == "ImuFusion simulator test, seed 7"


# ----------------------------------------------------------------------------- truth

#: Bound on the attitude error of re-integrating ref_gyr at 1 kHz [rad]. The test integrator
#: (trapezoidal rotation vector + coning term) errs by ≈ dt²/12 · Δω' per axis (the trapezoid's
#: local errors telescope): with |ω'| ≲ 21 rad/s² here and dt = 1 ms that is ≈ 4e-6 rad, plus
#: non-commutativity terms of the same order. A truth whose rate were off by only 0.1 % in
#: scale would miss by 1e-2 rad.
INTEGRATION_BOUND_RAD = 2e-5


def integrate_rate(q0: np.ndarray, rate: np.ndarray, dt: float) -> np.ndarray:
    """Integrate body rate (N, 3) from q0 with φ = (ω_k + ω_k+1) dt/2 + dt²/12 ω_k × ω_k+1."""
    steps = 0.5 * dt * (rate[:-1] + rate[1:]) + dt * dt / 12.0 * np.cross(rate[:-1], rate[1:])
    increments = quat_from_rotvec(steps)
    q = np.empty((rate.shape[0], 4))
    q[0] = q0
    for k, dq in enumerate(increments):
        q[k + 1] = quat_multiply(q[k], dq)
    return q


def test_integrated_ref_gyr_reproduces_ref_q(tmp_path):
    data = run(tmp_path, HANDHELD + POSITIONS + ROTATIONS + FIGURE8, rate_hz=1000.0)
    q = integrate_rate(data.ref_q[0], data.ref_gyr, 1e-3)
    assert np.max(angle_between(q, data.ref_q)) < INTEGRATION_BOUND_RAD


#: Rounding bound for vector identities on O(10–50) magnitudes in float64.
ROUNDING = 1e-9


def test_specific_force_and_field_are_gravity_and_earth_field_rotated(tmp_path):
    data = run(tmp_path, HANDHELD + POSITIONS + FIGURE8)
    r_nb = quat_to_matrix(data.ref_q)
    field_n = np.einsum("nij,nj->ni", r_nb, data.ref_mag)
    dip, decl = np.deg2rad(60.0), np.deg2rad(3.0)
    expected = 50.0 * np.array([np.cos(dip) * np.cos(decl), np.cos(dip) * np.sin(decl), np.sin(dip)])
    assert np.max(np.abs(field_n - expected)) < ROUNDING
    assert np.max(np.abs(np.linalg.norm(data.ref_mag, axis=1) - 50.0)) < ROUNDING
    at_rest = np.all(data.ref_gyr == 0.0, axis=1)
    assert at_rest.sum() > 500
    gravity_body = rotate_to_body(data.ref_q[at_rest], -GRAVITY_NED)
    assert np.max(np.abs(data.ref_acc[at_rest] - gravity_body)) < ROUNDING
    f, m = data.ref_acc[at_rest], data.ref_mag[at_rest]
    # down = −f/|f| at rest, so sin(dip) = −f·m / (|f| |m|)
    sin_dip = -np.sum(f * m, axis=1) / (np.linalg.norm(f, axis=1) * np.linalg.norm(m, axis=1))
    assert np.max(np.abs(np.rad2deg(np.arcsin(sin_dip)) - 60.0)) < ROUNDING
    assert np.allclose(data.ref_acc[0], [0.0, 0.0, -STANDARD_GRAVITY])


def test_handheld_motion_is_lively_but_keeps_pitch_bounded(tmp_path):
    data = run(tmp_path, HANDHELD * 3)
    w = data.ref_q
    pitch = np.rad2deg(np.arcsin(np.clip(2 * (w[:, 0] * w[:, 2] - w[:, 3] * w[:, 1]), -1, 1)))
    assert np.max(np.abs(pitch)) < 70.0
    assert 40.0 < np.rad2deg(np.max(np.abs(data.ref_gyr))) < 250.0
    moving = ~np.all(data.ref_gyr == 0.0, axis=1)
    translation = data.ref_acc + rotate_to_body(data.ref_q, GRAVITY_NED)   # R_nbᵀ a_n
    assert 0.5 < np.sqrt(np.mean(np.sum(translation[moving] ** 2, axis=1))) < 3.0


def test_temperature_profile_hits_breakpoints_and_warms_up(tmp_path):
    segments = hold(10.0) + hold(20.0, 45.0) + hold(10.0) + hold(20.0, 5.0)
    data = run(tmp_path, segments, temp_c=20.0)
    for t, temp in ((0.0, 20.0), (10.0, 20.0), (30.0, 45.0), (40.0, 45.0), (50.0, 25.0)):
        assert data.temp[np.flatnonzero(data.t == t)[0]] == pytest.approx(temp, abs=1e-12)
    warm = run(tmp_path, hold(30.0), temp_c=20.0, start="warmup_rise_c = 3.0\nwarmup_tau_s = 10.0\n")
    assert np.allclose(warm.temp, 20.0 + 3.0 * (1.0 - np.exp(-warm.t / 10.0)), atol=1e-12)


def test_segment_power_on_warms_up_then_decays(tmp_path):
    powered = '\n[[segment]]\ntype = "hold"\nduration_s = 20.0\nwarmup_rise_c = 4.0\nwarmup_tau_s = 5.0\n'
    scenario = load_scenario(write(tmp_path, scenario_text(hold(10.0) + powered + hold(30.0),
                                                           temp_c=20.0)))
    t = np.linspace(0.0, 59.9, 600)
    temp, rate = scenario.temperature_profile().evaluate(t)
    heat_end = 4.0 * (1.0 - np.exp(-20.0 / 5.0))
    expected = np.where(t < 10.0, 0.0, np.where(t < 30.0, 4.0 * (1.0 - np.exp(-(t - 10.0) / 5.0)),
                                                heat_end * np.exp(-(t - 30.0) / 5.0)))
    assert np.allclose(temp, 20.0 + expected, atol=1e-12)
    # the returned rate is the derivative of the returned temperature: central differences of
    # step 0.1 s err by <= h^2/6 max|T'''| = 0.01 * 0.8 / 25 / 6 ~ 5e-5 degC/s away from the kinks
    smooth = (np.abs(t - 10.0) > 0.15) & (np.abs(t - 30.0) > 0.15)
    smooth[[0, -1]] = False
    assert np.allclose(np.gradient(temp, t)[smooth], rate[smooth], atol=1e-4)
    assert abs(scenario.temperature_profile().evaluate(np.array([30.0 - 1e-9]))[0][0]
               - scenario.temperature_profile().evaluate(np.array([30.0]))[0][0]) < 1e-8


# ----------------------------------------------------------------------------- sensor errors

def test_error_free_sensor_reproduces_truth_up_to_quantisation(tmp_path):
    data = run(tmp_path, HANDHELD + ROTATIONS + FIGURE8, lsb=REAL_LSB)
    lsb = {"gyr": 1000.0 / 65536 * DPS, "acc": 16 * STANDARD_GRAVITY / 65536, "mag": 0.05}
    for triad, step in lsb.items():
        error = getattr(data, triad) - getattr(data, f"ref_{triad}")
        assert np.max(np.abs(error)) <= 0.5 * step * (1 + 1e-9), triad
        counts = getattr(data, triad) / step
        assert np.max(np.abs(counts - np.round(counts))) < 1e-6, triad


#: Static mean of N = 1000 samples with σ = 0.03 °/s: 5 σ/√N ≈ 0.005 °/s; acc σ 0.01 m/s²;
#: mag σ 0.1 µT. The bounds below are 5 σ/√N of each triad.
MEAN_BOUND = {"gyr": 5 * 0.03 * DPS / np.sqrt(1000), "acc": 5 * 0.01 / np.sqrt(1000),
              "mag": 5 * 0.1 / np.sqrt(1000)}


def test_bias_and_its_temperature_polynomial_are_the_mean_static_error(tmp_path):
    errors = {
        "gyr": "bias_dps = [0.5, -0.4, 0.3]\nbias_t1_dps_per_c = [0.01, -0.02, 0.005]\n"
               "bias_t2_dps_per_c2 = [1e-4, 0, -2e-4]\nnoise_density_dps_per_sqrt_hz = 0.003",
        "acc": "bias_ms2 = [0.05, -0.04, 0.06]\nbias_t1_ms2_per_c = [5e-4, 0, -5e-4]\n"
               "bias_t2_ms2_per_c2 = [0, 1e-5, 0]\nnoise_density_ms2_per_sqrt_hz = 1e-3",
        "mag": "bias_ut = [1, -2, 3]\nbias_t1_ut_per_c = [0.02, 0, -0.01]\n"
               "noise_density_ut_per_sqrt_hz = 0.01"}
    data = run(tmp_path, hold(10.0), errors, temp_c=45.0)   # ΔT = 20 °C
    expected = {"gyr": (np.array([0.5, -0.4, 0.3]) + 20 * np.array([0.01, -0.02, 0.005])
                        + 400 * np.array([1e-4, 0, -2e-4])) * DPS,
                "acc": np.array([0.05, -0.04, 0.06]) + 20 * np.array([5e-4, 0, -5e-4])
                + 400 * np.array([0, 1e-5, 0]),
                "mag": np.array([1, -2, 3]) + 20 * np.array([0.02, 0, -0.01])}
    for triad, bias in expected.items():
        error = getattr(data, triad) - getattr(data, f"ref_{triad}")
        assert np.all(np.abs(error.mean(axis=0) - bias) < MEAN_BOUND[triad]), triad


#: Exact identities in float64 (noise-free sensor with 1e-9 LSB) [rad/s].
EXACT_RAD_S = 1e-8


def test_scale_and_misalignment_from_a_constant_rotation(tmp_path):
    errors = {"gyr": "scale = [0.01, -0.02, 0.03]\nscale_t1_per_c = [1e-3, 0, 0]\n"
                     "scale_t2_per_c2 = [0, 0, 1e-5]\nmisalign_deg = [0.5, -0.3, 0.2]"}
    rotation = ('\n[[segment]]\ntype = "rotations"\naxes = ["x"]\nrates_dps = [100.0]\n'
                'angle_deg = 360.0\nramp_s = 0.5\nrest_s = 0.5\n')
    data = run(tmp_path, rotation, errors, temp_c=35.0)   # ΔT = 10 °C
    plateau = np.abs(data.ref_gyr[:, 0] - 100 * DPS) < 1e-12
    assert plateau.sum() > 250
    gain = 1 + np.array([0.01, -0.02, 0.03]) + 10 * np.array([1e-3, 0, 0]) + 100 * np.array([0, 0, 1e-5])
    m_xy, m_xz = np.deg2rad(0.5), np.deg2rad(-0.3)
    expected = 100 * DPS * gain * np.array([1.0, m_xy, m_xz])   # S · (I + M) · [ω, 0, 0]
    assert np.max(np.abs(data.gyr[plateau] - expected)) < EXACT_RAD_S


def test_temperature_rate_bias_of_the_gyroscope(tmp_path):
    errors = {"gyr": "temp_rate_dps_per_c_per_min = [0.001, -0.0005, 0.002]"}
    data = run(tmp_path, hold(5.0) + hold(20.0, 45.0), errors)   # 20 °C in 20 s = 60 °C/min
    error = data.gyr - data.ref_gyr
    ramp = data.t >= 5.0
    assert np.max(np.abs(error[~ramp])) < EXACT_RAD_S
    expected = np.array([0.001, -0.0005, 0.002]) * 60.0 * DPS
    assert np.max(np.abs(error[ramp] - expected)) < EXACT_RAD_S


def test_temperature_rate_bias_of_the_accelerometer_and_magnetometer(tmp_path):
    errors = {"acc": "temp_rate_ms2_per_c_per_min = [0.004, -0.003, 0.005]",
              "mag": "temp_rate_ut_per_c_per_min = [0.02, 0.0, -0.01]"}
    data = run(tmp_path, hold(5.0) + hold(20.0, 45.0), errors)   # 20 °C in 20 s = 60 °C/min
    ramp = data.t >= 5.0
    for triad, per_c_per_min in (("acc", [0.004, -0.003, 0.005]), ("mag", [0.02, 0.0, -0.01])):
        error = getattr(data, triad) - getattr(data, f"ref_{triad}")
        assert np.max(np.abs(error[~ramp])) < EXACT_RAD_S, triad
        assert np.max(np.abs(error[ramp] - np.array(per_c_per_min) * 60.0)) < EXACT_RAD_S, triad


def test_bias_drift_is_linear_in_the_time_since_the_first_sample(tmp_path):
    per_min = {"gyr": [0.6, -0.3, 0.1], "acc": [0.01, 0.02, -0.03], "mag": [0.4, -0.3, 0.25]}
    units = {"gyr": ("dps", DPS), "acc": ("ms2", 1.0), "mag": ("ut", 1.0)}
    errors = {k: f"bias_drift_{units[k][0]}_per_min = {v}" for k, v in per_min.items()}
    data = run(tmp_path, hold(30.0), errors)
    elapsed = np.arange(len(data.t)) / 100.0   # s since the first sample at 100 Hz
    for triad, drift in per_min.items():
        error = getattr(data, triad) - getattr(data, f"ref_{triad}")
        expected = elapsed[:, None] * np.array(drift) * units[triad][1] / 60.0
        assert np.max(np.abs(error - expected)) < EXACT_RAD_S, triad


def test_gyro_g_sensitivity_is_a_bias_per_true_specific_force(tmp_path):
    k = [[0.020, 0.004, -0.003], [0.003, -0.018, 0.005], [-0.004, 0.002, 0.022]]   # (°/s)/(m/s²)
    data = run(tmp_path, HANDHELD, {"gyr": f"g_sensitivity_dps_per_ms2 = {k}"})
    assert np.ptp(data.ref_acc, axis=0).min() > 5.0   # the motion tilts the unit: force varies per axis
    expected = data.ref_acc @ (np.array(k) * DPS).T
    assert np.max(np.abs(data.gyr - data.ref_gyr - expected)) < EXACT_RAD_S
    assert np.max(np.abs(data.acc - data.ref_acc)) < EXACT_RAD_S   # the accelerometer is unaffected


#: Relative accuracy of a standard deviation estimated from N = 6000 samples: 1/√(2N) ≈ 0.9 %;
#: 5 % is more than 5 standard errors.
STD_RELATIVE_BOUND = 0.05


def test_white_noise_and_bias_random_walk_magnitudes(tmp_path):
    errors = {"gyr": "noise_density_dps_per_sqrt_hz = 0.003",
              "acc": "bias_walk_ms2_per_sqrt_s = 0.002",
              "mag": "noise_density_ut_per_sqrt_hz = 0.01"}
    data = run(tmp_path, hold(60.0), errors)
    sigma_gyr = np.std(data.gyr - data.ref_gyr, axis=0)
    assert np.allclose(sigma_gyr, 0.003 * DPS * 10.0, rtol=STD_RELATIVE_BOUND)   # σ = d·√100
    assert np.allclose(np.std(data.mag - data.ref_mag, axis=0), 0.1, rtol=STD_RELATIVE_BOUND)
    walk = data.acc - data.ref_acc
    assert np.max(np.abs(walk[0])) < 1e-8                                         # w(0) = 0
    assert np.allclose(np.std(np.diff(walk, axis=0), axis=0), 0.002 / 10.0, rtol=STD_RELATIVE_BOUND)


def test_magnetometer_hard_soft_iron_and_cubic_distortion(tmp_path):
    soft = np.array([[1.04, 0.02, -0.01], [0.02, 0.96, 0.015], [-0.01, 0.015, 1.05]])
    cubic = np.array([[1.5, 0.5, -0.3], [0.4, -1.2, 0.6], [-0.5, 0.3, 1.0]])
    errors = {"mag": "hard_iron_ut = [18.0, -22.0, 12.0]\n"
                     f"soft_iron = {soft.tolist()}\nnonlinear_cubic_ut = {cubic.tolist()}\n"
                     "nonlinear_ref_ut = 50.0"}
    data = run(tmp_path, POSITIONS, errors)
    v = data.ref_mag @ soft.T
    expected = v + np.array([18.0, -22.0, 12.0]) + (v / 50.0) ** 3 @ cubic.T
    assert np.max(np.abs(data.mag - expected)) < 1e-8


def test_saturation_clips_at_full_scale(tmp_path):
    fast = ('\n[[segment]]\ntype = "rotations"\naxes = ["z"]\nrates_dps = [-600.0]\n'
            'angle_deg = 720.0\nramp_s = 0.2\nrest_s = 0.2\n')
    data = run(tmp_path, fast, lsb=REAL_LSB)
    assert np.rad2deg(np.min(data.gyr[:, 2])) == pytest.approx(-500.0, abs=1e-9)
    assert np.rad2deg(np.min(data.ref_gyr[:, 2])) == pytest.approx(-600.0)


# ----------------------------------------------------------------------------- scenario files

def sensor_values(obj) -> list:
    """All parameter values of a (nested) sensor dataclass as plain Python lists."""
    if is_dataclass(obj):
        return [sensor_values(getattr(obj, f.name)) for f in fields(obj)]
    return np.asarray(obj).tolist()


def test_bundled_scenarios_load_share_one_sensor_and_simulate():
    assert {p.name for p in SCENARIO_FILES} >= {"calibration.toml", "eval_handheld.toml",
                                                "eval_figure8.toml", "eval_rotations.toml"}
    scenarios = [load_scenario(p) for p in SCENARIO_FILES]
    assert all(sensor_values(s.sensor) == sensor_values(scenarios[0].sensor) for s in scenarios)
    for scenario in scenarios:
        short = replace(scenario, segments=scenario.segments[:2])
        data = simulate(short)
        assert len(data) == round(short.duration_s * scenario.rate_hz)
        assert data.name == scenario.name and bool(np.all(data.eval_mask))
        assert np.all(np.isfinite(data.inputs()))
        assert data.meta["earth_field"] == {"norm_ut": 50.0, "dip_deg": 60.0,
                                            "declination_deg": 3.0}
        assert data.meta["reference"] == "simulated" and data.meta["format"] == "imu-csv/1"


def test_calibration_scenario_covers_the_soaks_within_ten_minutes():
    scenario = load_scenario(SCENARIO_DIR / "calibration.toml")
    assert scenario.rate_hz == 100.0 and scenario.duration_s <= 600.0
    data = simulate(scenario)
    for soak in (-10.0, 5.0, 20.0, 35.0, 50.0):
        assert np.sum(data.temp == soak) > 90 * scenario.rate_hz
    assert np.rad2deg(np.max(np.abs(data.ref_gyr))) < 500.0   # inside the gyro range


def test_simulate_to_dir_writes_a_readable_recording(tmp_path):
    path = write(tmp_path, scenario_text(POSITIONS, NOISY))
    csv = simulate_to_dir(path, tmp_path / "out", seed=5)
    assert csv == tmp_path / "out" / "test.csv.gz" and (tmp_path / "out" / "test.json").exists()
    back, direct = read_imu_csv(csv), simulate(load_scenario(path), 5)
    assert np.array_equal(back.gyr, direct.gyr) and np.array_equal(back.ref_q, direct.ref_q)
    assert back.meta["sensor"] == "test_sensor"


# ----------------------------------------------------------------------------- bad files

@pytest.mark.parametrize("edit, key", [
    (lambda s: s.replace("rate_hz = 100.0", "rate_hz = -100.0"), "rate_hz"),
    (lambda s: s.replace("dip_deg = 60.0\n", ""), "dip_deg"),
    (lambda s: s.replace("seed = 7", "seed = 7\nsead = 8"), "sead"),
    (lambda s: s.replace("hold_s = 1.0", "hold_s = 'long'"), "hold_s"),
    (lambda s: s.replace('type = "positions"', 'type = "teleport"'), "type"),
    (lambda s: s.replace("lsb_dps = 1e-9", "lsb_dps = 1e-9\nbias_dps = [1, 2]"), "bias_dps"),
    (lambda s: s.replace("[sensor.acc]", "[sensor.acc]\ntemp_rate_dps_per_c_per_min = [0, 0, 0]"),
     "temp_rate_dps_per_c_per_min"),
])
def test_bad_scenario_names_file_and_key(tmp_path, edit, key):
    path = write(tmp_path, edit(scenario_text(POSITIONS)), "bad.toml")
    with pytest.raises(ScenarioError, match=rf"bad\.toml.*'{key}'"):
        load_scenario(path)


def test_missing_file_and_steep_handheld_start_are_scenario_errors(tmp_path):
    with pytest.raises(ScenarioError, match="nowhere.toml.*not found"):
        load_scenario(tmp_path / "nowhere.toml")
    steep = load_scenario(write(tmp_path, scenario_text(HANDHELD, start="attitude_deg = [0, 80, 0]\n")))
    with pytest.raises(ScenarioError, match=r"scenario\.toml.*segment 1.*pitch"):
        simulate(steep)
