"""Flat array layouts shared by Python and the C runtime (sources/ImuLayout.h).

The C runtime receives trained coefficients and settings as flat `double` arrays: the FMU from
the generated header `sources/ImuCoefficientsData.h`, the batch library through ctypes. This
module is the Python side of that contract; `tests/test_layout.py` pins it to the C side
through `ImuBatchLayout()`.
"""
from __future__ import annotations

LAYOUT_VERSION = 1

#: Runtime inputs per sample, in order (units: rad/s, m/s², µT, °C).
INPUTS = ("gyr_x", "gyr_y", "gyr_z", "acc_x", "acc_y", "acc_z",
          "mag_x", "mag_y", "mag_z", "temp")

#: Runtime outputs per sample, in order.
OUTPUTS = (
    "rate_x", "rate_y", "rate_z",          # corrected angular rate [rad/s]
    "accel_x", "accel_y", "accel_z",       # corrected specific force [m/s²]
    "field_x", "field_y", "field_z",       # corrected magnetic field [µT]
    "roll", "pitch", "yaw",                # ZYX Euler angles, body -> magnetic NED [rad]
    "heading",                             # yaw + declination, true heading [rad]
    "q_w", "q_x", "q_y", "q_z",            # attitude quaternion body -> magnetic NED
    "gain_roll", "gain_pitch", "gain_yaw",  # adaptive fusion gains [1]
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
)

TRIAD_ORDER = ("gyr", "acc", "mag")
MAX_DEGREE = 3
#: One triad block: enabled, t0 [°C], ts [°C], degree, A (3x3 row-major),
#: g[axis][k-1] for k = 1..MAX_DEGREE, b[axis][k] for k = 0..MAX_DEGREE.
TRIAD_BLOCK = 4 + 9 + 3 * MAX_DEGREE + 3 * (MAX_DEGREE + 1)
#: Whole coefficient array: [LAYOUT_VERSION, gyr block, acc block, mag block].
N_COEFFICIENTS = 1 + len(TRIAD_ORDER) * TRIAD_BLOCK


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
    """A triad block that changes nothing: enabled, t0=25 °C, ts=1 °C, degree 0, A=I, g=b=0."""
    a = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    return [1.0, 25.0, 1.0, 0.0] + a + [0.0] * (3 * MAX_DEGREE) + [0.0] * (3 * (MAX_DEGREE + 1))


def identity_coefficients() -> list[float]:
    """The whole coefficient array of an untrained model (every stage is the identity)."""
    return [float(LAYOUT_VERSION)] + identity_block() * len(TRIAD_ORDER)
