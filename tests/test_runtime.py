"""The C runtime through its ctypes bridge: layout, thermal model, attitude fusion, errors, build."""
from __future__ import annotations

import subprocess

import numpy as np
import pytest

from contract import layout
from contract.errors import BuildError
from training import runtime

G = 9.80665                      # m/s², gravity the runtime assumes
FIELD_NORM = 50.0                # µT
DIP = np.radians(60.0)           # rad, field dip angle of the synthetic earth field
FS = 100.0                       # Hz
ROLL, PITCH, YAW, HEADING, QW, GAINS = 9, 10, 11, 12, 13, slice(17, 20)

# Accuracy requirement of the product for 100 Hz handheld motion (1-2 m/s² RMS accelerations,
# ~100 °/s peaks, rest phases) with calibrated MEMS errors (gyro noise 0.03 °/s per sample,
# residual bias 0.01 °/s, field errors up to 1 µT): roll/pitch RMSE <= 1°, yaw RMSE <= 2°.
ROLL_PITCH_RMSE_BOUND_DEG = 1.0
YAW_RMSE_BOUND_DEG = 2.0
# Noise-free sensors consistent with the motion: only rounding and the O(dt²) integration error
# of a constant rate (exact for the trapezoidal rule) remain, so 1e-9 rad is generous.
EXACT_BOUND_RAD = 1e-9
# Thermal model C vs numpy: the same double operations up to summation order; values of order
# 1e2 µT carry a rounding error ~1e-14 relative.
THERMAL_RTOL = 1e-12


#: These tests pin the method's adaptive-gain Euler fusion (attitude_mode 0, no rest bias), which
#: stays selectable; the default quaternion filter is tested in tests/test_chain_stages.py.
EULER_METHOD = {"attitude_mode": 0.0, "rest_gyro_threshold": 0.0}


def runtime_inputs(*sensor_columns) -> np.ndarray:
    """Inputs in layout.INPUTS order from the gyr, acc, mag, temp columns; auxiliary inputs 0."""
    x = np.column_stack(sensor_columns)
    return np.column_stack([x, np.zeros((len(x), len(layout.AUX_INPUTS)))])


def settings(**overrides) -> np.ndarray:
    return np.array(layout.settings_array({**EULER_METHOD, **overrides}))


def identity() -> np.ndarray:
    return np.array(layout.identity_coefficients())


def euler_to_matrix(roll, pitch, yaw) -> np.ndarray:
    """(..., 3, 3) rotation body -> NED, R = Rz(yaw) Ry(pitch) Rx(roll)."""
    cr, sr, cp, sp, cy, sy = (np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch),
                              np.cos(yaw), np.sin(yaw))
    return np.stack([np.stack([cp * cy, sr * sp * cy - cr * sy, cr * sp * cy + sr * sy], -1),
                     np.stack([cp * sy, sr * sp * sy + cr * cy, cr * sp * sy - sr * cy], -1),
                     np.stack([-sp, sr * cp, cr * cp], -1)], -2)


def euler_to_quaternion(roll, pitch, yaw) -> np.ndarray:
    """[w, x, y, z] of the ZYX Euler angles (closed form), w >= 0."""
    cr, sr, cp, sp, cy, sy = (np.cos(roll / 2), np.sin(roll / 2), np.cos(pitch / 2),
                              np.sin(pitch / 2), np.cos(yaw / 2), np.sin(yaw / 2))
    q = np.array([cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
                  cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy])
    return q * np.sign(q[0])


def sensors(r: np.ndarray, a_nav: np.ndarray | float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Noise-free specific force [m/s²] and field [µT] in body axes for rotations r (N, 3, 3)."""
    f_nav = np.asarray(a_nav) - np.array([0.0, 0.0, G])
    m_nav = FIELD_NORM * np.array([np.cos(DIP), 0.0, np.sin(DIP)])
    return (np.einsum("nji,nj->ni", r, np.broadcast_to(f_nav, (len(r), 3))),
            np.einsum("nji,j->ni", r, m_nav))


def wrap(a):
    return np.angle(np.exp(1j * np.asarray(a)))


# ---------------------------------------------------------------- synthetic handheld motion

def warp(t, rest=5.0, move=20.0):
    """Warped time tau(t) in closed form and its rate w(t) in [0, 1]: rest phases of `rest` s,
    then sin²-enveloped motion bursts of `move` s."""
    period = rest + move
    k, x = np.floor(t / period), np.clip(np.mod(t, period) - rest, 0.0, move)
    tau = k * move / 2 + x / 2 - move / (4 * np.pi) * np.sin(2 * np.pi * x / move)
    return tau, np.sin(np.pi * x / move) ** 2


def sines(spec, tau):
    """Sum of a·sin(f·tau + p) and its derivative with respect to tau."""
    return (sum(a * np.sin(f * tau + p) for a, f, p in spec),
            sum(a * f * np.cos(f * tau + p) for a, f, p in spec))


def handheld(seed: int, duration: float = 105.0):
    """Noisy sensors and true ZYX Euler angles of a smooth handheld motion (~100 °/s peaks,
    ~1.8 m/s² RMS linear acceleration while moving, 5 s rest phases), MEMS errors after
    calibration: gyro noise 0.03 °/s per sample + 0.01 °/s bias, acc noise/bias 0.02 m/s²,
    field noise 0.5 µT + residual offset 0.5 µT. Body rates follow in closed form from the
    Euler-angle rates, so truth and gyro agree exactly."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(duration * FS)) / FS
    tau, w = warp(t)
    (roll, d_roll), (pitch, d_pitch), (yaw, d_yaw) = (
        sines(s, tau) for s in (((0.5, 1.3, 0.0), (0.2, 3.1, 1.0)),
                                ((0.35, 0.9, 0.5), (0.15, 2.3, 2.0)),
                                ((1.5, 0.5, 0.0), (0.5, 1.9, 0.3))))
    d_roll, d_pitch, d_yaw = d_roll * w, d_pitch * w, d_yaw * w
    gyr = np.stack([d_roll - d_yaw * np.sin(pitch),
                    d_pitch * np.cos(roll) + d_yaw * np.cos(pitch) * np.sin(roll),
                    -d_pitch * np.sin(roll) + d_yaw * np.cos(pitch) * np.cos(roll)], axis=1)
    a_nav = np.stack([a * np.sin(f * t + p) * w
                      for a, f, p in ((2.5, 2.3, 0.0), (2.5, 1.7, 1.0), (2.0, 2.9, 2.0))], axis=1)
    acc, mag = sensors(euler_to_matrix(roll, pitch, yaw), a_nav)

    def unit():
        v = rng.normal(size=3)
        return v / np.linalg.norm(v)

    gyr = gyr + np.radians(0.01) * np.sign(rng.normal(size=3)) \
        + np.radians(0.03) * rng.normal(size=gyr.shape)
    acc = acc + 0.02 * unit() + 0.02 * rng.normal(size=acc.shape)
    mag = mag + 0.5 * unit() + 0.5 * rng.normal(size=mag.shape)
    inputs = runtime_inputs(gyr, acc, mag, np.full(len(t), np.nan))
    return t, inputs, np.stack([roll, pitch, wrap(yaw)], axis=1)


# ---------------------------------------------------------------- layout and thermal model

def test_layout_matches_python():
    assert runtime.runtime_layout() == {
        "version": layout.LAYOUT_VERSION, "n_coefficients": layout.N_COEFFICIENTS,
        "n_settings": len(layout.SETTINGS), "n_inputs": len(layout.INPUTS),
        "n_outputs": len(layout.OUTPUTS)}


def random_inputs(rng, n=200):
    x = runtime_inputs(rng.normal(0, 1, (n, 3)), rng.normal(0, 5, (n, 3)) + [0, 0, -G],
                       rng.normal(0, 30, (n, 3)), rng.uniform(-40, 85, n))
    x[::7, 9] = np.nan  # bad temperature: the guard holds the last valid one (Tn = 0 before it)
    return x


def held(values: np.ndarray) -> np.ndarray:
    """values (N,) or (N, k) with each row holding a NaN replaced by the previous row, as the
    runtime's guard (sources/ImuGuard.c) holds a bad temperature or a non-finite output."""
    out = np.array(values, dtype=float)
    for k in range(1, len(out)):
        if np.any(np.isnan(out[k])):
            out[k] = out[k - 1]
    return out


def test_identity_coefficients_change_nothing():
    x = random_inputs(np.random.default_rng(0))
    out = runtime.run_batch(identity(), settings(), np.arange(len(x)) / FS, x)
    np.testing.assert_array_equal(out[:, :9], x[:, :9])


def thermal_block(rng, degree: int) -> np.ndarray:
    a = np.eye(3) + 0.02 * rng.normal(size=(3, 3))
    a = 0.5 * (a + a.T)
    g = np.zeros((3, layout.MAX_DEGREE))
    b = np.zeros((3, layout.MAX_DEGREE + 1))
    g[:, :degree] = 0.01 * rng.normal(size=(3, degree))
    b[:, :degree + 1] = rng.normal(size=(3, degree + 1))
    return np.concatenate([[1.0, rng.uniform(15, 35), rng.uniform(5, 30), degree],
                           a.ravel(), g.ravel(), b.ravel(), [0.0, 0.0, 0.0]])  # no calibrated range: unclamped


def thermal_reference(block: np.ndarray, x: np.ndarray, temp: np.ndarray) -> np.ndarray:
    """numpy version of x_c = A (G(Tn) ⊙ (x - B(Tn))), Tn = (T - t0)/ts (0 if T is NaN)."""
    if block[0] == 0:
        return x
    t0, ts, degree = block[1], block[2], int(block[3])
    a = block[4:13].reshape(3, 3)
    g = block[13:13 + 3 * layout.MAX_DEGREE].reshape(3, layout.MAX_DEGREE)
    b = block[13 + 3 * layout.MAX_DEGREE:layout.TRIAD_BLOCK - 3].reshape(3, layout.MAX_DEGREE + 1)
    tn = np.where(np.isnan(temp), 0.0, (temp - t0) / ts)[:, None]
    gain = 1.0 + sum(g[:, k - 1] * tn ** k for k in range(1, degree + 1))
    bias = sum(b[:, k] * tn ** k for k in range(degree + 1))
    return (gain * (x - bias)) @ a.T


@pytest.mark.parametrize("degrees", [(3, 2, 1), (0, 3, 2)])
def test_thermal_matches_numpy_reference(degrees):
    rng = np.random.default_rng(sum(degrees))
    blocks = [thermal_block(rng, d) for d in degrees]
    blocks[2][0] = 0.0 if degrees[0] == 0 else 1.0  # one run with a disabled magnetometer block
    x = random_inputs(rng)
    out = runtime.run_batch(np.array(layout.pack_coefficients(blocks)), settings(),
                            np.arange(len(x)) / FS, x)
    for i, block in enumerate(blocks):
        expected = thermal_reference(block, x[:, 3 * i:3 * i + 3], held(x[:, 9]))
        np.testing.assert_allclose(out[:, 3 * i:3 * i + 3], expected, rtol=THERMAL_RTOL,
                                   atol=THERMAL_RTOL)
    off = runtime.run_batch(np.array(layout.pack_coefficients(blocks)),
                            settings(enable_thermal=0), np.arange(len(x)) / FS, x)
    np.testing.assert_array_equal(off[:, :9], x[:, :9])


@pytest.mark.parametrize("index,value", [(3, 4.0), (3, 1.5), (2, 0.0), (0, 2.0), (20, np.nan)])
def test_invalid_thermal_block_is_rejected(index, value):
    c = identity()
    c[1 + index] = value
    with pytest.raises(ValueError, match="code -4"):
        runtime.run_batch(c, settings(), [0.0], np.zeros((1, len(layout.INPUTS))))


# ---------------------------------------------------------------- attitude: closed forms

def static_run(roll, pitch, yaw, n=50, **overrides):
    r = euler_to_matrix(np.full(n, roll), np.full(n, pitch), np.full(n, yaw))
    acc, mag = sensors(r)
    x = runtime_inputs(np.zeros((n, 3)), acc, mag, np.full(n, 25.0))
    return runtime.run_batch(identity(), settings(**overrides), np.arange(n) / FS, x)


def test_static_level_gives_magnetic_heading():
    yaw = np.radians(170.0)
    out = static_run(0.0, 0.0, yaw, declination=np.radians(20.0))
    assert np.abs(out[:, ROLL:PITCH + 1]).max() < EXACT_BOUND_RAD
    assert np.abs(wrap(out[:, YAW] - yaw)).max() < EXACT_BOUND_RAD
    assert np.abs(out[:, HEADING] - np.radians(-170.0)).max() < EXACT_BOUND_RAD  # wrapped
    np.testing.assert_allclose(out[:, QW:QW + 4], np.tile([np.cos(yaw / 2), 0, 0, np.sin(yaw / 2)],
                                                          (len(out), 1)), atol=EXACT_BOUND_RAD)


@pytest.mark.parametrize("roll", np.radians([-150.0, -30.0, 0.0, 45.0, 179.0]))
@pytest.mark.parametrize("pitch", np.radians([-80.0, -10.0, 0.0, 60.0]))
@pytest.mark.parametrize("yaw", np.radians([-120.0, 0.0, 95.0, 180.0]))
def test_static_euler_and_quaternion_closed_form(roll, pitch, yaw):
    out = static_run(roll, pitch, yaw, n=5)
    assert np.abs(wrap(out[:, ROLL:YAW + 1] - [roll, pitch, yaw])).max() < EXACT_BOUND_RAD
    assert np.all(out[:, ROLL:YAW + 1] > -np.pi) and np.all(out[:, ROLL:YAW + 1] <= np.pi)
    q = euler_to_quaternion(roll, pitch, yaw)
    np.testing.assert_allclose(out[:, QW:QW + 4], np.tile(q, (5, 1)), atol=EXACT_BOUND_RAD)


@pytest.mark.parametrize("with_magnetometer", [True, False])
def test_constant_rotation_about_z_follows_closed_form(with_magnetometer):
    rate, yaw0, n = 0.7, np.radians(-100.0), 1000  # rad/s; 10 s = about 1.1 turns
    t = np.arange(n) / FS
    yaw = yaw0 + rate * t
    acc, mag = sensors(euler_to_matrix(np.zeros(n), np.zeros(n), yaw))
    if not with_magnetometer:
        mag[1:] = np.nan  # yaw from the gyro alone after the initial fix
    x = runtime_inputs(np.tile([0.0, 0.0, rate], (n, 1)), acc, mag, np.full(n, np.nan))
    out = runtime.run_batch(identity(), settings(), t, x)
    assert np.abs(wrap(out[:, YAW] - yaw)).max() < EXACT_BOUND_RAD
    assert np.abs(out[:, ROLL:PITCH + 1]).max() < EXACT_BOUND_RAD
    np.testing.assert_array_equal(out[:, 6:9], held(mag))  # corrected field = raw (identity), held


def test_time_not_increasing_does_not_propagate():
    n = 6
    x = runtime_inputs(np.tile([0.0, 0.0, 1.0], (n, 1)), np.full((n, 6), np.nan), np.zeros(n))
    x[0, 3:9] = [0.0, 0.0, -G, FIELD_NORM * np.cos(DIP), 0.0, FIELD_NORM * np.sin(DIP)]
    out = runtime.run_batch(identity(), settings(), [0.0, 0.1, 0.1, 0.05, 0.2, 0.3], x)
    np.testing.assert_allclose(out[:, YAW], [0.0, 0.1, 0.1, 0.1, 0.2, 0.3], atol=EXACT_BOUND_RAD)


# ---------------------------------------------------------------- attitude: accuracy vs truth

@pytest.mark.parametrize("seed", [1, 2])
def test_handheld_motion_accuracy(seed):
    t, x, truth = handheld(seed)
    out = runtime.run_batch(identity(), settings(), t, x)
    rmse = np.degrees(np.sqrt(np.mean(wrap(out[:, ROLL:YAW + 1] - truth) ** 2, axis=0)))
    assert rmse[0] <= ROLL_PITCH_RMSE_BOUND_DEG and rmse[1] <= ROLL_PITCH_RMSE_BOUND_DEG, rmse
    assert rmse[2] <= YAW_RMSE_BOUND_DEG, rmse
    # the quaternion is the same attitude as the Euler outputs
    q = euler_to_quaternion(*out[:, ROLL:YAW + 1].T).T
    np.testing.assert_allclose(out[:, QW:QW + 4], q, atol=1e-9)
    gains = out[1:, GAINS]
    assert np.all((gains > 0) & (gains < 1))


def test_nonfinite_inputs_keep_outputs_finite():
    t, x, truth = handheld(3, duration=30.0)
    x[100:110, 0:3] = np.nan     # gaps of single sensors while moving
    x[200, 1] = np.inf
    x[300:400, 3:6] = np.nan
    x[500:700, 6:9] = np.nan
    x[800, 3:9] = -np.inf
    x[1000, 9] = np.nan
    x[2600:2650, :] = np.nan     # every sensor lost for 0.5 s (during the rest phase 25-30 s)
    out = runtime.run_batch(identity(), settings(), t, x)
    assert np.all(np.isfinite(out[:, ROLL:]))
    hold = out[2600, ROLL:QW + 4]
    np.testing.assert_array_equal(out[2600:2650, ROLL:QW + 4], np.tile(hold, (50, 1)))
    # The gaps cost no accuracy: after the 10 s of the first gaps the run is as accurate as
    # required. (A total loss of all sensors while moving is not recovered within seconds: the
    # first acc fix after it is trusted fully and carries the linear-acceleration tilt error.)
    err = np.degrees(np.sqrt(np.mean(wrap(out[1000:, ROLL:YAW + 1] - truth[1000:]) ** 2, 0)))
    assert err[:2].max() <= ROLL_PITCH_RMSE_BOUND_DEG and err[2] <= YAW_RMSE_BOUND_DEG, err


def test_sensors_missing_from_the_start():
    """A thermal log without accelerometer/magnetometer: attitude stays finite at zero tilt, and
    the first finite samples initialise it."""
    n = 20
    r = euler_to_matrix(np.full(n, 0.3), np.full(n, -0.2), np.full(n, 1.0))
    acc, mag = sensors(r)
    acc[:5], mag[:10] = np.nan, np.nan
    x = runtime_inputs(np.zeros((n, 3)), acc, mag, np.full(n, 20.0))
    out = runtime.run_batch(identity(), settings(), np.arange(n) / FS, x)
    assert np.all(np.isfinite(out[:, ROLL:]))
    np.testing.assert_array_equal(out[:5, ROLL:YAW + 1], 0.0)
    assert np.abs(wrap(out[10:, ROLL:YAW + 1] - [0.3, -0.2, 1.0])).max() < EXACT_BOUND_RAD


def test_runs_are_deterministic():
    t, x, _ = handheld(4, duration=20.0)
    a = runtime.run_batch(identity(), settings(), t, x)
    b = runtime.run_batch(identity(), settings(), t, x)
    np.testing.assert_array_equal(a, b)


# ---------------------------------------------------------------- errors

def call_batch(c, s, n=3, t=None, x=None):
    lib = runtime.load_runtime()
    c, s = np.ascontiguousarray(c, float), np.ascontiguousarray(s, float)
    t = np.arange(n, dtype=float) if t is None else t
    x = np.zeros((n, len(layout.INPUTS))) if x is None else x
    out = np.zeros((n, len(layout.OUTPUTS)))
    ptr = runtime.pointer
    return lib.ImuBatchRun(ptr(c), c.size, ptr(s), s.size, n, ptr(t) if t.size else None,
                           ptr(x), ptr(out))


def test_bad_sizes_give_error_codes():
    c, s = identity(), settings()
    assert call_batch(c, s) == 0
    assert call_batch(c[:-1], s) == -2
    bad_version = c.copy()
    bad_version[0] = layout.LAYOUT_VERSION + 1.0
    assert call_batch(bad_version, s) == -3
    assert call_batch(c, np.append(s, 0.0)) == -5
    assert call_batch(c, settings(angle_noise=0.0)) == -6
    assert call_batch(c, s, t=np.zeros(0)) == -1
    assert call_batch(c, s, n=0, t=np.zeros(0)) == 0
    with pytest.raises(ValueError, match="wrong number of coefficients"):
        runtime.run_batch(c[:-1], s, [0.0], np.zeros((1, len(layout.INPUTS))))
    with pytest.raises(ValueError, match="shape"):
        runtime.run_batch(c, s, [0.0, 1.0], np.zeros((2, 9)))


@pytest.mark.parametrize("name,value", [
    ("field_norm", 0.0), ("gyro_noise", -1e-3), ("gyro_bias_residual", np.nan),
    ("mse_time_constant", 0.0), ("angle_noise", np.inf), ("enable_thermal", 0.5),
    ("declination", np.nan)])
def test_bad_setting_is_named(name, value):
    with pytest.raises(ValueError, match=f"code -6.*{name} must be"):
        runtime.run_batch(identity(), settings(**{name: value}), [0.0], np.zeros((1, len(layout.INPUTS))))


# ---------------------------------------------------------------- build

def test_strict_build_cache_and_exports(tmp_path, monkeypatch):
    monkeypatch.setenv("IMUFUSION_CACHE", str(tmp_path))
    path = runtime.build_runtime()  # -Wall -Wextra -Wpedantic -Werror: any warning fails
    assert path.parent == tmp_path and path.exists()
    assert {p.name for p in runtime.runtime_sources()} >= {
        "ImuMath.c", "ImuThermal.c", "ImuPipeline.c", "ImuRuntime.c", "ImuBatch.c"}
    mtime = path.stat().st_mtime_ns
    assert runtime.build_runtime() == path and path.stat().st_mtime_ns == mtime  # cached
    assert [p.name for p in tmp_path.iterdir()] == [path.name]  # no temporary files left
    symbols = subprocess.run(["nm", "-D", "--defined-only", str(path)], capture_output=True,
                             text=True, check=True).stdout.split()
    exported = {s for s in symbols if s.startswith("Imu")}
    assert {"ImuBatchRun", "ImuBatchCheckSettings", "ImuBatchLayout"} <= exported
    assert all(name.startswith("ImuBatch") for name in exported)


def test_compiler_failure_raises_build_error(tmp_path, monkeypatch):
    monkeypatch.setenv("IMUFUSION_CACHE", str(tmp_path))
    monkeypatch.setenv("CC", "cc -DIMU_PI=")  # breaks every use of IMU_PI
    with pytest.raises(BuildError, match="compiling the C runtime failed"):
        runtime.build_runtime()
    assert list(tmp_path.iterdir()) == []


def test_a_compile_stopped_by_ctrl_c_leaves_nothing_in_the_cache(tmp_path, monkeypatch):
    """A stop while the compiler runs (the interruption fuzz left 0-byte .tmp files in the cache)."""
    monkeypatch.setenv("IMUFUSION_CACHE", str(tmp_path))

    def stopped(*args, **kwargs):
        raise KeyboardInterrupt
    monkeypatch.setattr(runtime.subprocess, "run", stopped)
    with pytest.raises(KeyboardInterrupt):
        runtime.build_runtime()
    assert list(tmp_path.iterdir()) == []


def test_the_library_is_opened_once_while_its_sources_stay_as_they_are(monkeypatch):
    """load_runtime hashed every source on each call (1 ms, 10 % of a 24 000-sample run_batch)."""
    first = runtime.load_runtime()
    monkeypatch.setattr(runtime, "build_runtime", lambda: pytest.fail("the sources were hashed again"))
    assert runtime.load_runtime() is first
    monkeypatch.setattr(runtime, "CFLAGS", (*runtime.CFLAGS, "-DIMU_A_CHANGED_BUILD"))
    with pytest.raises(pytest.fail.Exception, match="hashed again"):
        runtime.load_runtime()
