"""Time alignment of the triads (sources/ImuAlign.c) and the auxiliary inputs, through the batch
runtime, the FMU and `imufmu run`, against closed-form truth."""
from __future__ import annotations

import numpy as np
import pytest
from fmpy import read_model_description

from contract import layout
from contract.errors import DataError
from fmu.cosim import run_fmu
from fmu.packer import fmu_aux_columns
from training import runtime
from training.cli import main
from training.data.dataset import ImuData
from training.data.io import read_imu_csv, write_imu_csv
from training.fmu_build import build_fmu

DT = 0.01                 # s, sample interval
G = 9.80665               # m/s²
FIELD = np.array([20.0, 5.0, 40.0])  # µT, body field at t = 0
OUT = {name: i for i, name in enumerate(layout.OUTPUTS)}
RATE, FIELD_OUT, ACCEL = (slice(OUT[f"{q}_x"], OUT[f"{q}_z"] + 1) for q in ("rate", "field", "accel"))
#: Rotation about a fixed axis at a rate linear in time: the trapezoid on the buffered gyro and the
#: interpolated partial interval are exact, so only rounding remains (measured ~1e-15 relative);
#: 1e-6 relative is the bound of the issue.
ROTATION_RTOL = 1e-6
#: Interpolation and extrapolation are a few double operations on values of order 1: a few ulps.
INTERPOLATION_ATOL = 1e-12
#: FMU (fmpy's CMake) and batch library run the same C code with other flags (tests/test_fmu.py).
GOLDEN_TOLERANCE = 1e-12


def _rz(angle: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotations about z by angle [rad]."""
    c, s, z, o = np.cos(angle), np.sin(angle), np.zeros_like(angle), np.ones_like(angle)
    return np.stack([c, -s, z, s, c, z, z, z, o], axis=1).reshape(-1, 3, 3)


def _inputs(t, gyr, acc=None, mag=None) -> np.ndarray:
    """(N, len(INPUTS)): the triads (default: level at rest in FIELD), 25 °C, auxiliary inputs 0."""
    n = t.size
    acc = np.tile([0.0, 0.0, -G], (n, 1)) if acc is None else acc
    mag = np.tile(FIELD, (n, 1)) if mag is None else mag
    return np.column_stack([gyr, acc, mag, np.full(n, 25.0), np.zeros((n, len(layout.AUX_INPUTS)))])


def _run(x, t, **settings) -> np.ndarray:
    return runtime.run_batch(np.array(layout.identity_coefficients()), np.array(layout.settings_array(settings)),
                             t, x)


def _turning_about_z(n, rate0, ramp):
    """t, gyro [rad/s] turning about z at rate0 + ramp·t, and the body field of that turn:
    a world-fixed vector in body axes, FIELD rotated by -angle (dx/dt = -w x x)."""
    t = np.arange(n) * DT

    def field(tt):
        return np.einsum("nij,j->ni", _rz(-(rate0 * tt + 0.5 * ramp * tt * tt)), FIELD)
    gyr = np.column_stack([np.zeros(n), np.zeros(n), rate0 + ramp * t])
    return t, gyr, field


@pytest.mark.parametrize("ramp", [0.0, 0.8], ids=["constant rate", "rate ramp"])
def test_lagging_magnetometer_is_rotated_forward_to_the_true_field(ramp):
    lag_samples = 3
    t, gyr, field = _turning_about_z(300, 0.7, ramp)
    delayed = field(t - lag_samples * DT)
    out = _run(_inputs(t, gyr, mag=delayed), t, lag_mag=lag_samples * DT)
    truth = field(t)
    error = np.linalg.norm(out[lag_samples:, FIELD_OUT] - truth[lag_samples:], axis=1) / np.linalg.norm(FIELD)
    assert error.max() < ROTATION_RTOL
    # unaligned, the error is the turn over 3 samples (~2 % of the field): the bound is meaningful
    assert np.linalg.norm(delayed[-1] - truth[-1]) / np.linalg.norm(FIELD) > 1e3 * ROTATION_RTOL


def test_rotation_skips_intervals_with_a_bad_gyro_sample():
    # The guard makes a bad gyro sample all-NaN; the rotation over [t - 3 dt, t] of the sample
    # after it then integrates only the one interval whose ends are both finite.
    t, gyr, field = _turning_about_z(50, 0.7, 0.0)
    gyr[20] = np.nan
    out = _run(_inputs(t, gyr, mag=field(t - 3 * DT)), t, lag_mag=3 * DT)
    expected = _rz(np.array([-0.7 * DT]))[0] @ field(t[21:22] - 3 * DT)[0]
    np.testing.assert_allclose(out[21, FIELD_OUT], expected, rtol=0, atol=ROTATION_RTOL * np.linalg.norm(FIELD))


def _smooth_rates(t):
    return np.column_stack([0.3 * np.sin(2.0 * t), 0.2 * np.cos(3.0 * t), 0.1 + 0.05 * t])


def test_leading_triads_are_interpolated_back():
    # Gyro and accelerometer lead true time by 2.5 samples: the outputs are the samples
    # interpolated 2.5 samples back (the oldest sample before the buffer reaches back so far).
    t = np.arange(200) * DT
    gyr = _smooth_rates(t)
    acc = np.column_stack([np.sin(t), np.cos(t), -G + 0.1 * t])
    out = _run(_inputs(t, gyr, acc=acc), t, lag_gyr=-2.5 * DT, lag_acc=-2.5 * DT)
    back = np.maximum(t - 2.5 * DT, t[0])
    for cols, x in ((RATE, gyr), (ACCEL, acc)):
        expected = np.column_stack([np.interp(back, t, x[:, i]) for i in range(3)])
        np.testing.assert_allclose(out[:, cols], expected, rtol=0, atol=INTERPOLATION_ATOL)
    np.testing.assert_allclose(out[3:, RATE], 0.5 * (gyr[:-3] + gyr[1:-2]), rtol=0, atol=INTERPOLATION_ATOL)


def test_lagging_gyro_is_extrapolated_to_true_time():
    # A gyro lagging by 2.5 samples on a rate linear in time: 2 w(t) - w(t - lag) is exact.
    t = np.arange(100) * DT
    lag = 2.5 * DT
    truth = np.column_stack([0.2 + 0.5 * t, -0.1 + 0.3 * t, 0.05 - 0.2 * t])
    measured = np.column_stack([0.2 + 0.5 * (t - lag), -0.1 + 0.3 * (t - lag), 0.05 - 0.2 * (t - lag)])
    out = _run(_inputs(t, measured), t, lag_gyr=lag)
    np.testing.assert_allclose(out[3:, RATE], truth[3:], rtol=0, atol=INTERPOLATION_ATOL)


def test_a_lag_beyond_the_buffer_uses_its_oldest_sample():
    t = np.arange(150) * DT
    gyr = _smooth_rates(t)
    out = _run(_inputs(t, gyr), t, lag_gyr=-1.0)  # 100 samples back; the buffer holds 64
    reach = 63
    np.testing.assert_array_equal(out[reach:, RATE], gyr[:-reach])


@pytest.mark.parametrize("name, lag", [("lag_gyr", -1.0), ("lag_acc", 0.7), ("lag_mag", 0.64)])
def test_a_lag_beyond_the_full_buffer_is_flagged_not_while_it_fills(name, lag):
    """Issue 31 item 10: a lag the buffer cannot reach (its span is 63 steps = 0.63 s here) used to
    be clamped without a word; now calibration_valid = 0 once the buffer is full (sample 63 on),
    and not while it fills at start-up, nor for a lag within the span (0.62 s)."""
    t = np.arange(150) * DT
    x = _inputs(t, _smooth_rates(t))
    valid = OUT["calibration_valid"]
    np.testing.assert_array_equal(np.flatnonzero(_run(x, t, **{name: lag})[:, valid] == 0.0), np.arange(63, 150))
    assert np.all(_run(x, t, **{name: np.sign(lag) * 0.62})[:, valid] == 1.0)


def test_zero_lags_change_nothing_bit_for_bit():
    t = np.arange(200) * DT
    _, gyr, field = _turning_about_z(200, 0.7, 0.8)
    x = _inputs(t, gyr, acc=np.column_stack([np.sin(t), np.cos(t), np.full(t.size, -G)]), mag=field(t))
    plain = _run(x, t)
    assert np.array_equal(plain[:, :9], x[:, :9])
    gyro_only = _run(x, t, lag_gyr=-2.5 * DT)  # another triad's lag leaves acc and mag alone
    assert np.array_equal(gyro_only[:, ACCEL], plain[:, ACCEL])
    assert np.array_equal(gyro_only[:, FIELD_OUT], plain[:, FIELD_OUT])
    assert not np.array_equal(gyro_only[:, RATE], plain[:, RATE])


@pytest.mark.parametrize("name, value", [("lag_gyr", 1.5), ("lag_acc", -1.01), ("lag_mag", np.nan)])
def test_lag_out_of_range_is_rejected_naming_it(name, value):
    t = np.arange(3) * DT
    with pytest.raises(ValueError, match=rf"{name} must be finite and within \[-1, 1\] s"):
        _run(_inputs(t, np.zeros((3, 3))), t, **{name: value})


# ---------------------------------------------------------------- auxiliary inputs end to end

AUX = [{"column": "aux_motor_current", "unit": "A", "meaning": "motor current"}]
#: A motor-current term on the gyro z axis [rad/s per A], bounded to the current range it was
#: fitted on [A].
TERMS = [("gyr_z", "aux_1", None, 2e-3, -1.0, 1.5)]
LAGS = {"lag_gyr": -0.02, "lag_mag": 0.03}


def _coefficients() -> np.ndarray:
    return np.array(layout.pack_coefficients([layout.identity_block()] * 3, layout.terms_block(TERMS)))


def _recording(n=400) -> ImuData:
    """A turning sensor with a motor current (A) that exceeds the term's upper bound at times."""
    t, gyr, field = _turning_about_z(n, 0.4, 0.2)
    current = 1.2 * np.sin(0.9 * t) + 0.5
    current[50:55] = np.nan  # a gap in the current log: the terms are skipped there
    return ImuData(t=t, gyr=gyr, acc=np.tile([0.0, 0.0, -G], (n, 1)), mag=field(t), temp=np.full(n, 25.0),
                   aux={"aux_heater": np.ones(n), "aux_motor_current": current}, name="motor")


@pytest.fixture(scope="module")
def aux_fmu(tmp_path_factory):
    return build_fmu(_coefficients(), LAGS, tmp_path_factory.mktemp("aux") / "ImuFusion.fmu", aux_inputs=AUX)


def test_inputs_map_the_model_columns_onto_the_aux_inputs():
    data = _recording()
    x = data.inputs(aux_columns=["aux_motor_current"])
    assert x.shape == (len(data), len(layout.INPUTS))
    k = layout.INPUTS.index("aux_1")
    assert np.array_equal(x[:, k], data.aux["aux_motor_current"], equal_nan=True)
    assert np.all(x[:, k + 1:] == 0.0) and np.all(data.inputs()[:, k:] == 0.0)
    with pytest.raises(DataError, match="motor.*aux_motor_torque"):
        data.inputs(aux_columns=["aux_motor_torque"])


def test_fmu_with_aux_inputs_and_lags_equals_the_batch_runtime(aux_fmu):
    data = _recording()
    x = data.inputs(aux_columns=fmu_aux_columns(aux_fmu))
    batch = runtime.run_batch(_coefficients(), np.array(layout.settings_array(LAGS)), data.t, x)
    np.testing.assert_allclose(run_fmu(aux_fmu, data.t, x), batch, rtol=0, atol=GOLDEN_TOLERANCE)
    # the bounded motor-current term is in the outputs: clamped at 1.5 A; where the current is NaN
    # the guard holds its last finite value (bad input, issue 31 item 6)
    plain = runtime.run_batch(np.array(layout.identity_coefficients()), np.array(layout.settings_array(LAGS)),
                              data.t, x)
    current = data.aux["aux_motor_current"]
    held = current.copy()
    for k in np.flatnonzero(np.isnan(current)):
        held[k] = held[k - 1]
    expected = 2e-3 * np.clip(held, -1.0, 1.5)
    np.testing.assert_allclose(plain[:, OUT["rate_z"]] - batch[:, OUT["rate_z"]], expected, rtol=0, atol=1e-12)


def test_model_description_names_the_aux_columns(aux_fmu):
    described = {v.name: v.description for v in read_model_description(str(aux_fmu)).modelVariables}
    assert described["aux_1"] == ("Auxiliary input 1: recording column aux_motor_current [A] (motor current); "
                                  "used by diagnosed correction terms")
    assert described["aux_2"] == "Auxiliary input 2: unused by this model (0)"
    assert fmu_aux_columns(aux_fmu) == ["aux_motor_current"]


def test_imufmu_run_feeds_the_recording_aux_columns(aux_fmu, tmp_path):
    data = _recording()
    path = write_imu_csv(data, tmp_path / "motor.csv")
    assert main(["run", str(aux_fmu), str(path), "--out", str(tmp_path / "out.csv")]) == 0
    got = np.loadtxt(tmp_path / "out.csv", delimiter=",", skiprows=1)[:, 1:]
    recording = read_imu_csv(path)
    expected = runtime.run_batch(_coefficients(), np.array(layout.settings_array(LAGS)), recording.t,
                                 recording.inputs(aux_columns=["aux_motor_current"]))
    np.testing.assert_allclose(got, expected, rtol=0, atol=GOLDEN_TOLERANCE)


def test_imufmu_run_names_a_missing_aux_column(aux_fmu, tmp_path, capsys):
    data = _recording()
    data.aux.pop("aux_motor_current")
    path = write_imu_csv(data, tmp_path / "no_current.csv")
    assert main(["run", str(aux_fmu), str(path), "--out", str(tmp_path / "out.csv")]) == 1
    message = capsys.readouterr().err.strip()
    assert message.startswith("imufmu run: error: no_current:") and "'aux_motor_current'" in message
    assert "\n" not in message
