"""Physical bounds of the values in a model artefact (model.json): flags, the gain/bias temperature
models and the correction terms. training/artefact.py refuses a file that breaks one, naming it.

The bounds are what a calibration of a MEMS IMU can be, not what a fit happened to give:
a value beyond them is a unit mistake, a corrupted file or a fit that went wrong, and an FMU built
from it would do harm silently. The runtime's input limits come from training/data/input_limits.py
(pinned to sources/ImuGuard.h).
"""
from __future__ import annotations

import math

import numpy as np

from contract.ranges import FIELD_NORM_MAX_UT
from training.data import input_limits
from training.models.thermal import MIN_TS, ThermalModel

#: Valid sensor temperatures [°C] (the runtime guard's, training/data/input_limits.py): the centre t0 of
#: a temperature model lies inside, and its half-range ts is at most the whole span.
TEMP_MIN_C = input_limits.TEMP_MIN_C
TEMP_MAX_C = input_limits.TEMP_MAX_C
#: Half-range ts of the normalised temperature [°C]: at least the fit's own floor (training/models/thermal.py
#: MIN_TS: a smaller one makes Tn explode a few degrees away), at most the valid span.
TS_MIN_C = MIN_TS
TS_MAX_C = TEMP_MAX_C - TEMP_MIN_C
#: Singular values of the constant matrix A [1]: scale factors of a MEMS triad are within percent
#: of 1 and soft iron rarely stretches an axis 2×; 5× either way would be a unit mistake (g vs
#: m/s² is 9.8×, gauss vs µT 100×, ° vs rad 57×). A condition number up to 25 follows.
A_SINGULAR_MIN = 0.2
A_SINGULAR_MAX = 5.0
#: Sum of |g_k| [1]: the gain G(Tn) = 1 + Σ g_k Tn^k may drift by at most 100 % over the calibrated
#: range (|Tn| <= 1); MEMS gains drift by a few percent.
GAIN_DRIFT_MAX = 1.0
#: Full scale of each triad in its unit: a bias (Σ|b_k| over the calibrated range) or a correction
#: term larger than this is beyond anything the sensor measures: the runtime guard's input limits
#: (training/data/input_limits.py = sources/ImuGuard.h) [rad/s, m/s²], and for the field its saturation
#: factor (20) × the largest field_norm [µT].
MAG_SATURATION_FACTOR = input_limits.MAG_SATURATION
FULL_SCALE = {"gyr": input_limits.GYR_LIMIT_RAD_S, "acc": input_limits.ACC_LIMIT_M_S2,
              "mag": MAG_SATURATION_FACTOR * FIELD_NORM_MAX_UT}
UNITS = {"gyr": "rad/s", "acc": "m/s²", "mag": "µT"}


def _num(x: float) -> str:
    """A number as plain short text (4 significant digits)."""
    return f"{float(x):.4g}"


def flag_problem(value) -> str | None:
    """Why a model.json on/off flag is not one (JSON true/false or the numbers 0/1), or None."""
    if isinstance(value, bool) or (isinstance(value, (int, float)) and value in (0, 1)):
        return None
    return f"is {value!r}, expected true/false or 0/1"


def matrix_problem(a: np.ndarray) -> str | None:
    """Why A [1] is not a plausible scale/misalignment/soft-iron matrix, or None."""
    singular = np.linalg.svd(a, compute_uv=False)
    if not (singular.min() >= A_SINGULAR_MIN and singular.max() <= A_SINGULAR_MAX):
        return (f"has singular values {_num(singular.min())}..{_num(singular.max())}, expected within "
                f"[{A_SINGULAR_MIN}, {A_SINGULAR_MAX}] (a singular, badly conditioned or unit-mistaken matrix)")
    if np.linalg.det(a) <= 0.0:
        return "has a negative determinant: it mirrors the axes (an axis-mapping mistake, not a calibration)"
    return None


def thermal_problem(model: ThermalModel, triad: str) -> str | None:
    """Why a triad's temperature model is implausible (one line without the file), or None."""
    where = f"thermal.{triad}"
    if not TEMP_MIN_C <= model.t0 <= TEMP_MAX_C:
        return f"'{where}.t0' is {_num(model.t0)} °C, expected within [{TEMP_MIN_C:g}, {TEMP_MAX_C:g}] °C"
    if not TS_MIN_C <= model.ts <= TS_MAX_C:
        return f"'{where}.ts' is {_num(model.ts)} °C, expected within [{TS_MIN_C:g}, {TS_MAX_C:g}] °C"
    problem = matrix_problem(model.A)
    if problem:
        return f"'{where}.A' {problem}"
    drift = np.abs(model.g).sum(axis=1).max(initial=0.0)
    if not drift <= GAIN_DRIFT_MAX:
        return f"'{where}.g' lets the gain drift by {_num(drift)} (sum of |g_k|), expected at most {GAIN_DRIFT_MAX:g}"
    bias = np.abs(model.b).sum(axis=1).max(initial=0.0)
    if not bias <= FULL_SCALE[triad]:
        return (f"'{where}.b' reaches a bias of {_num(bias)} {UNITS[triad]} (sum of |b_k|), beyond the "
                f"full scale {_num(FULL_SCALE[triad])} {UNITS[triad]}")
    return None


def term_problem(term: dict) -> str | None:
    """Why a validated correction term's largest correction |coefficient|·max(|lo|, |hi|) exceeds
    the full scale of its target triad (the runtime clamps the regressor to [lo, hi]), or None."""
    triad = term["target"].split("_")[0]  # a contract.layout.TERM_TARGETS name: gyr_x .. mag_z
    largest = abs(term["coefficient"]) * max(abs(term["lo"]), abs(term["hi"]))
    if not (math.isfinite(largest) and largest <= FULL_SCALE[triad]):
        return (f"corrects {term['target']} by up to {_num(largest)} {UNITS[triad]} (|coefficient| × "
                f"max(|lo|, |hi|)), beyond the full scale {_num(FULL_SCALE[triad])} {UNITS[triad]}")
    return None
