"""`train`'s acc_norm_tolerance (training.attitude.acc_norm): the still accelerometer's own norm error,
read from the rests of the calibration recordings, against the scale error a constructed recording has."""
from __future__ import annotations

import dataclasses

import numpy as np

from training.attitude.acc_norm import SETTING, acc_norm_tolerance_setting, rest_departures
from training.data.dataset import ImuData
from training.models.thermal import ThermalModel

from rigid_motion import ideal_readings

DT = 0.01
#: Scale errors of the constructed accelerometer (raw per true): the rest with gravity on z shows 0.9 %.
SCALE = np.array([1.004, 0.995, 1.009])
#: Noise [m/s²] per sample; a rest mean of >= 200 samples has <= 0.0014 m/s² of it, 1.4e-4 relative.
NOISE = 0.02
#: Bound [1] on the read departure against the true one: 3.5 times the rest mean's relative noise (half
#: the smallest difference between two of the scale errors, so a rest read in the wrong pose fails).
BOUND = 5e-4


def _recording() -> ImuData:
    """3 s still level, a 2 s turn of 90° about x (gravity then along y), 3 s still, a 2 s turn of 90° about
    z (gravity then along x), 3 s still: three poses, gravity along z, y and x in turn; scaled by SCALE."""
    phases = [(3.0, (0, 0, 0)), (2.0, (np.pi / 4, 0, 0)), (3.0, (0, 0, 0)), (2.0, (0, 0, np.pi / 4)), (3.0, (0, 0, 0))]
    rate = np.concatenate([np.tile(r, (int(round(s / DT)), 1)) for s, r in phases])
    _, acc, mag = ideal_readings(rate, DT)
    rng = np.random.default_rng(3)
    n = len(rate)
    return ImuData(t=np.arange(n) * DT, gyr=rate + 0.002 * rng.standard_normal((n, 3)),
                   acc=acc * SCALE + NOISE * rng.standard_normal((n, 3)),
                   mag=mag + 0.3 * rng.standard_normal((n, 3)), temp=np.full(n, np.nan), name="constructed")


def test_the_departure_of_each_rest_is_the_scale_error_along_gravity():
    departures = [v for _, v in rest_departures([_recording()], ThermalModel.identity())]
    np.testing.assert_allclose(departures, np.abs(SCALE[[2, 1, 0]] - 1.0), rtol=0, atol=BOUND)


def test_a_calibration_that_removes_the_scale_error_leaves_no_departure():
    corrected = dataclasses.replace(ThermalModel.identity(), A=np.diag(1.0 / SCALE))
    assert max(v for _, v in rest_departures([_recording()], corrected)) < BOUND


def test_train_writes_the_largest_departure_and_says_where():
    notes: list[str] = []
    setting = acc_norm_tolerance_setting([_recording()], ThermalModel.identity(), notes)
    assert abs(setting[SETTING] - 0.009) < BOUND
    assert any(n.startswith(f"{SETTING} = 0.009") and "constructed" in n for n in notes)


def test_without_a_rest_the_default_stays_and_the_note_says_why():
    d = _recording()
    d.gyr = d.gyr + np.array([0.0, 0.0, 0.5])       # turning about z all the time: no rest
    d.acc = d.acc + 0.5 * np.sin(np.arange(len(d))[:, None] * 0.3)
    notes: list[str] = []
    assert acc_norm_tolerance_setting([d], ThermalModel.identity(), notes) == {}
    assert any(n.startswith(f"{SETTING} = 0 (the FMU's default)") for n in notes)
