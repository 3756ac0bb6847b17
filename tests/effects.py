"""A generator of undeclared sensor effects for the tests of `imufmu diagnose` (issue 14).

Each injector takes a recording with its truth (training.data.dataset.ImuData with ref_gyr, ref_acc,
ref_mag; normally scenarios/variants/diag_effects.toml, sensor diag_base, whose declared errors
a model trained on diag_calibration_clean.toml covers) and returns a NEW ImuData whose RAW
columns carry one effect the sensor model does not declare. The input is never modified: the
result is a dataclasses.replace copy that shares the untouched arrays and holds new arrays for
what changed. Effects are computed from the truth where the physics says so (the true rate
ref_gyr, true specific force ref_acc, true body field ref_mag, the true sensor temperature
temp) and added to the raw columns after the ADC (no re-quantisation: the data already carry
their quantisation noise; a 16-bit LSB is 0.015 °/s, 0.0024 m/s², 0.05 µT).

    injector(data, rng=None, **magnitude) -> ImuData

`rng` only drives the effects that draw a random auxiliary waveform (None: a fixed default
seed, so every injector is deterministic); magnitudes are keyword arguments with defaults.

Noise floor of diag_base at 100 Hz (per-sample σ = noise density · √100 Hz), against which the
default magnitudes are chosen large (≥ ~7 σ RMS on the held-out part, see
benchmarks/effect_sizes.py) yet physically plausible:
    gyro 0.003 °/s/√Hz -> σ = 0.03 °/s;  acc 100 µg/√Hz -> σ = 0.0098 m/s²;
    mag 0.01 µT/√Hz -> σ = 0.1 µT.

`EFFECTS` maps each name to an `Effect`: the injector, the target triad, the signal family a
diagnosis should select (keywords compared with the selected regressor names after dropping
the axis suffixes: 'gyr_x*gyr_y' -> 'gyr*gyr', 'd_mag_z' -> 'd_mag'; see `regressor_family`)
and a one-line description.
"""
from __future__ import annotations

import re
from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace

import numpy as np

from training.data.dataset import ImuData

#: rad/s per °/s.
DEG = np.pi / 180.0
#: Standard gravity [m/s²] (for magnitudes quoted per g).
G0 = 9.80665
#: Reference temperature [°C] of the temperature-driven effects (the simulator's ΔT origin).
T_REF_C = 25.0
#: Seed of the auxiliary waveforms when no rng is given.
DEFAULT_SEED = 14

Injector = Callable[..., ImuData]


# ----------------------------------------------------------------------------- helpers

def truth_as_raw(data: ImuData) -> ImuData:
    """A copy whose raw triads are the truth (ref_gyr, ref_acc, ref_mag): injecting an effect
    into it isolates the effect from noise and from the declared sensor errors."""
    return replace(data, gyr=data.ref_gyr, acc=data.ref_acc, mag=data.ref_mag)


def delay(x: np.ndarray, samples: int) -> np.ndarray:
    """x delayed by `samples` ≥ 0 rows, edge-padded (never wrapped): out[k] = x[max(k − samples, 0)]."""
    if samples < 0:
        raise ValueError(f"delay must be >= 0 samples, got {samples}")
    idx = np.maximum(np.arange(x.shape[0]) - samples, 0)
    return x[idx].copy()


def rate_derivative(data: ImuData) -> np.ndarray:
    """True angular acceleration ω̇ (N, 3) [rad/s²]: central differences of ref_gyr in time."""
    return np.gradient(data.ref_gyr, data.t, axis=0)


def lowpassed_temp_rate(t: np.ndarray, temp: np.ndarray, tau_s: float) -> np.ndarray:
    """dT/dt [°C/s] by backward differences, through a first-order low-pass of time constant
    tau_s [s] starting at 0: y_k = y_{k−1} + Δt/(τ + Δt)·((T_k − T_{k−1})/Δt − y_{k−1})."""
    out = np.zeros_like(temp, dtype=float)
    for k in range(1, temp.shape[0]):
        dt = t[k] - t[k - 1]
        out[k] = out[k - 1] + dt / (tau_s + dt) * ((temp[k] - temp[k - 1]) / dt - out[k - 1])
    return out


def switching_waveform(t: np.ndarray, rng: np.random.Generator, high: float,
                       hold_s: tuple[float, float] = (1.5, 4.0), off_share: float = 0.3,
                       pwm_share: float = 0.35, pwm_hz: tuple[float, float] = (0.5, 2.0)) -> np.ndarray:
    """A random on/off + PWM-like drive (N,) in [0, high]: consecutive intervals of U(hold_s) [s],
    each off (share off_share), a square wave between 0 and a level U(0.1, 1)·high at U(pwm_hz)
    [Hz] with a duty cycle U(0.2, 0.8) (share pwm_share), or constant at such a level. The same
    draws every interval whatever its kind, so the sequence depends on the seed only."""
    out = np.zeros(t.shape[0])
    start = float(t[0])
    while start <= t[-1]:
        length, kind, level = rng.uniform(*hold_s), rng.uniform(), rng.uniform(0.1, 1.0) * high
        freq, duty = rng.uniform(*pwm_hz), rng.uniform(0.2, 0.8)
        sel = (t >= start) & (t < start + length)
        if kind >= off_share + pwm_share:
            out[sel] = level
        elif kind >= off_share:
            out[sel] = level * (np.mod((t[sel] - start) * freq, 1.0) < duty)
        start += length
    return out


def _add(data: ImuData, triad: str, effect: np.ndarray, **aux: np.ndarray) -> ImuData:
    """New ImuData with `effect` (N, 3) added to the raw `triad` and the aux columns added."""
    changed = {triad: getattr(data, triad) + effect}
    if aux:
        changed["aux"] = {**data.aux, **aux}
    return replace(data, **changed)


def _rng(rng: np.random.Generator | None) -> np.random.Generator:
    return np.random.default_rng(DEFAULT_SEED) if rng is None else rng


# ----------------------------------------------------------------------------- the effects

def none(data: ImuData, rng: np.random.Generator | None = None) -> ImuData:
    """No effect: a new ImuData holding the same arrays."""
    return replace(data)


def mag_delay(data: ImuData, rng: np.random.Generator | None = None, samples: int = 4) -> ImuData:
    """Raw magnetometer delayed by `samples` whole samples against gyro and accelerometer (a
    separate chip or a slower digital filter): mag_raw[k] = mag_raw_before[k − samples], the
    first samples repeating mag_raw_before[0]. Error ≈ −DΔt·ṁ = DΔt·(ω × m) [µT].
    Default 4 samples = 40 ms at 100 Hz (typical of a magnetometer sampled at its own ODR, 2-5
    allowed): ≈ 0.85 µT RMS on the handheld motion (ω ~ 0.5 rad/s, |m| = 50 µT) against 0.1 µT noise."""
    if not 2 <= samples <= 5:
        raise ValueError(f"mag_delay: samples must be 2..5, got {samples}")
    return replace(data, mag=delay(data.mag, samples))


def mag_long_delay(data: ImuData, rng: np.random.Generator | None = None, samples: int = 20) -> ImuData:
    """Raw magnetometer 20 samples (200 ms) late: a magnetometer read at 5 Hz and held, or a long
    moving-average filter. Far outside the linear range of a time-shift fit (ω·D·Δt ~ 0.1-0.5 rad):
    ≈ 4 µT RMS on the handheld motion against 0.1 µT."""
    return replace(data, mag=delay(data.mag, samples))


def gyro_lead(data: ImuData, rng: np.random.Generator | None = None, samples: int = 7) -> ImuData:
    """Raw gyro 7 samples (70 ms) EARLY against accelerometer, magnetometer and truth (its
    timestamps taken at a later interrupt than its sampling instant): gyr_raw[k] = gyr[k + samples],
    the last samples repeating the final one. The runtime must delay it (a negative lag)."""
    idx = np.minimum(np.arange(len(data)) + samples, len(data) - 1)
    return replace(data, gyr=data.gyr[idx].copy())


def acc_delay(data: ImuData, rng: np.random.Generator | None = None, samples: int = 3) -> ImuData:
    """Raw accelerometer delayed by `samples` whole samples against the gyro (a low-pass digital
    filter's group delay on the accelerometer only): acc_raw[k] = acc_raw_before[k − samples],
    edge-padded. Error ≈ −DΔt·ḟ [m/s²] (ḟ = −ω × f + translational jerk).
    Default 3 samples = 30 ms (a 20-40 Hz on-chip filter): ≈ 0.17 m/s² RMS against 0.0098 m/s²."""
    if not 1 <= samples <= 5:
        raise ValueError(f"acc_delay: samples must be 1..5, got {samples}")
    return replace(data, acc=delay(data.acc, samples))


def gyro_rate_scale(data: ImuData, rng: np.random.Generator | None = None,
                    k: tuple[float, float, float] = (0.01, -0.008, 0.012)) -> ImuData:
    """Gyro scale factor growing with the rate (rate nonlinearity): ω_raw += k·ω·|ω| per axis,
    k [1/(rad/s)], ω the true rate [rad/s]. Default ~1 % at 1 rad/s (0.17 % at 10 °/s, 2.6 % at
    150 °/s: a poor but real MEMS rate nonlinearity): ≈ 0.37 °/s RMS against 0.03 °/s."""
    w = data.ref_gyr
    return _add(data, "gyr", np.asarray(k) * w * np.abs(w))


def aux_field(data: ImuData, rng: np.random.Generator | None = None, max_current_a: float = 10.0,
              c_ut_per_a: tuple[float, float, float] = (0.25, -0.15, 0.3)) -> ImuData:
    """Field of an outside current: a motor fixed to the body draws I(t) [A] (new column
    aux_motor_current: random on/off + PWM-like drive, levels 0..max_current_a, changing every
    1.5-4 s, drawn from `rng` independently of the motion) and adds mag_raw += c·I [µT], c in
    body axes [µT/A]. Default |c| ≈ 4.2 µT at 10 A (a 10 A lead ~0.5 m away gives
    μ0·I/(2πr) = 4 µT): ≈ 1.1 µT RMS against 0.1 µT."""
    current = switching_waveform(data.t, _rng(rng), max_current_a)
    out = _add(data, "mag", current[:, None] * np.asarray(c_ut_per_a), aux_motor_current=current)
    aux_meta = {**data.meta.get("aux", {}), "aux_motor_current": {"unit": "A", "meaning": "motor current"}}
    return replace(out, meta={**data.meta, "aux": aux_meta})


def lever_arm(data: ImuData, rng: np.random.Generator | None = None,
              r_m: tuple[float, float, float] = (0.06, -0.04, 0.03)) -> ImuData:
    """Accelerometer offset by r [m] (body axes) from the point the truth refers to:
    acc_raw += ω̇ × r + ω × (ω × r) [m/s²] (tangential + centripetal), ω, ω̇ from ref_gyr.
    Default |r| = 8 cm (accelerometer on another board of the unit): ≈ 0.14 m/s² RMS against
    0.0098 m/s²."""
    w, r = data.ref_gyr, np.asarray(r_m)
    effect = np.cross(rate_derivative(data), r) + np.cross(w, np.cross(w, r))
    return _add(data, "acc", effect)


#: Default g-sensitivity [(°/s)/g], row = gyro axis: diagonal 0.35-0.45, cross ≤ 0.1 (°/s)/g.
#: Four times the 0.1 (°/s)/g a modern consumer datasheet quotes as typical, the high end of
#: low-cost and older MEMS gyros: needed because at 0.1 (°/s)/g the effect (≈ 0.06 °/s RMS on
#: this motion, mostly the gravity offset) would sit at 2 σ of the gyro noise.
G_SENS_DPS_PER_G = ((0.4, 0.08, -0.06),
                    (-0.07, 0.35, 0.1),
                    (0.05, -0.09, 0.45))


def gyro_g_sensitivity(data: ImuData, rng: np.random.Generator | None = None,
                       g_matrix: np.ndarray | None = None) -> ImuData:
    """Gyro bias proportional to the true specific force f [m/s²]: ω_raw += G·f, G (3, 3)
    [(rad/s)/(m/s²)], row = gyro axis. Default G_SENS_DPS_PER_G ((°/s)/g, 0.35-0.45 on the
    diagonal): ≈ 0.25 °/s RMS against 0.03 °/s."""
    g = np.asarray(G_SENS_DPS_PER_G) * DEG / G0 if g_matrix is None else np.asarray(g_matrix)
    return _add(data, "gyr", data.ref_acc @ g.T)


def acc_cross_nonlinearity(data: ImuData, rng: np.random.Generator | None = None,
                           k_xy: float = 3e-3, k_yz: float = -3e-3, k_zx: float = 3e-3) -> ImuData:
    """Accelerometer cross-axis nonlinearity: acc_x += k_xy·f_x·f_y, acc_y += k_yz·f_y·f_z,
    acc_z += k_zx·f_z·f_x, k [1/(m/s²)], f the true specific force [m/s²].
    Default |k| = 3e-3 per m/s²: 0.15 m/s² (15 mg) at 45° tilt (f_x = f_y = 6.9 m/s²), within the
    ~0.5 % of full scale (8 g) nonlinearity of consumer parts: ≈ 0.07 m/s² RMS against 0.0098 m/s²."""
    f = data.ref_acc
    effect = np.column_stack([k_xy * f[:, 0] * f[:, 1], k_yz * f[:, 1] * f[:, 2], k_zx * f[:, 2] * f[:, 0]])
    return _add(data, "acc", effect)


def temp_rate_bias(data: ImuData, rng: np.random.Generator | None = None,
                   c_dps_per_c_per_min: tuple[float, float, float] = (0.05, -0.04, 0.045),
                   tau_s: float = 10.0) -> ImuData:
    """Gyro bias proportional to the temperature rate (thermal gradients across the package
    while it warms): ω_raw += c·dT/dt, dT/dt [°C/s] from the true temperature through a
    first-order low-pass of tau_s [s] (the package's thermal lag). c [(°/s)/(°C/min)].
    Default 0.05 (°/s)/(°C/min): 0.6 °/s = 20 σ at 12 °C/min (5x the mems_grade_thermal_rate
    unit, a fast warm-up of a poorly packaged part): ≈ 0.4 °/s RMS against 0.03 °/s."""
    rate = lowpassed_temp_rate(data.t, data.temp, tau_s) * 60.0       # °C/min
    return _add(data, "gyr", rate[:, None] * np.asarray(c_dps_per_c_per_min) * DEG)


def mag_temp_drift(data: ImuData, rng: np.random.Generator | None = None,
                   h_ut_per_c: tuple[float, float, float] = (0.15, -0.12, 0.1)) -> ImuData:
    """Hard iron drifting with temperature (a magnetised part whose remanence changes with
    temperature), on top of the offset drift the calibration covers: mag_raw += h·(T − 25 °C),
    h [µT/°C]. Default |h| ≈ 0.2 µT/°C -> 4 µT over the 15-35 °C ramp: ≈ 0.8 µT RMS (1 µT on
    the held-out part) against 0.1 µT."""
    return _add(data, "mag", (data.temp - T_REF_C)[:, None] * np.asarray(h_ut_per_c))


def mag_field_cross(data: ImuData, rng: np.random.Generator | None = None,
                    k_per_ut: tuple[float, float, float] = (1.5e-3, -1.2e-3, 1.5e-3)) -> ImuData:
    """Field-dependent soft iron (a nearby soft-magnetic part whose permeability changes with the
    field it sees): mag_x += k_x·m_x·m_y, mag_y += k_y·m_y·m_z, mag_z += k_z·m_z·m_x, m the true
    body field [µT], k [1/µT]. Default |k| ≤ 1.5e-3 /µT: 1.8 µT (3.7 %) at m_x = m_y = 35 µT, a
    strong but possible distortion next to a soft-magnetic part: ≈ 1 µT RMS against 0.1 µT."""
    m, k = data.ref_mag, np.asarray(k_per_ut)
    effect = np.column_stack([m[:, 0] * m[:, 1], m[:, 1] * m[:, 2], m[:, 2] * m[:, 0]]) * k
    return _add(data, "mag", effect)


def mag_warmup_drift(data: ImuData, rng: np.random.Generator | None = None,
                     v_ut_per_min: tuple[float, float, float] = (0.5, -0.4, 0.3)) -> ImuData:
    """A field offset creeping with time since power-on, not with the temperature (a slowly
    settling magnetisation after the board powered up): mag_raw += v·t, v [µT/min]. Default
    |v| ≈ 0.7 µT/min -> 1.8 µT over 150 s: ≈ 0.9 µT RMS against 0.1 µT. The only effect whose
    regressor is `time`, the one a diagnosis must bound: exported, it may not keep drifting."""
    minutes = (data.t - data.t[0])[:, None] / 60.0
    return _add(data, "mag", minutes * np.asarray(v_ut_per_min))


def heater_gyro_bias(data: ImuData, rng: np.random.Generator | None = None, max_power_w: float = 2.0,
                     c_dps_per_w: tuple[float, float, float] = (0.3, -0.2, 0.25)) -> ImuData:
    """Gyro bias driven by a heater elsewhere on the board (new column aux_heater_power [W]:
    random on/off + PWM-like thermostat drive 0..max_power_w, drawn from `rng`): its supply
    current couples into the gyro drive electronics, ω_raw += c·P, c [(°/s)/W], instantaneous.
    The heater does not warm the sensor (temp unchanged). Default |c| ≈ 0.44 (°/s)/W: up to
    0.9 °/s at 2 W: ≈ 0.23 °/s RMS against 0.03 °/s."""
    power = switching_waveform(data.t, _rng(rng), max_power_w)
    return _add(data, "gyr", power[:, None] * np.asarray(c_dps_per_w) * DEG, aux_heater_power=power)


def gyro_cross_products(data: ImuData, rng: np.random.Generator | None = None,
                        k: tuple[float, float] = (0.006, -0.005)) -> ImuData:
    """Gyro cross-axis rate products (a vibratory gyro's sense axis coupled to the rotation about
    the other two): ω_y,raw += k_y·ω_x·ω_z and ω_z,raw += k_z·ω_x·ω_y, k [1/(rad/s)], ω the true rate.
    Default about 0.5 % of a rate per rad/s of another: ≈ 0.13 °/s RMS on y and z against 0.03 °/s."""
    w = data.ref_gyr
    effect = np.zeros_like(w)
    effect[:, 1] = k[0] * w[:, 0] * w[:, 2]
    effect[:, 2] = k[1] * w[:, 0] * w[:, 1]
    return _add(data, "gyr", effect)


def supply_gyro_bias(data: ImuData, rng: np.random.Generator | None = None, max_sag_v: float = 0.5,
                     c_dps_per_v: tuple[float, float, float] = (0.8, -0.6, 0.7)) -> ImuData:
    """Gyro bias driven by the supply voltage (new column aux_supply_voltage [V]: a 5 V rail that
    sags by up to max_sag_v under a switching load, drawn from `rng`), ω_raw += c·(V − 5 V),
    c [(°/s)/V], beside a second recorded column that has nothing to do with the gyro (a decoy:
    aux_fan_speed [rpm], an independent switching waveform up to 3000 rpm). Default |c| ≈ 1.2
    (°/s)/V (a poor supply rejection): up to 0.6 °/s: ≈ 0.16 °/s RMS against 0.03 °/s."""
    generator = _rng(rng)
    voltage = 5.0 - switching_waveform(data.t, generator, max_sag_v)
    fan = switching_waveform(data.t, generator, 3000.0)
    return _add(data, "gyr", (voltage - 5.0)[:, None] * np.asarray(c_dps_per_v) * DEG,
                aux_supply_voltage=voltage, aux_fan_speed=fan)


# ----------------------------------------------------------------------------- registry

_AXIS_SUFFIX = re.compile(r"_[xyz](?=$|\*)")


def regressor_family(label: str) -> str:
    """A regressor label without its axis suffixes: 'gyr_x*gyr_y' -> 'gyr*gyr',
    'd_acc_z' -> 'd_acc', 'temp_rate' and 'aux_motor_current' unchanged."""
    return _AXIS_SUFFIX.sub("", label)


@dataclass(frozen=True)
class Effect:
    """One undeclared effect: `inject(data, rng=None, **magnitude) -> ImuData`, the raw triad it
    changes (`target`: 'gyr' | 'acc' | 'mag'), the regressor families a diagnosis should select
    for it (`family`, compared with regressor_family of the selected regressors), the aux
    columns it adds, and a one-line physical description with units."""

    name: str
    inject: Injector
    target: str | None
    family: frozenset[str]
    description: str
    aux: tuple[str, ...] = ()

    def __call__(self, data: ImuData, rng: np.random.Generator | None = None, **magnitude) -> ImuData:
        return self.inject(data, rng, **magnitude)

    def matches(self, regressors: Iterable[str]) -> bool:
        """True when any regressor label (e.g. 'd_gyr_x', 'gyr_x*gyr_y') is of the effect's family."""
        return any(regressor_family(r) in self.family for r in regressors)


def _effect(name, inject, target, family, description, aux=()) -> tuple[str, Effect]:
    return name, Effect(name, inject, target, frozenset(family), description, tuple(aux))


EFFECTS: dict[str, Effect] = dict([
    _effect("none", none, None, (), "no effect: the recording as simulated"),
    _effect("mag_delay", mag_delay, "mag", {"dc_mag", "d_mag", "gyr*mag"},
            "magnetometer 4 samples (40 ms) late against gyro and accelerometer; error ≈ D·(ω × m) [µT]"),
    # ω·|ω| is odd in ω: the signed square gyr·|gyr| (abs_gyr in the runtime's vocabulary).
    _effect("gyro_rate_scale", gyro_rate_scale, "gyr", {"gyr*abs_gyr"},
            "gyro rate nonlinearity ω += k·ω·|ω|, k ≈ 0.01 1/(rad/s) (1 % at 1 rad/s) [rad/s]"),
    _effect("aux_field", aux_field, "mag", {"aux_motor_current"},
            "field of a body-fixed motor current, mag += c·I, |c| ≈ 0.42 µT/A, I 0-10 A [µT]",
            aux=("aux_motor_current",)),
    _effect("lever_arm", lever_arm, "acc", {"d_gyr", "gyr*gyr"},
            "accelerometer 8 cm off the rotation centre, acc += ω̇×r + ω×(ω×r) [m/s²]"),
    _effect("gyro_g_sensitivity", gyro_g_sensitivity, "gyr", {"acc"},
            "gyro g-sensitivity ω += G·f, G ≈ 0.4 (°/s)/g diagonal, ≤ 0.1 cross [rad/s]"),
    _effect("acc_cross_nonlinearity", acc_cross_nonlinearity, "acc", {"acc*acc"},
            "accelerometer cross-axis products acc_i += k·f_i·f_j, |k| = 3e-3 per m/s² [m/s²]"),
    _effect("temp_rate_bias", temp_rate_bias, "gyr", {"temp_rate"},
            "gyro bias ∝ low-passed temperature rate, ≈ 0.05 (°/s)/(°C/min) [rad/s]"),
    _effect("mag_temp_drift", mag_temp_drift, "mag", {"temp"},
            "hard iron drifting ≈ 0.2 µT/°C with temperature, mag += h·(T − 25 °C) [µT]"),
    _effect("acc_delay", acc_delay, "acc", {"dc_acc", "d_acc", "gyr*acc"},
            "accelerometer 3 samples (30 ms) late against the gyro; error ≈ −D·ḟ [m/s²]"),
    _effect("mag_field_cross", mag_field_cross, "mag", {"mag*mag"},
            "field-dependent soft iron mag_i += k·m_i·m_j, |k| ≤ 1.5e-3 /µT [µT]"),
    # On a monotonic temperature ramp, time and temperature are both readings of a slow drift; the
    # diagnosis prefers the physical driver (time since power-on does not carry over to the next
    # power cycle) unless time explains clearly more (training.diagnosis.diagnose.TIME_TIE).
    _effect("mag_long_delay", mag_long_delay, "mag", {"dc_mag"},
            "magnetometer 20 samples (200 ms) late, far beyond a linear time-shift fit [µT]"),
    _effect("gyro_lead", gyro_lead, "gyr", {"dc_gyr"},
            "gyro 7 samples (70 ms) early against accelerometer, magnetometer and truth [rad/s]"),
    _effect("mag_warmup_drift", mag_warmup_drift, "mag", {"time", "temp"},
            "field offset creeping with time since power-on, mag += v·t, |v| ≈ 0.7 µT/min [µT]"),
    _effect("heater_gyro_bias", heater_gyro_bias, "gyr", {"aux_heater_power"},
            "gyro bias from a board heater's supply current, ω += c·P, |c| ≈ 0.44 (°/s)/W, P 0-2 W [rad/s]",
            aux=("aux_heater_power",)),
    _effect("gyro_cross_products", gyro_cross_products, "gyr", {"gyr*gyr"},
            "gyro cross-axis rate products ω_y += k·ω_x·ω_z, ω_z += k·ω_x·ω_y, |k| ≈ 0.005 1/(rad/s) [rad/s]"),
    _effect("supply_gyro_bias", supply_gyro_bias, "gyr", {"aux_supply_voltage"},
            "gyro bias from the supply voltage, ω += c·(V − 5 V), |c| ≈ 1.2 (°/s)/V, sag ≤ 0.5 V, beside an "
            "irrelevant aux_fan_speed column [rad/s]", aux=("aux_supply_voltage", "aux_fan_speed")),
])
