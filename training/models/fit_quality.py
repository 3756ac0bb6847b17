"""Is a fitted calibration plausible for a MEMS sensor? Warnings for the summary `train` prints.

A fit can lower the residual and still be wrong: a gain that absorbs an unmodelled effect, a
cross-axis term that absorbs a mounting error, a noise density measured on a moving "rest". The
checks compare the fit at its centre temperature t0 (x_c = A·(x − B) there, G(t0) = 1) with what
the sensor class allows, with a margin over datasheet tolerances so that a warning means "look":

- gain: the scale factor of each raw axis (its reading per true value, the norm of a row of A⁻¹;
  `scale_factors`) is the sensor's sensitivity. Datasheets give ±1–3 % for MEMS gyros and
  accelerometers (MPU-6050 ±3 %, BMI270 ±2 %, LSM6DSO ±1 %), so a scale factor more than
  SCALE_TOLERANCE = 5 % from 1 is outside the class. Magnetometer gains carry soft iron of the board as
  well (typically up to ±15 %), hence 25 %.
- cross-axis: atan(A_ij / A_ii); MEMS cross-axis sensitivity is ±1–2 % (0.6–1.1°), so beyond 2° is
  outside the class; soft iron adds to the magnetometer's, hence 5°.
- gyro noise density: MEMS gyros span about 0.002 °/s/√Hz (navigation grade, ADIS16490) to
  0.03 °/s/√Hz (consumer), so the GYRO_NOISE_CLASS band is that span widened by about 4× each way;
  outside it the rests were not still, the signal is quantised or filtered, or the unit is wrong.
"""
from __future__ import annotations

import numpy as np

from contract.layout import TRIAD_ORDER, settings_defaults
from training.models.thermal import ThermalModel

#: Largest |gain − 1| of the sensor class, per triad [1].
SCALE_TOLERANCE = {"gyr": 0.05, "acc": 0.05, "mag": 0.25}
#: Largest cross-axis angle of the sensor class, per triad [°].
CROSS_AXIS_LIMIT_DEG = {"gyr": 2.0, "acc": 2.0, "mag": 5.0}
#: White-noise density band of MEMS gyros [rad/s/√Hz] (0.0005 … 0.12 °/s/√Hz).
GYRO_NOISE_CLASS = (float(np.deg2rad(0.0005)), float(np.deg2rad(0.12)))
_AXES = "xyz"


def at_t0(model: ThermalModel) -> tuple[np.ndarray, np.ndarray]:
    """(A·G(t0) (3, 3), B(t0) (3,)): the model at its centre temperature, where G = 1."""
    return model.A, model.b[:, 0]


def cross_axis_deg(a: np.ndarray) -> list[float]:
    """Cross-axis terms of A as small angles [°]: atan(A_ij / A_ii) for i ≠ j, order xy xz yx yz zx zy."""
    return [float(np.degrees(np.arctan2(a[i, j], a[i, i]))) for i in range(3) for j in range(3) if i != j]


def _pairs() -> list[str]:
    """Axis-pair names in cross_axis_deg order."""
    return [_AXES[i] + _AXES[j] for i in range(3) for j in range(3) if i != j]


#: What a scale factor means wherever one is written (the summary, model.json's fit_stats).
SCALE_FACTOR_CONVENTION = "raw reading per true value of each raw axis at t0 (1.01 reads 1 % high; the correction A inverts it)"


def scale_factors(model: ThermalModel) -> np.ndarray:
    """The sensor's scale factor of each raw axis at t0 (3,): its raw reading per true value, the norm of
    row i of (A·G(t0))⁻¹ — the convention of the summary, model.json's fit_stats and the simulator's
    sensor files (1.01 = reads 1 % high; the correction A has the inverse)."""
    a, _ = at_t0(model)
    return np.linalg.norm(np.linalg.inv(a), axis=1)


def gain_warnings(triad: str, model: ThermalModel, reference: str = "none") -> list[str]:
    """One warning per axis whose scale factor at t0 (raw per true) is further than SCALE_TOLERANCE from 1;
    `reference`: the triad's reference kind ('none' when self-calibrated), which decides what to check."""
    limit = SCALE_TOLERANCE[triad]
    check = ("the unit conversion of the raw data (imufmu import --units) and the sensor's range setting"
             if reference == "none" else "the reference's unit and the sensor's range setting")
    return [f"{triad}: warning: scale factor {_AXES[i]} = {s:.4f} (raw per true) is {100 * abs(s - 1):.1f} % from 1 "
            f"(MEMS class: within {100 * limit:.0f} %): check {check}"
            for i, s in enumerate(scale_factors(model)) if abs(s - 1.0) > limit]


def cross_axis_warnings(triad: str, model: ThermalModel) -> list[str]:
    """One warning per axis pair whose cross-axis angle exceeds CROSS_AXIS_LIMIT_DEG."""
    a, _ = at_t0(model)
    limit = CROSS_AXIS_LIMIT_DEG[triad]
    return [f"{triad}: warning: misalignment {pair} = {angle:+.2f} ° (MEMS class: within ±{limit:g} °): "
            "a rotation between the sensor and the reference is absorbed by the fit"
            for pair, angle in zip(_pairs(), cross_axis_deg(a)) if abs(angle) > limit]


def noise_warnings(settings: dict[str, float]) -> list[str]:
    """A warning when the gyro noise density measured at rest lies outside GYRO_NOISE_CLASS (nothing
    when gyro_noise is the default, i.e. it was not measured)."""
    density = settings.get("gyro_noise")
    if density is None or density == settings_defaults()["gyro_noise"]:
        return []
    lo, hi = GYRO_NOISE_CLASS
    if lo <= density <= hi:
        return []
    return [f"gyr: warning: noise density at rest {np.rad2deg(density):.3g} °/s/√Hz is outside the MEMS class "
            f"({np.rad2deg(lo):.4g} … {np.rad2deg(hi):.3g} °/s/√Hz): the rests were not still, or the signal "
            "is quantised, filtered or in another unit"]


def fit_warnings(thermal: dict[str, ThermalModel], settings: dict[str, float],
                 references: dict[str, str] | None = None) -> list[str]:
    """Every plausibility warning of an exported calibration (triads kept at the identity are skipped);
    references: each triad's reference kind ('none': self-calibrated)."""
    out = []
    for triad in TRIAD_ORDER:
        if thermal[triad].enabled:
            out += (gain_warnings(triad, thermal[triad], (references or {}).get(triad, "none"))
                    + cross_axis_warnings(triad, thermal[triad]))
    return out + noise_warnings(settings)


#: How the note of a triad whose gain/bias fit lost to raw on held-out data and whose bias alone is
#: exported instead begins (after "<triad>: "; training.train._bias_only_fallback); the summary quotes it.
BIAS_FALLBACK_NOTE = "the bias B(T) alone is exported instead"


def is_warning(note: str) -> bool:
    """True for a note the summary must repeat as a warning (a warning or a triad not exported)."""
    return ": warning:" in note or ": NOT EXPORTED" in note
