"""Flat array layouts shared by Python and the C runtime (sources/ImuLayout.h).

The C runtime receives trained coefficients and settings as flat `double` arrays: the FMU from
the generated header `sources/ImuCoefficientsData.h`, the batch library through ctypes. This
module is the Python side of that contract; `tests/test_layout.py` pins it to the C side
through `ImuBatchLayout()`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

LAYOUT_VERSION = 4

#: Auxiliary inputs: signals from outside the IMU (motor current, heater power, supply voltage, …)
#: that diagnosed correction terms may use, in their own units; 0 where a model maps none.
AUX_INPUTS = ("aux_1", "aux_2", "aux_3", "aux_4")
#: Runtime inputs per sample, in order (units: rad/s, m/s², µT, °C, then the auxiliary inputs).
INPUTS = ("gyr_x", "gyr_y", "gyr_z", "acc_x", "acc_y", "acc_z",
          "mag_x", "mag_y", "mag_z", "temp") + AUX_INPUTS

#: Runtime outputs per sample, in order.
OUTPUTS = (
    "rate_x", "rate_y", "rate_z",          # corrected angular rate [rad/s]
    "accel_x", "accel_y", "accel_z",       # corrected specific force [m/s²]
    "field_x", "field_y", "field_z",       # corrected magnetic field [µT]
    "roll", "pitch", "yaw",                # ZYX Euler angles, body -> magnetic NED [rad]
    "heading",                             # yaw + declination, true heading [rad]
    "q_w", "q_x", "q_y", "q_z",            # attitude quaternion body -> magnetic NED
    "gain_roll", "gain_pitch", "gain_yaw",  # adaptive fusion gains [1]
    "hard_iron_x", "hard_iron_y", "hard_iron_z",    # particle-filter hard iron [µT] (0 when off)
    "soft_iron_xx", "soft_iron_yy", "soft_iron_zz",  # particle-filter soft-iron diagonal [1]
    "pf_neff",                             # particle-filter effective sample size [1] (0 when off)
    "calibration_valid",                   # 1 while every model input is inside its calibrated range, else 0 (layout 4)
)

#: Settings (FMU parameters), in order, with default values.
SETTINGS = (
    ("declination", 0.0),             # rad, magnetic declination (heading = yaw + declination)
    ("field_norm", 50.0),             # µT, local earth-field magnitude
    ("gyro_noise", 3.0e-4),           # rad/s/√Hz, white-noise density of the corrected gyro
    ("gyro_bias_residual", 3.0e-4),   # rad/s, residual gyro bias after calibration
    ("mse_time_constant", 1.0),       # s, averaging time of the innovation mean-square errors
    ("angle_noise", 0.0175),          # rad, floor of the acc/mag angle error standard deviation
    ("enable_thermal", 1.0),          # 1 = apply the gain/bias temperature model
    ("attitude_mode", 1.0),           # 1 = quaternion filter (wins on real data, docs/BENCHMARKS.md), 0 = the method's adaptive-gain Euler fusion
    ("field_dip", 1.0471975511965976),  # rad, local earth-field dip (positive down), 60°
    ("tau_acc", 3.0),                 # s, time constant of the quaternion filter's inclination correction
    ("tau_mag", 9.0),                 # s, time constant of the quaternion filter's heading correction
    ("rest_gyro_threshold", 0.035),   # rad/s, rest detection for the gyro bias (0 = none); 2 °/s = VQF's default, train sets it from the data
    ("rest_acc_threshold", 0.5),      # m/s², rest detection: specific-force deviation threshold
    ("mag_reject_time", 60.0),        # s, longest rejection of a disturbed field (0 = no rejection)
    ("enable_elm", 0.0),              # 1 = apply the ELM nonlinear field model (when trained)
    ("enable_pf", 0.0),               # 1 = online hard/soft-iron particle filter (docs/magpf.md)
    ("pf_particles", 128.0),          # particle count, 2..512
    ("pf_measurement_noise", 0.3),    # µT, field noise per axis the filter assumes
    ("pf_process_noise_hard", 0.01),  # µT per filter update, random walk of the hard iron
    ("pf_process_noise_soft", 2e-4),  # 1 per filter update, random walk of the soft iron
    ("pf_prior_spread_hard", 3.0),    # µT, prior spread around the trained calibration
    ("pf_prior_spread_soft", 0.02),   # 1, prior spread of the soft-iron entries
    ("pf_decimation", 16.0),          # filter every n-th valid sample (compensate every sample)
    ("pf_seed", 1.0),                 # PCG32 seed of the filter
    ("pf_threshold_high", 2.0),       # ω1 relative to 1/N (double-threshold splitting)
    ("pf_threshold_low", 0.5),        # ω2 relative to 1/N
    ("pf_sphere_bins", 2.0),          # cells per cube-face side of the direction buffer (0 = off)
    ("enable_psobp", 0.0),            # 1 = PSO-BP network on the gyro bias left by the polynomial
    ("pf_rao_blackwell", 1.0),        # 1 = soft iron integrated out (docs/magpf.md), 0 = the method's 9-state filter
    ("pf_min_rotation", 0.008726646259971648),  # rad (0.5°), turn of the field direction before a sample counts
    ("pf_change_spread_hard", 30.0),  # µT, hard-iron prior spread after a change of environment
    ("pf_hold_prior", 1.0),           # 1 = the prior calibration is held until the first declared change
    ("pf_settle_spread", 1.0),        # µT, the attitude filter ignores the field while the hard-iron cloud sigma exceeds it (0 = never)
    ("lag_gyr", 0.0),                 # s, how long the gyro input lags true time (< 0: it leads; sources/ImuAlign.h)
    ("lag_acc", 0.0),                 # s, how long the accelerometer input lags true time
    ("lag_mag", 0.0),                 # s, how long the magnetometer input lags true time
    ("mount_x", 1.0),                 # signed sensor axis that is body x: 1 = +x, 2 = +y, 3 = +z, negative = opposite (training/mounting.py)
    ("mount_y", 2.0),                 # signed sensor axis that is body y
    ("mount_z", 3.0),                 # signed sensor axis that is body z
)

@dataclass(frozen=True)
class SettingRange:
    """Declared type and range of one setting: Real, Integer (whole numbers) or Boolean (0 or 1).

    min/max [unit] are inclusive unless min_open/max_open (the bound itself is refused; FMI's
    min/max attributes cannot say so, so the FMU refuses it at initialisation); nonzero: 0 is
    refused too (likewise refused only at initialisation). unit: the FMI unit
    of a Real (None: dimensionless). typical (angles in rad only): a |value| above it is legal but
    looks like degrees given as rad (warned about in degrees, not refused).
    """

    type: str
    min: float
    max: float
    unit: str | None = None
    min_open: bool = False
    max_open: bool = False
    typical: float | None = None
    nonzero: bool = False


#: Named bounds of the settings, from physics and from the runtime's fixed-size arrays.
#: Declination: ±180° by definition; beyond 30° it occurs only near the magnetic poles (IGRF),
#: so a larger value more likely is degrees given as rad (2.5 "degrees" would be 143°).
DECLINATION_TYPICAL_RAD = math.radians(30.0)
#: Earth-field magnitude [µT]: the surface field is 22–67 µT; the bounds are the loader's
#: (training/io.py MAG_MEDIAN_NORM_MIN_UT/MAX_UT, pinned by tests/test_value_checks.py): a value
#: in gauss is 100× smaller, one in nT 1000× larger.
FIELD_NORM_MIN_UT = 5.0
FIELD_NORM_MAX_UT = 1000.0
#: Gyro white-noise density [rad/s/√Hz]: 0.1 is about 60× the noisiest MEMS gyro (~0.1 °/s/√Hz).
GYRO_NOISE_MAX = 0.1
#: Gyro rates of settings [rad/s] (residual bias, rest threshold): 1 rad/s = 57 °/s is no bias and no rest.
GYRO_RATE_SETTING_MAX = 1.0
#: Time constants and rejection time [s]: at most one day.
TIME_SETTING_MAX_S = 86400.0
#: Standard gravity [m/s²]: a rest threshold on the specific-force deviation above 1 g detects nothing.
STANDARD_GRAVITY = 9.80665
#: Particle filter (sources/ImuMagPf.h/.c ImuMagPfSettingsCheck): fixed array sizes and its ranges.
PF_MAX_PARTICLES = 512          # IMU_MAG_PF_MAX_PARTICLES
PF_MAX_DECIMATION = 1000
PF_MAX_SPHERE_BINS = 4          # IMU_MAG_PF_MAX_BIN_SIDE
PF_NOISE_MAX_UT = 100.0         # measurement and hard-iron process noise [µT]
PF_SPREAD_MAX_UT = 1.0e4        # hard-iron spreads [µT] (10 mT saturates any magnetometer)
PF_THRESHOLD_HIGH_MAX = 100.0   # ω1 relative to 1/N
#: Time alignment (sources/ImuAlign.h IMU_ALIGN_MAX_LAG) [s].
LAG_MAX_S = 1.0
#: Largest FMI Integer (Int32): the seed's upper bound.
INT32_MAX = 2**31 - 1

_REAL, _INTEGER, _BOOLEAN = "Real", "Integer", "Boolean"
_FLAG = SettingRange(_BOOLEAN, 0.0, 1.0)
_TIME = SettingRange(_REAL, 0.0, TIME_SETTING_MAX_S, "s", min_open=True)
_UNIT_FRACTION = SettingRange(_REAL, 0.0, 1.0)
_LAG = SettingRange(_REAL, -LAG_MAX_S, LAG_MAX_S, "s")
_PF_SPREAD = SettingRange(_REAL, 0.0, PF_SPREAD_MAX_UT, "uT")
#: A signed sensor axis (±1..±3); 0 and a triple that repeats or mirrors an axis are refused
#: together (training/mounting.py mounting_problem, ImuPipelineSettingsCheck).
_MOUNT_AXIS = SettingRange(_INTEGER, -3.0, 3.0, nonzero=True)

#: Type, range and unit (FMI spelling) of every setting, by name (SETTINGS order). The one source:
#: contract/variables.py takes the FMI types, units and the modelDescription.xml min/max from it,
#: contract/schema.py checks --param values and model.json against it, tests/test_value_checks.py
#: pins the C runtime's ImuPipelineSettingsCheck to it.
SETTING_RANGES = {
    "declination": SettingRange(_REAL, -math.pi, math.pi, "rad", typical=DECLINATION_TYPICAL_RAD),
    "field_norm": SettingRange(_REAL, FIELD_NORM_MIN_UT, FIELD_NORM_MAX_UT, "uT"),
    "gyro_noise": SettingRange(_REAL, 0.0, GYRO_NOISE_MAX, "rad/s/sqrt(Hz)"),
    "gyro_bias_residual": SettingRange(_REAL, 0.0, GYRO_RATE_SETTING_MAX, "rad/s"),
    "mse_time_constant": _TIME,
    "angle_noise": SettingRange(_REAL, 0.0, math.pi, "rad", min_open=True),
    "enable_thermal": _FLAG,
    "attitude_mode": SettingRange(_INTEGER, 0.0, 1.0),
    "field_dip": SettingRange(_REAL, -0.5 * math.pi, 0.5 * math.pi, "rad"),
    "tau_acc": _TIME,
    "tau_mag": _TIME,
    "rest_gyro_threshold": SettingRange(_REAL, 0.0, GYRO_RATE_SETTING_MAX, "rad/s"),
    "rest_acc_threshold": SettingRange(_REAL, 0.0, STANDARD_GRAVITY, "m/s2", min_open=True),
    "mag_reject_time": SettingRange(_REAL, 0.0, TIME_SETTING_MAX_S, "s"),
    "enable_elm": _FLAG,
    "enable_pf": _FLAG,
    "pf_particles": SettingRange(_INTEGER, 2.0, PF_MAX_PARTICLES),
    "pf_measurement_noise": SettingRange(_REAL, 0.0, PF_NOISE_MAX_UT, "uT", min_open=True),
    "pf_process_noise_hard": SettingRange(_REAL, 0.0, PF_NOISE_MAX_UT, "uT"),
    "pf_process_noise_soft": _UNIT_FRACTION,
    "pf_prior_spread_hard": _PF_SPREAD,
    "pf_prior_spread_soft": _UNIT_FRACTION,
    "pf_decimation": SettingRange(_INTEGER, 1.0, PF_MAX_DECIMATION),
    "pf_seed": SettingRange(_INTEGER, 0.0, INT32_MAX),
    "pf_threshold_high": SettingRange(_REAL, 1.0, PF_THRESHOLD_HIGH_MAX, min_open=True),
    "pf_threshold_low": SettingRange(_REAL, 0.0, 1.0, min_open=True, max_open=True),
    "pf_sphere_bins": SettingRange(_INTEGER, 0.0, PF_MAX_SPHERE_BINS),
    "enable_psobp": _FLAG,
    "pf_rao_blackwell": _FLAG,
    "pf_min_rotation": SettingRange(_REAL, 0.0, 0.5 * math.pi, "rad"),
    "pf_change_spread_hard": _PF_SPREAD,
    "pf_hold_prior": _FLAG,
    "pf_settle_spread": _PF_SPREAD,
    "lag_gyr": _LAG,
    "lag_acc": _LAG,
    "lag_mag": _LAG,
    "mount_x": _MOUNT_AXIS,
    "mount_y": _MOUNT_AXIS,
    "mount_z": _MOUNT_AXIS,
}
#: Settings that are only valid together (ImuMagPfSettingsCheck): with pf_rao_blackwell = 1 the
#: hard-iron spreads must be > 0 µT.
RAO_BLACKWELL_POSITIVE = ("pf_prior_spread_hard", "pf_change_spread_hard")

TRIAD_ORDER = ("gyr", "acc", "mag")
MAX_DEGREE = 3
#: One triad block: enabled, t0 [°C], ts [°C], degree, A (3x3 row-major),
#: g[axis][k-1] for k = 1..MAX_DEGREE, b[axis][k] for k = 0..MAX_DEGREE, then (layout 4) the calibrated
#: temperature range: has_range (0/1), t_min [°C], t_max [°C] (the runtime clamps T to it).
TRIAD_BLOCK = 4 + 9 + 3 * MAX_DEGREE + 3 * (MAX_DEGREE + 1) + 3
#: Components a term may correct (index = target in the terms block): the compensated triads.
TERM_TARGETS = INPUTS[:9]
#: Signals that diagnosed correction terms may use (sources/ImuTerms.h ImuTermSignal, same order):
#: compensated triads, temperature [°C], its low-passed rate [°C/s], time since the first sample [s],
#: the time derivatives of the compensated triads, their absolute values (a signed power x·|x| is
#: the product x * abs_x), the constant 1 (a term on `one` alone is an offset), the raw
#: auxiliary inputs and the temperature rate low-passed over 1 s instead of 10 s.
TERM_SIGNALS = (TERM_TARGETS + ("temp", "temp_rate", "time")
                + tuple(f"d_{name}" for name in TERM_TARGETS)
                + tuple(f"abs_{name}" for name in TERM_TARGETS)
                + ("one",) + AUX_INPUTS + ("temp_rate_fast",))
TERMS_MAX = 64
#: Terms block: [count, then TERMS_MAX x (target, signal a, signal b or -1, coefficient, lo, hi)];
#: the runtime clamps the regressor s[a]·s[b] to [lo, hi].
TERM_ENTRY = 6
TERMS_BLOCK = 1 + TERM_ENTRY * TERMS_MAX
#: Blocks of the neural stages (sources/ImuElm.h IMU_ELM_BLOCK; all zeros = disabled), in order.
STAGE_BLOCKS = {"elm": 3 + 4 * 3 + 64 * (3 + 1 + 3),   # sources/ImuElm.h IMU_ELM_BLOCK
                "psobp": 7 + 3 * (4 * 16 + 1)}         # sources/ImuPsoBp.h IMU_PSOBP_BLOCK
#: Offsets of the blocks in the coefficient array (sources/ImuLayout.h).
OFFSET_THERMAL = 1
OFFSET_TERMS = OFFSET_THERMAL + len(TRIAD_ORDER) * TRIAD_BLOCK
OFFSET_ELM = OFFSET_TERMS + TERMS_BLOCK
OFFSET_PSOBP = OFFSET_ELM + STAGE_BLOCKS["elm"]
#: Whole coefficient array: [LAYOUT_VERSION, gyr, acc, mag thermal blocks, terms, elm, psobp blocks].
N_COEFFICIENTS = OFFSET_PSOBP + STAGE_BLOCKS["psobp"]


def settings_defaults() -> dict[str, float]:
    """Default value of every setting, by name."""
    return dict(SETTINGS)


def settings_array(overrides: dict[str, float] | None = None) -> list[float]:
    """Settings as the flat array the runtime takes; unknown names raise KeyError."""
    values = settings_defaults()
    for k, v in (overrides or {}).items():
        if k not in values:
            raise KeyError(f"unknown setting '{k}' (known: {', '.join(values)})")
        values[k] = float(v)
    return [values[name] for name, _ in SETTINGS]


def identity_block() -> list[float]:
    """A triad block that changes nothing: enabled, t0=25 °C, ts=1 °C, degree 0, A=I, g=b=0, no range."""
    a = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    return [1.0, 25.0, 1.0, 0.0] + a + [0.0] * (3 * MAX_DEGREE) + [0.0] * (3 * (MAX_DEGREE + 1)) + [0.0] * 3


def terms_block(terms: list[tuple[str, str, str | None, float, float, float]]) -> list[float]:
    """Terms block from (target, signal a, signal b or None, coefficient, lo, hi) tuples, by name;
    lo and hi [unit of s[a]·s[b]] bound the regressor (the runtime rejects lo > hi or non-finite)."""
    if len(terms) > TERMS_MAX:
        raise ValueError(f"{len(terms)} correction terms, at most {TERMS_MAX} fit in the runtime")
    block = [float(len(terms))]
    for target, a, b, coefficient, lo, hi in terms:
        block += [float(TERM_TARGETS.index(target)), float(TERM_SIGNALS.index(a)),
                  -1.0 if b is None else float(TERM_SIGNALS.index(b)), float(coefficient),
                  float(lo), float(hi)]
    return block + [0.0] * (TERMS_BLOCK - len(block))


def pack_coefficients(thermal_blocks: list[list[float]], terms: list[float] | None = None,
                      **stages: list[float]) -> list[float]:
    """The whole coefficient array from the gyr, acc, mag thermal blocks, a terms block and the
    neural stage blocks by name (STAGE_BLOCKS; an absent stage is disabled: all zeros)."""
    if len(thermal_blocks) != len(TRIAD_ORDER) or any(len(b) != TRIAD_BLOCK for b in thermal_blocks):
        raise ValueError(f"expected {len(TRIAD_ORDER)} thermal blocks of {TRIAD_BLOCK} values")
    terms = terms_block([]) if terms is None else list(terms)
    if len(terms) != TERMS_BLOCK:
        raise ValueError(f"terms block has {len(terms)} values, expected {TERMS_BLOCK}")
    values = [float(LAYOUT_VERSION)] + [float(v) for b in thermal_blocks for v in b] + terms
    for name in stages.keys() - STAGE_BLOCKS.keys():
        raise ValueError(f"unknown stage block '{name}' (known: {', '.join(STAGE_BLOCKS)})")
    for name, size in STAGE_BLOCKS.items():
        block = [float(v) for v in stages.get(name, [0.0] * size)]
        if len(block) != size:
            raise ValueError(f"{name} block has {len(block)} values, expected {size}")
        values += block
    return values


def identity_coefficients() -> list[float]:
    """The whole coefficient array of an untrained model (every stage is the identity)."""
    return pack_coefficients([identity_block()] * len(TRIAD_ORDER))
