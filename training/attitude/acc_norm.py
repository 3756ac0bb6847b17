"""acc_norm_tolerance from the calibration recordings: how far the still accelerometer's corrected norm is
from standard gravity.

The quaternion filter's motion bias estimate trusts a measurement less when the low-passed specific
force departs from g, since an unaveraged linear acceleration may then tilt it (sources/ImuMotionBias.h).
But an accelerometer's scale error moves the norm too, in every pose and all the time: an uncalibrated
MEMS part is off by up to about 1 % (BROAD's sensor at rest: 0.1-1.0 % depending on the pose), and a
calibration from a single pose or a derived reference leaves a few tenths of a percent. That part is
not linear acceleration. The rests of the calibration recordings show it directly: the corrected mean
specific force of a rest is gravity alone, and its norm's departure from g is the sensor's own. The
largest one is written; the filter counts only a departure beyond it.

Measured (docs/BENCHMARKS.md, `imufmu bench broad-trained`): BROAD trained on 01 + 02 without a
reference writes 0.0087 and its inclination beats VQF's on 16 of the 20 trials (14 with 0).
"""
from __future__ import annotations

import numpy as np

from contract.ranges import STANDARD_GRAVITY
from training.data.dataset import ImuData
from training.models.thermal import ThermalModel, apply_thermal
from training.selfcal.rest import detect_rest

SETTING = "acc_norm_tolerance"


def rest_departures(datasets: list[ImuData], model: ThermalModel) -> list[tuple[str, float]]:
    """[(recording name, |‖f‖ / g - 1|)] of every rest (not hold: a hand's tremor is not gravity alone)
    of the recordings with an accelerometer, f the rest's mean specific force corrected by `model`
    and g the standard gravity the FMU's filter compares with (IMU_ATTITUDE_GRAVITY)."""
    out = []
    for d in datasets:
        if not d.has("acc"):
            continue
        rests = [w for w in detect_rest(d).rests if np.all(np.isfinite(w.acc))]
        if not rests:
            continue
        f = apply_thermal(model, np.array([w.acc for w in rests]), np.array([w.temp for w in rests]))
        out += [(d.name, abs(float(n) / STANDARD_GRAVITY - 1.0)) for n in np.linalg.norm(f, axis=1)]
    return out


def acc_norm_tolerance_setting(datasets: list[ImuData], model: ThermalModel, notes: list[str]) -> dict[str, float]:
    """{'acc_norm_tolerance': the largest rest departure} (rest_departures), or {} (the FMU's default
    0: every departure is taken for linear acceleration) with a note when no recording has a rest."""
    departures = rest_departures(datasets, model)
    if not departures:
        notes.append(f"{SETTING} = 0 (the FMU's default): no calibration recording shows the accelerometer at "
                     "rest, so its own norm error is unknown and the filter takes every departure of the "
                     "specific-force norm from g for linear acceleration")
        return {}
    name, worst = max(departures, key=lambda item: item[1])
    notes.append(f"{SETTING} = {worst:.4f}: the corrected specific force of the {len(departures)} rest(s) of the "
                 f"calibration recordings departs from standard gravity by up to {100 * worst:.2f} % ({name}); the "
                 "attitude filter's motion bias estimate counts only a departure beyond it as linear acceleration")
    return {SETTING: worst}
