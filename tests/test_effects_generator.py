"""The undeclared-effect generator of the diagnosis tests (tests/effects.py, issue 14), pinned
against the truth: each injector changes only its raw target triad (plus its own aux column),
by the closed-form effect computed here independently, deterministically, without touching
its input."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from effects import DEG, EFFECTS, G_SENS_DPS_PER_G, Effect, delay, regressor_family, truth_as_raw
from training.data.dataset import ImuData
from training.main_job import SCENARIO_DIR
from training.simulator import load_scenario, simulate

SCENARIO = SCENARIO_DIR / "variants" / "diag_effects.toml"
TRIADS = ("gyr", "acc", "mag")
#: The list of issue 14, which the registry must hold at least.
REQUIRED = {"none", "mag_delay", "gyro_rate_scale", "aux_field", "lever_arm", "gyro_g_sensitivity",
            "acc_cross_nonlinearity", "temp_rate_bias", "mag_temp_drift"}


@pytest.fixture(scope="module")
def data() -> ImuData:
    return simulate(load_scenario(SCENARIO))


@pytest.fixture(scope="module")
def samples(data) -> np.ndarray:
    """A few sample indices in motion (the fastest turn, and others spread over the recording)."""
    speed = np.linalg.norm(data.ref_gyr, axis=1)
    moving = np.flatnonzero(speed > 0.3)
    return np.unique(np.r_[np.argmax(speed), moving[:: max(1, moving.size // 5)]])


def snapshot(d: ImuData) -> dict[str, np.ndarray]:
    arrays = {f.name: getattr(d, f.name) for f in dataclasses.fields(d)
              if isinstance(getattr(d, f.name), np.ndarray)}
    return {k: v.copy() for k, v in arrays.items()} | {f"aux:{k}": v.copy() for k, v in d.aux.items()}


def injected(data: ImuData, name: str, **magnitude) -> np.ndarray:
    """Raw target after minus before."""
    effect = EFFECTS[name]
    return getattr(effect(data, **magnitude), effect.target) - getattr(data, effect.target)


# ----------------------------------------------------------------------------- scenario and registry

def test_scenario(data):
    """150 s at 100 Hz, 15 -> 35 °C, rests included, rate of warming both fast and slow."""
    assert len(data) == 15000 and data.meta["rate_hz"] == 100.0
    assert data.temp[0] == pytest.approx(15.0) and data.temp[-1] == pytest.approx(35.0)
    rate = np.gradient(data.temp, data.t) * 60.0
    assert rate.max() == pytest.approx(12.0, rel=1e-6) and rate.min() == pytest.approx(0.0, abs=1e-9)
    assert 0.15 < np.mean(np.linalg.norm(data.ref_gyr, axis=1) == 0.0) < 0.4


def test_registry():
    assert REQUIRED <= EFFECTS.keys() and len(EFFECTS) >= len(REQUIRED) + 2
    for name, effect in EFFECTS.items():
        assert isinstance(effect, Effect) and effect.name == name and effect.description
        assert (effect.target is None) == (name == "none")
        assert effect.target in (None, *TRIADS)
        assert bool(effect.family) == (name != "none")
        with pytest.raises(dataclasses.FrozenInstanceError):
            effect.name = "x"


def test_family_matching():
    assert regressor_family("gyr_x*gyr_y") == "gyr*gyr" and regressor_family("d_mag_z") == "d_mag"
    assert regressor_family("temp_rate") == "temp_rate"
    assert regressor_family("aux_motor_current") == "aux_motor_current"
    assert EFFECTS["lever_arm"].matches(["d_gyr_x", "d_gyr_y", "d_gyr_z"])
    assert EFFECTS["lever_arm"].matches(["gyr_x*gyr_y", "gyr_x*gyr_z"])
    assert not EFFECTS["lever_arm"].matches(["temp", "acc_x"])
    assert EFFECTS["aux_field"].matches(["aux_motor_current"])
    assert not EFFECTS["none"].matches(["temp"])


# ----------------------------------------------------------------------------- generic properties

@pytest.mark.parametrize("name", sorted(EFFECTS))
def test_changes_only_its_target(data, name):
    """A new ImuData; only the target triad and the effect's own aux columns differ; the input
    is left as it was."""
    before = snapshot(data)
    effect = EFFECTS[name]
    out = effect(data)
    assert out is not data and isinstance(out, ImuData)
    out.validate()
    assert set(out.aux) == set(data.aux) | set(effect.aux)
    for key in effect.aux:
        assert out.aux[key].shape == data.t.shape and np.all(np.isfinite(out.aux[key]))
    for f in dataclasses.fields(data):
        a, b = getattr(data, f.name), getattr(out, f.name)
        if f.name == effect.target:
            assert np.all(np.isfinite(b)) and not np.array_equal(a, b)
        elif isinstance(a, np.ndarray):
            assert np.array_equal(a, b), f.name
        elif f.name == "meta":   # only the effect's aux columns may be described
            assert {k: v for k, v in b.items() if k != "aux"} == {k: v for k, v in a.items() if k != "aux"}
            assert set(b.get("aux", {})) <= set(a.get("aux", {})) | set(effect.aux)
        elif f.name != "aux":
            assert a == b, f.name
    after = snapshot(data)
    assert before.keys() == after.keys() and all(np.array_equal(before[k], after[k]) for k in before)


def test_none_is_identity(data):
    out = EFFECTS["none"](data)
    for f in dataclasses.fields(data):
        a, b = getattr(data, f.name), getattr(out, f.name)
        assert np.array_equal(a, b) if isinstance(a, np.ndarray) else a == b


@pytest.mark.parametrize("name", sorted(EFFECTS))
def test_deterministic(data, name):
    effect = EFFECTS[name]
    if effect.target is None:
        return
    first = getattr(effect(data, np.random.default_rng(5)), effect.target)
    assert np.array_equal(first, getattr(effect(data, np.random.default_rng(5)), effect.target))
    assert np.array_equal(getattr(effect(data), effect.target), getattr(effect(data), effect.target))
    other = getattr(effect(data, np.random.default_rng(6)), effect.target)
    assert np.array_equal(first, other) != bool(effect.aux)   # only aux waveforms are random


# ----------------------------------------------------------------------------- closed forms

@pytest.mark.parametrize("name, triad, default", [("mag_delay", "mag", 4), ("acc_delay", "acc", 3)])
def test_delay(data, name, triad, default):
    """raw[k] == original[k − D], the first D samples hold original[0] (edge padding, no wrap)."""
    for d in (default, 2, 5):
        out = getattr(EFFECTS[name](data, samples=d), triad)
        raw = getattr(data, triad)
        assert np.array_equal(out[d:], raw[:-d])
        assert np.array_equal(out[:d], np.repeat(raw[:1], d, axis=0))
    with pytest.raises(ValueError):
        EFFECTS[name](data, samples=6)
    assert np.array_equal(delay(np.arange(5.0)[:, None], 0), np.arange(5.0)[:, None])


def test_mag_delay_physics(data, samples):
    """On the truth, a delay D of the field is ≈ D·Δt·(ω × m) (m_b' = −ω × m_b)."""
    base = truth_as_raw(data)
    diff = injected(base, "mag_delay")
    dt = 0.01
    for k in samples:
        w, m = data.ref_gyr[k - 2], data.ref_mag[k - 2]   # mid-point of the 4-sample delay
        expected = 4 * dt * np.array([w[1] * m[2] - w[2] * m[1], w[2] * m[0] - w[0] * m[2],
                                      w[0] * m[1] - w[1] * m[0]])
        assert np.allclose(diff[k], expected, atol=0.02 * np.linalg.norm(expected) + 0.02)


def test_lever_arm(data, samples):
    """acc += ω̇ × r + ω(ω·r) − r|ω|², ω̇ by a central difference of the true rate."""
    r = np.array([0.05, 0.02, -0.07])
    diff = injected(data, "lever_arm", r_m=tuple(r))
    for k in samples:
        w = data.ref_gyr[k]
        wd = (data.ref_gyr[k + 1] - data.ref_gyr[k - 1]) / (data.t[k + 1] - data.t[k - 1])
        tangential = np.array([wd[1] * r[2] - wd[2] * r[1], wd[2] * r[0] - wd[0] * r[2],
                               wd[0] * r[1] - wd[1] * r[0]])
        centripetal = w * (w @ r) - r * (w @ w)
        assert np.allclose(diff[k], tangential + centripetal, rtol=1e-9, atol=1e-12)
    still = np.linalg.norm(data.ref_gyr, axis=1) == 0.0
    inside = still & np.roll(still, 1) & np.roll(still, -1)   # at rest, and so are both neighbours
    assert np.abs(diff[inside]).max() < 1e-12


def test_gyro_rate_scale(data, samples):
    k = (0.02, -0.01, 0.03)
    diff = injected(data, "gyro_rate_scale", k=k)
    for i in samples:
        w = data.ref_gyr[i]
        assert np.allclose(diff[i], [k[j] * w[j] * abs(w[j]) for j in range(3)], rtol=1e-12, atol=0)


def test_gyro_g_sensitivity(data, samples):
    diff = injected(data, "gyro_g_sensitivity")
    g = np.array(G_SENS_DPS_PER_G) * (np.pi / 180.0) / 9.80665
    for i in samples:
        f = data.ref_acc[i]
        assert np.allclose(diff[i], [sum(g[a, b] * f[b] for b in range(3)) for a in range(3)], rtol=1e-12)
    custom = np.arange(9.0).reshape(3, 3) * 1e-4
    assert np.allclose(injected(data, "gyro_g_sensitivity", g_matrix=custom)[samples],
                       data.ref_acc[samples] @ custom.T, rtol=1e-12)


def test_acc_cross_nonlinearity(data, samples):
    diff = injected(data, "acc_cross_nonlinearity", k_xy=1e-3, k_yz=2e-3, k_zx=-3e-3)
    for i in samples:
        fx, fy, fz = data.ref_acc[i]
        assert np.allclose(diff[i], [1e-3 * fx * fy, 2e-3 * fy * fz, -3e-3 * fz * fx], rtol=1e-12)


def test_mag_field_cross(data, samples):
    diff = injected(data, "mag_field_cross", k_per_ut=(1e-3, 2e-3, 3e-3))
    for i in samples:
        mx, my, mz = data.ref_mag[i]
        assert np.allclose(diff[i], [1e-3 * mx * my, 2e-3 * my * mz, 3e-3 * mz * mx], rtol=1e-12)


def test_mag_temp_drift(data):
    h = np.array([0.1, -0.2, 0.05])
    diff = injected(data, "mag_temp_drift", h_ut_per_c=tuple(h))
    for i in (0, 7000, 14999):
        assert np.allclose(diff[i], h * (data.temp[i] - 25.0), rtol=1e-12)
    assert np.allclose(diff[0], h * -10.0) and np.allclose(diff[-1], h * 10.0)


def test_temp_rate_bias_on_a_ramp():
    """A ramp at 12 °C/min from t = 0 through the first-order low-pass (α = Δt/(τ + Δt), start 0):
    bias_k = c · 12 °C/min · (1 − (1 − α)^k), reaching c · 12 °C/min after a few τ."""
    n, dt, tau = 20000, 0.01, 10.0
    t = np.arange(n) * dt
    zeros = np.zeros((n, 3))
    ramp = ImuData(t=t, gyr=zeros, acc=zeros, mag=zeros, temp=20.0 + 0.2 * t,
                   ref_gyr=zeros, ref_acc=zeros, ref_mag=zeros)
    c = np.array([0.05, -0.02, 0.01])
    diff = injected(ramp, "temp_rate_bias", c_dps_per_c_per_min=tuple(c), tau_s=tau) / DEG
    k = np.arange(n)
    expected = c * 12.0 * (1.0 - (tau / (tau + dt)) ** k)[:, None]
    assert np.allclose(diff, expected, rtol=1e-9, atol=1e-12)
    assert np.allclose(diff[-1], c * 12.0, rtol=1e-8)


def test_temp_rate_bias_on_the_recording(data):
    """Zero while the temperature holds at the start; ≈ c · 12 °C/min late in a fast ramp."""
    diff = injected(data, "temp_rate_bias") / DEG
    c = np.array([0.05, -0.04, 0.045])
    assert np.abs(diff[data.t < 5.0]).max() < 1e-12
    late = np.argmin(np.abs(data.t - 135.0))      # 29 s (2.9 τ) into the 12 °C/min ramp from 106 s
    assert np.allclose(diff[late], c * 12.0, rtol=0.05)


@pytest.mark.parametrize("name, column, high, unit_scale", [("aux_field", "aux_motor_current", 10.0, 1.0),
                                                            ("heater_gyro_bias", "aux_heater_power", 2.0, DEG)])
def test_aux_driven(data, name, column, high, unit_scale):
    """raw += c · aux; aux in [0, high], off and on for a while, switching every few seconds, not
    correlated with the motion."""
    effect = EFFECTS[name]
    c = np.array([0.3, -0.2, 0.1])
    kw = {"c_ut_per_a": tuple(c)} if name == "aux_field" else {"c_dps_per_w": tuple(c)}
    out = effect(data, np.random.default_rng(1), **kw)
    drive = out.aux[column]
    diff = getattr(out, effect.target) - getattr(data, effect.target)
    assert np.allclose(diff, drive[:, None] * c * unit_scale, rtol=1e-12, atol=1e-15)
    assert drive.min() == 0.0 and 0.5 * high < drive.max() <= high
    assert 0.1 < np.mean(drive == 0.0) < 0.8
    switches = np.count_nonzero(np.diff(drive))
    assert 150.0 / 10.0 < switches < 150.0 * 2 * 2.0   # a level change every few s, PWM ≤ 2 Hz
    speed = np.linalg.norm(data.ref_gyr, axis=1)
    assert abs(np.corrcoef(drive, speed)[0, 1]) < 0.2


def test_long_delay_and_lead(data):
    """mag_long_delay: raw[k] == original[k − 20]; gyro_lead: raw[k] == original[k + 7], the last
    7 samples holding the final one."""
    mag = EFFECTS["mag_long_delay"](data).mag
    assert np.array_equal(mag[20:], data.mag[:-20]) and np.array_equal(mag[:20], np.repeat(data.mag[:1], 20, axis=0))
    gyr = EFFECTS["gyro_lead"](data).gyr
    assert np.array_equal(gyr[:-7], data.gyr[7:]) and np.array_equal(gyr[-7:], np.repeat(data.gyr[-1:], 7, axis=0))


def test_gyro_cross_products(data, samples):
    k = (0.02, -0.03)
    diff = injected(data, "gyro_cross_products", k=k)
    for i in samples:
        w = data.ref_gyr[i]
        assert np.allclose(diff[i], [0.0, k[0] * w[0] * w[2], k[1] * w[0] * w[1]], rtol=1e-12, atol=0)


def test_supply_gyro_bias_has_an_unrelated_decoy_column(data):
    c = np.array([0.3, -0.2, 0.1])
    out = EFFECTS["supply_gyro_bias"](data, np.random.default_rng(1), c_dps_per_v=tuple(c))
    voltage, fan = out.aux["aux_supply_voltage"], out.aux["aux_fan_speed"]
    assert np.allclose(out.gyr - data.gyr, (voltage - 5.0)[:, None] * c * np.pi / 180.0, rtol=1e-12, atol=1e-15)
    assert 4.5 <= voltage.min() < 5.0 and voltage.max() == 5.0
    assert abs(np.corrcoef(voltage, fan)[0, 1]) < 0.3   # drawn independently: nothing of the bias in it
