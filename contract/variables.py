"""The one variable table of the ImuFusion FMU: every variable with its value reference, causality,
variability, type, unit, display unit, description, start value and (parameters) default and
declared range. Everything else is derived from it:

- contract.layout: the orders of the runtime's flat arrays (INPUTS, OUTPUTS, SETTINGS — value-
  reference order within each causality) and SETTING_RANGES;
- contract.generate: the C enums of sources/ImuLayout.h, the value references and slot table of
  sources/config.h, the README's variable table and docs/fmu.md's parameter table
  (`python -m contract.generate` rewrites them; tests/test_generated.py fails when one is stale);
- fmu.model_description: modelDescription.xml, and the FMU's documentation.

Adding a parameter: one row here (the next free value reference; existing ones never change),
`python -m contract.generate`, and the C code that uses it (sources/ImuPipeline.c). The
descriptions of the auxiliary inputs depend on the model (`variable_table(artefact.aux_inputs)`);
`VARIABLES` is the table of a model that maps none.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from contract.ranges import (BOOLEAN, DECLINATION_TYPICAL_RAD, EULER_ALL_ADDITIONS, FIELD_NORM_MAX_UT, FIELD_NORM_MIN_UT, FLAG,
                             GYRO_NOISE_MAX, GYRO_RATE_SETTING_MAX, INT32_MAX, INTEGER, LAG, MOUNT_AXIS,
                             PF_MAX_DECIMATION, PF_MAX_PARTICLES, PF_MAX_SPHERE_BINS, PF_NOISE_MAX_UT, PF_SPREAD,
                             PF_THRESHOLD_HIGH_MAX, REAL, STANDARD_GRAVITY, TIME, TIME_SETTING_MAX_S, UNIT_FRACTION,
                             SettingRange)


@dataclass(frozen=True)
class Variable:
    """One FMU variable; `start` is None for outputs (their initial value is calculated).
    Parameters also carry `default` (the start as the float the settings array holds) and `range`
    (declared type and range, contract.ranges)."""

    name: str
    value_reference: int
    causality: str      # "input" | "output" | "parameter"
    variability: str    # "continuous" | "fixed"
    type: str           # "Real" | "Integer" | "Boolean"
    unit: str | None
    display_unit: str | None
    description: str
    start: float | int | bool | None
    min: float | None = None    # declared range (parameters)
    max: float | None = None
    default: float | None = None
    range: SettingRange | None = None


#: The body frame of every output (issue 35): the phrase contract.mounting.frame_text, `imufmu run`,
#: its CSV header and the calibration summary use too.
BODY_FRAME = "body axes = sensor axes turned by mount_x..z"
_NED = f"body -> magnetic NED, ZYX Euler angles; {BODY_FRAME}"
_BODY = f"({BODY_FRAME})"


def _input(name: str, vr: int, unit: str | None, description: str, start: float) -> Variable:
    """A continuous Real input."""
    return Variable(name, vr, "input", "continuous", "Real", unit, None, description, start)


def _output(name: str, vr: int, unit: str, description: str, display_unit: str | None = None) -> Variable:
    """A continuous Real output (initial = calculated, no start value)."""
    return Variable(name, vr, "output", "continuous", "Real", unit, display_unit, description, None)


def _parameter(name: str, vr: int, default: float, declared: SettingRange, description: str,
               display_unit: str | None = None) -> Variable:
    """A fixed parameter (set before initialisation) with its default [unit of the range] and declared
    type and range; Integer and Boolean parameters carry no unit."""
    if declared.type == BOOLEAN:
        return Variable(name, vr, "parameter", "fixed", declared.type, None, None, description, bool(default),
                        default=float(default), range=declared)
    typed = int(default) if declared.type == INTEGER else default
    return Variable(name, vr, "parameter", "fixed", declared.type, declared.unit, display_unit, description, typed,
                    declared.min, declared.max, float(default), declared)


_LAYOUT_2: tuple[Variable, ...] = (
    _input("gyr_x", 0, "rad/s", "Raw angular rate about sensor x", 0.0),
    _input("gyr_y", 1, "rad/s", "Raw angular rate about sensor y", 0.0),
    _input("gyr_z", 2, "rad/s", "Raw angular rate about sensor z", 0.0),
    _input("acc_x", 3, "m/s2", "Raw specific force along sensor x", 0.0),
    _input("acc_y", 4, "m/s2", "Raw specific force along sensor y", 0.0),
    _input("acc_z", 5, "m/s2", "Raw specific force along sensor z (about -9.81 at rest with z down, +9.81 with z up)", -9.80665),
    _input("mag_x", 6, "uT", "Raw magnetic field along sensor x", 20.0),
    _input("mag_y", 7, "uT", "Raw magnetic field along sensor y", 0.0),
    _input("mag_z", 8, "uT", "Raw magnetic field along sensor z", 40.0),
    _input("temp", 9, "degC", "Sensor temperature (NaN if unknown)", 25.0),
    _output("rate_x", 10, "rad/s", f"Corrected angular rate about body x {_BODY}"),
    _output("rate_y", 11, "rad/s", f"Corrected angular rate about body y {_BODY}"),
    _output("rate_z", 12, "rad/s", f"Corrected angular rate about body z {_BODY}"),
    _output("accel_x", 13, "m/s2", f"Corrected specific force along body x {_BODY}"),
    _output("accel_y", 14, "m/s2", f"Corrected specific force along body y {_BODY}"),
    _output("accel_z", 15, "m/s2", f"Corrected specific force along body z {_BODY}"),
    _output("field_x", 16, "uT", f"Corrected magnetic field along body x {_BODY}"),
    _output("field_y", 17, "uT", f"Corrected magnetic field along body y {_BODY}"),
    _output("field_z", 18, "uT", f"Corrected magnetic field along body z {_BODY}"),
    _output("roll", 19, "rad", f"Roll angle phi ({_NED})", "deg"),
    _output("pitch", 20, "rad", f"Pitch angle theta ({_NED})", "deg"),
    _output("yaw", 21, "rad", f"Yaw angle psi relative to magnetic north ({_NED})", "deg"),
    _output("heading", 22, "rad", f"True heading = yaw + declination, of body x {_BODY}", "deg"),
    _output("q_w", 23, "1", f"Attitude quaternion w, Hamilton, body -> magnetic NED {_BODY}"),
    _output("q_x", 24, "1", f"Attitude quaternion x, Hamilton, body -> magnetic NED {_BODY}"),
    _output("q_y", 25, "1", f"Attitude quaternion y, Hamilton, body -> magnetic NED {_BODY}"),
    _output("q_z", 26, "1", f"Attitude quaternion z, Hamilton, body -> magnetic NED {_BODY}"),
    _output("gain_roll", 27, "1", "Adaptive fusion gain of the roll angle (0 = gyro only, 1 = accelerometer only)"),
    _output("gain_pitch", 28, "1", "Adaptive fusion gain of the pitch angle (0 = gyro only, 1 = accelerometer only)"),
    _output("gain_yaw", 29, "1", "Adaptive fusion gain of the yaw angle (0 = gyro only, 1 = magnetometer only)"),
    _output("hard_iron_x", 30, "uT", "Particle-filter hard-iron estimate along body x, relative to the trained "
            "calibration (0 when enable_pf is off)"),
    _output("hard_iron_y", 31, "uT", "Particle-filter hard-iron estimate along body y (0 when enable_pf is off)"),
    _output("hard_iron_z", 32, "uT", "Particle-filter hard-iron estimate along body z (0 when enable_pf is off)"),
    _output("soft_iron_xx", 33, "1", "Particle-filter soft-iron matrix entry b11 (0 when enable_pf is off)"),
    _output("soft_iron_yy", 34, "1", "Particle-filter soft-iron matrix entry b22 (0 when enable_pf is off)"),
    _output("soft_iron_zz", 35, "1", "Particle-filter soft-iron matrix entry b33 (0 when enable_pf is off)"),
    _output("pf_neff", 36, "1", "Particle-filter effective sample size before resampling (0 when enable_pf is off)"),
    _parameter("declination", 37, 0.0, SettingRange(REAL, -math.pi, math.pi, "rad", typical=DECLINATION_TYPICAL_RAD),
               "Magnetic declination: heading = yaw + declination", "deg"),
    _parameter("field_norm", 38, 50.0, SettingRange(REAL, FIELD_NORM_MIN_UT, FIELD_NORM_MAX_UT, "uT"),
               "Local earth-field magnitude"),
    _parameter("gyro_noise", 39, 3.0e-4, SettingRange(REAL, 0.0, GYRO_NOISE_MAX, "rad/s/sqrt(Hz)"),
               "White-noise density of the corrected gyro"),
    _parameter("gyro_bias_residual", 40, 3.0e-4, SettingRange(REAL, 0.0, GYRO_RATE_SETTING_MAX, "rad/s"),
               "Residual gyro bias after calibration"),
    _parameter("mse_time_constant", 41, 1.0, TIME,
               "Averaging time of the innovation mean-square errors"),
    _parameter("angle_noise", 42, 0.0175, SettingRange(REAL, 0.0, math.pi, "rad", min_open=True),
               "Floor of the accelerometer/magnetometer angle error standard deviation", "deg"),
    _parameter("enable_thermal", 43, 1.0, FLAG,
               "Apply the gain/bias temperature model"),
    _parameter("attitude_mode", 44, 1.0, SettingRange(INTEGER, 0.0, 1.0),
               "Attitude filter: 0 = adaptive-gain Euler fusion, 1 = quaternion filter "
               "with gyro bias at rest and magnetic disturbance rejection"),
    _parameter("field_dip", 45, 1.0471975511965976, SettingRange(REAL, -0.5 * math.pi, 0.5 * math.pi, "rad"),
               "Local earth-field dip (inclination, positive down)", "deg"),
    _parameter("tau_acc", 46, 3.0, TIME,
               "Time constant of the inclination correction (quaternion filter)"),
    _parameter("tau_mag", 47, 9.0, TIME,
               "Time constant of the heading correction (quaternion filter)"),
    _parameter("rest_gyro_threshold", 48, 0.035, SettingRange(REAL, 0.0, GYRO_RATE_SETTING_MAX, "rad/s"),
               "Rest detection rate threshold for the gyro bias estimate "
               "(0 = no bias estimation)", "deg/s"),
    _parameter("rest_acc_threshold", 49, 0.5, SettingRange(REAL, 0.0, STANDARD_GRAVITY, "m/s2", min_open=True),
               "Rest detection specific-force deviation threshold"),
    _parameter("mag_reject_time", 50, 60.0, SettingRange(REAL, 0.0, TIME_SETTING_MAX_S, "s"),
               "Longest rejection of a magnetic field whose norm or dip is disturbed "
               "(0 = no rejection; quaternion filter)"),
    _parameter("enable_elm", 51, 0.0, FLAG,
               "Apply the extreme-learning-machine model of the nonlinear "
               "magnetometer distortion (when the artefact carries one)"),
    _parameter("enable_pf", 52, 0.0, FLAG,
               "Online hard/soft-iron estimation by particle filter on the calibrated field"),
    _parameter("pf_particles", 53, 128.0, SettingRange(INTEGER, 2.0, PF_MAX_PARTICLES),
               "Particle count of the filter (2..512)"),
    _parameter("pf_measurement_noise", 54, 0.3, SettingRange(REAL, 0.0, PF_NOISE_MAX_UT, "uT", min_open=True),
               "Field noise per axis assumed by the filter"),
    _parameter("pf_process_noise_hard", 55, 0.01, SettingRange(REAL, 0.0, PF_NOISE_MAX_UT, "uT"),
               "Random-walk standard deviation of the hard iron per filter update"),
    _parameter("pf_process_noise_soft", 56, 2e-4, UNIT_FRACTION,
               "Random-walk standard deviation of the soft-iron entries per filter update"),
    _parameter("pf_prior_spread_hard", 57, 3.0, PF_SPREAD,
               "Prior standard deviation of the hard iron around the trained calibration"),
    _parameter("pf_prior_spread_soft", 58, 0.02, UNIT_FRACTION,
               "Prior standard deviation of the soft-iron entries"),
    _parameter("pf_decimation", 59, 16.0, SettingRange(INTEGER, 1.0, PF_MAX_DECIMATION),
               "Filter every n-th valid sample (the field is compensated every sample)"),
    _parameter("pf_seed", 60, 1.0, SettingRange(INTEGER, 0.0, INT32_MAX),
               "Seed of the filter's PCG32 random numbers"),
    _parameter("pf_threshold_high", 61, 2.0, SettingRange(REAL, 1.0, PF_THRESHOLD_HIGH_MAX, min_open=True),
               "High-weight threshold omega1 of double-threshold splitting, relative to 1/N"),
    _parameter("pf_threshold_low", 62, 0.5, SettingRange(REAL, 0.0, 1.0, min_open=True, max_open=True),
               "Low-weight threshold omega2 of double-threshold splitting, relative to 1/N"),
    _parameter("pf_sphere_bins", 63, 2.0, SettingRange(INTEGER, 0.0, PF_MAX_SPHERE_BINS),
               "Cells per cube-face side of the buffer of field directions (0 = current sample only)"),
    _parameter("enable_psobp", 64, 0.0, FLAG,
               "Apply the PSO-BP network (temperature and its rate) to the gyro bias "
               "that the gain/bias polynomial leaves (when the artefact carries one)"),
    _parameter("pf_rao_blackwell", 65, 1.0, FLAG,
               "Particle filter samples the hard iron only and integrates the soft "
               "iron out exactly (off: the method's 9-state filter with splitting and restoration network)"),
    _parameter("pf_min_rotation", 66, 0.008726646259971648, SettingRange(REAL, 0.0, 0.5 * math.pi, "rad"),
               "Turn of the field direction since the last sample used before the "
               "filter uses a sample (thins samples at rest)", "deg"),
    _parameter("pf_change_spread_hard", 67, 30.0, PF_SPREAD,
               "Prior standard deviation of the hard iron around the estimate "
               "after a declared change of environment"),
    _parameter("pf_hold_prior", 68, 1.0, FLAG,
               "Particle filter holds the prior (trained) calibration until the first "
               "declared change of environment"),
    _parameter("pf_settle_spread", 69, 1.0, PF_SPREAD,
               "The attitude filter ignores the magnetometer while the particle "
               "filter's hard-iron standard deviation exceeds this (0: never)"),
)

#: The auxiliary inputs: signals from outside the IMU (motor current, heater power, supply voltage, …)
#: that diagnosed correction terms may use, in their own units; 0 where a model maps none.
AUX_INPUTS = ("aux_1", "aux_2", "aux_3", "aux_4")
#: Value reference of aux_1 (the auxiliary inputs are contiguous, in AUX_INPUTS order).
_FIRST_AUX_VR = 70

_LAGS: tuple[Variable, ...] = (
    _parameter("lag_gyr", 74, 0.0, LAG,
               "How long the gyro input lags true time (negative: it leads, within [-1, 1] s); "
               "the compensated rates are aligned to true time before the correction terms"),
    _parameter("lag_acc", 75, 0.0, LAG,
               "How long the accelerometer input lags true time (negative: it leads, within "
               "[-1, 1] s); the compensated specific force is aligned to true time before the correction terms"),
    _parameter("lag_mag", 76, 0.0, LAG,
               "How long the magnetometer input lags true time (negative: it leads, within "
               "[-1, 1] s); the compensated field is aligned to true time before the correction terms"),
)


#: Outputs added by layout version 4, after the last value reference of layout 3.
_LAYOUT_4_OUTPUTS: tuple[Variable, ...] = (
    _output("calibration_valid", 77, "1", "1 while every model input (temperature, its rate, the correction terms' "
            "regressors, the field for the ELM) is inside the range the model was calibrated on, 0 while one is "
            "outside: the model is then evaluated at the range edge (clamped), never extrapolated"),
)


#: Parameters added by layout version 4, after calibration_valid.
_MOUNTING: tuple[Variable, ...] = tuple(
    _parameter(f"mount_{axis}", 78 + k, float(k + 1), MOUNT_AXIS,
               f"The sensor axis that is body {axis} (FRD: x forward, y right, z down), "
               "with its sign: 1 = +x, 2 = +y, 3 = +z, -1 = -x, -2 = -y, -3 = -z; the three must name different "
               f"axes and stay right-handed. A board with z up and x forward: 1, -2, -3. {BODY_FRAME[0].upper()}"
               f"{BODY_FRAME[1:]}: the corrected rate, specific force and field, roll, pitch, yaw, heading and "
               "q_* are in the body axes, q_sensor_* gives the attitude of the sensor axes")
    for k, axis in enumerate("xyz"))


#: Variables added after the mounting (same layout version: a parameter's default keeps older models'
#: arrays meaningful, contract.layout reads the defaults by name).
_FILTER_FROM_DATA: tuple[Variable, ...] = (
    _parameter("gyro_hold", 81, 1.0, FLAG,
               "Attitude filters integrate each rate sample over the interval before it (1: a sensor "
               "whose samples average the rate over their interval, as MEMS decimation filters and VQF "
               "assume) or the trapezoid of two samples (0: instantaneous samples); `train` chooses it "
               "by replaying a reference"),
    _output("mag_disturbed", 82, "1", "1 while the attitude filter rejects the field as disturbed (its norm or dip "
            "off field_norm, field_dip; quaternion filter), 0 while it uses it or has none"),
    _parameter("mag_heading", 83, 1.0, FLAG,
               "Attitude filters correct the heading with the magnetometer (0: 6D, heading from the gyro alone, "
               "for a field too non-uniform to trust); `train` decides from the calibration recordings"),
    _parameter("motion_bias", 84, 1.0, FLAG,
               "The quaternion filter also estimates the gyro bias in motion, from its inclination "
               "correction (VQF's motion bias estimation; 0: at rest only)"),
    _parameter("acc_norm_tolerance", 85, 0.0, UNIT_FRACTION,
               "How far the corrected specific-force norm of the still sensor may be from standard gravity "
               "(relative: |f| / g - 1); the quaternion filter's motion bias estimate takes a low-passed "
               "specific force whose norm departs by more than this as carrying linear acceleration and trusts "
               "it less, within it as the accelerometer's own scale error; `train` writes the largest "
               "departure of its calibration recordings' rests"),
)


#: Switches between each source method as its source describes it and the product's additions (issue 33):
#: `imufmu train --method` sets them; the defaults are the product's forms.
_SOURCE_FORMS: tuple[Variable, ...] = (
    _parameter("euler_additions", 86, float(EULER_ALL_ADDITIONS), SettingRange(INTEGER, 0.0, float(EULER_ALL_ADDITIONS)),
               "The project's additions to the adaptive-gain Euler fusion (attitude_mode 0), a sum of bits: "
               "1 trapezoidal propagation, 2 measurement-error floor, 4 error growth with the norms' departure, "
               "8 integration-error bound, 16 tilt variance in the yaw error, 32 restart on growing bounds; "
               "0 = the fusion as its source describes it (docs/euler.md)"),
    _parameter("pf_additions", 87, 1.0, FLAG,
               "The project's additions to the particle filter's 9-state method (pf_rao_blackwell 0): roughening "
               "of the resampled cloud, resample-move, tempering, innovation-driven inflation, the change test, "
               "glitch clipping and the ambient-norm mean (0: the method as its source describes it, docs/magpf.md)"),
    _parameter("psobp_clamp", 88, 1.0, FLAG,
               "The PSO-BP network's inputs (temperature and its rate) are clamped to their training ranges "
               "(0: evaluated outside them as the source's network is; calibration_valid reports either way)"),
)

#: Beyond the calibrated range (issue 33): the gain/bias models continue along their edge tangent.
_OUTSIDE_RANGE: tuple[Variable, ...] = (
    _parameter("thermal_continuation", 89, 1.0, FLAG,
               "Outside the calibrated temperature range the gain/bias polynomials continue along their tangent at "
               "the range edge for at most one calibrated span, then hold (0: they hold their edge value); "
               "calibration_valid is 0 outside the range either way (docs/fmu.md, Calibrated range)"),
)

#: Online learning of the gyro bias at rests (issue 33 item 3; sources/ImuBiasLearning.h).
_BIAS_LEARNING: tuple[Variable, ...] = (
    _parameter("bias_learning", 90, 1.0, FLAG,
               "Learn the gyro gain/bias model's constant and linear bias coefficients at rests by the source's "
               "adaptive-rate gradient rule (needs rest_gyro_threshold > 0; docs/fmu.md, Online bias learning)"),
    _parameter("bias_learning_rate", 91, 0.01, SettingRange(REAL, 0.0, 1.0, "1/s", min_open=True),
               "Smallest adaptation rate of the bias learning: while the rest residual is noise the learnt bias "
               "averages over about 1 / rate seconds of rest; a bias change raises the rate itself"),
    _parameter("bias_learning_limit", 92, 0.0175, SettingRange(REAL, 0.0, GYRO_RATE_SETTING_MAX, "rad/s"),
               "Largest learnt change of each bias coefficient (train writes 10 times the rest noise it measured)",
               "deg/s"),
    _output("bias_learning_shift", 93, "rad/s", "How far the learnt gyro bias is from the trained one at the current "
            "temperature, |d0 + d1 Tn| (0 while bias_learning is off or nothing was learnt)", "deg/s"),
)


#: The attitude of the sensor axes (issue 35 item 3): for a user whose reference is in the sensor's axes.
_SENSOR_ATTITUDE: tuple[Variable, ...] = tuple(
    _output(f"q_sensor_{c}", 94 + k, "1", f"Attitude quaternion {c} of the SENSOR axes, Hamilton, sensor -> magnetic "
            "NED: q_* composed with the mounting's turn, q * q(sensor -> body); equals q_* when mount_x..z = 1, 2, 3")
    for k, c in enumerate("wxyz"))


def aux_description(k: int, entry: dict | None) -> str:
    """Description of input aux_k (k from 1): the recording column, unit and meaning a model's
    aux_inputs entry maps to it, or that the model leaves it unused."""
    if entry is None:
        return f"Auxiliary input {k}: unused by this model (0)"
    unit = f" [{entry['unit']}]" if entry.get("unit") else ""
    meaning = f" ({entry['meaning']})" if entry.get("meaning") else ""
    return f"Auxiliary input {k}: recording column {entry['column']}{unit}{meaning}; used by diagnosed correction terms"


def _aux_inputs(aux_inputs: Sequence[dict]) -> tuple[Variable, ...]:
    """The auxiliary inputs (dimensionless to the FMU, start 0), described from a model's aux_inputs."""
    entries = list(aux_inputs) + [None] * (len(AUX_INPUTS) - len(aux_inputs))
    return tuple(_input(name, _FIRST_AUX_VR + k, None, aux_description(k + 1, entry), 0.0)
                 for k, (name, entry) in enumerate(zip(AUX_INPUTS, entries)))


def variable_table(aux_inputs: Sequence[dict] = ()) -> tuple[Variable, ...]:
    """Every variable in value-reference order; aux_inputs: the model's ModelArtefact.aux_inputs
    (entry k describes input aux_{k+1})."""
    if len(aux_inputs) > len(AUX_INPUTS):
        raise ValueError(f"{len(aux_inputs)} auxiliary inputs mapped, the FMU has {len(AUX_INPUTS)}")
    return (_LAYOUT_2 + _aux_inputs(aux_inputs) + _LAGS + _LAYOUT_4_OUTPUTS + _MOUNTING + _FILTER_FROM_DATA
            + _SOURCE_FORMS + _OUTSIDE_RANGE
            + _BIAS_LEARNING + _SENSOR_ATTITUDE)


VARIABLES: tuple[Variable, ...] = variable_table()


def inputs() -> tuple[Variable, ...]:
    """The inputs, in contract.layout.INPUTS order."""
    return tuple(v for v in VARIABLES if v.causality == "input")


def outputs() -> tuple[Variable, ...]:
    """The outputs, in contract.layout.OUTPUTS order."""
    return tuple(v for v in VARIABLES if v.causality == "output")


def parameters() -> tuple[Variable, ...]:
    """The parameters, in contract.layout.SETTINGS order."""
    return tuple(v for v in VARIABLES if v.causality == "parameter")


def by_name(name: str) -> Variable:
    """The variable called `name`; KeyError naming the known variables otherwise."""
    for v in VARIABLES:
        if v.name == name:
            return v
    raise KeyError(f"unknown FMU variable '{name}' (known: {', '.join(v.name for v in VARIABLES)})")
