"""`imufmu import` (training/data/importer.py): a user's CSV or .mat file -> imu-csv/1.

The two shared recordings that were converted from other tools' examples come back from files
written in those tools' formats (units converted back, the original header) to the last digit the
formats carry; every unit conversion is checked against its closed form; every refusal is one line
naming the input file (tests/cli_errors.py).
"""
from __future__ import annotations

import gzip
import json
import math
from decimal import Decimal
from pathlib import Path

import numpy as np
import pytest
import scipy.io

from cli_errors import fails
from conftest import SHARED_DATA
from training.cli import main
from training.data import io as io_module
from training.data import source_table
from training.data.column_names import recognise
from training.data.importer import ImportOptions, import_recording
from training.data.io import read_imu_csv
from training.data.units import STANDARD_GRAVITY, parse_unit

XIO = SHARED_DATA / "xio_handheld" / "xio_handheld.csv.gz"
FERRARIS = SHARED_DATA / "imucal_ferraris" / "ferraris_session.csv.gz"
#: Fusion's Examples/Python/sensor_data.csv header (xioTechnologies/Fusion).
XIO_HEADER = ("Time (s),Gyroscope X (deg/s),Gyroscope Y (deg/s),Gyroscope Z (deg/s),Accelerometer X (g),"
              "Accelerometer Y (g),Accelerometer Z (g),Magnetometer X (uT),Magnetometer Y (uT),Magnetometer Z (uT)")
#: imucal's example_data/example_ferraris_session.csv header (mad-lab-fau/imucal).
IMUCAL_HEADER = "n_samples,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z"
#: x-io's file prints its values with 7 significant digits ('0.01644619', '0.9970807').
XIO_DIGITS = 7


def _shared(path: Path) -> Path:
    if not path.is_file():
        pytest.skip(f"shared recording not found at {path}")
    return path


def _cells(path: Path) -> list[list[str]]:
    """The data cells of a CSV(.gz) as text."""
    opener = gzip.open if path.name.endswith(".gz") else open
    with opener(path, "rt") as f:
        return [line.split(",") for line in f.read().splitlines()[1:]]


def _rows(n: int = 200, rate: float = 100.0, seed: int = 0) -> dict[str, np.ndarray]:
    """A plausible recording in SI units: t [s], gyr [rad/s], acc [m/s²], mag [µT], temp [°C]."""
    rng = np.random.default_rng(seed)
    return {"t": np.arange(n) / rate, "gyr": rng.normal(0.0, 0.5, (n, 3)),
            "acc": np.array([0.1, -0.2, -9.8]) + rng.normal(0.0, 0.2, (n, 3)),
            "mag": np.array([20.0, -3.0, 42.0]) + rng.normal(0.0, 0.5, (n, 3)),
            "temp": 25.0 + rng.normal(0.0, 0.1, n)}


def _write(path: Path, header: list[str], columns: list[np.ndarray], delimiter: str = ",",
           fmt=repr) -> Path:
    """A delimited text file with `header` and one row per sample of `columns`."""
    lines = [delimiter.join(header)]
    lines += [delimiter.join(fmt(float(v)) for v in row) for row in zip(*columns)]
    path.write_text("\n".join(lines) + "\n")
    return path


def _user_csv(tmp_path: Path, name: str = "user.csv", delimiter: str = ",", fmt=repr, **kw) -> Path:
    """A user's file: time [ms], gyro [deg/s], acc [g], mag [nT], temperature [°C], plus 'status'."""
    d = _rows(**kw)
    header = ["Time", "GyroX", "GyroY", "GyroZ", "AccX", "AccY", "AccZ", "MagX", "MagY", "MagZ", "Temp", "Status"]
    cols = [d["t"] * 1e3, *np.degrees(d["gyr"]).T, *(d["acc"] / STANDARD_GRAVITY).T, *(d["mag"] * 1e3).T,
            d["temp"], np.ones(len(d["t"]))]
    return _write(tmp_path / name, header, cols, delimiter, fmt)


USER_UNITS = ["t=ms,gyr=deg/s,acc=g,mag=nT,temp=C"]


# ------------------------------------------------------------------ the two shared recordings


def _xio_original(tmp_path: Path) -> Path:
    """The shared x-io log written back in x-io's format: deg/s, g, µT at 7 significant digits."""
    a = read_imu_csv(_shared(XIO))
    cols = [a.t, *np.degrees(a.gyr).T, *(a.acc / STANDARD_GRAVITY).T, *a.mag.T]
    digits = [repr] + [lambda v: f"{v:.{XIO_DIGITS}g}"] * 9
    lines = [XIO_HEADER] + [",".join(f(float(v)) for f, v in zip(digits, row)) for row in zip(*cols)]
    (tmp_path / "sensor_data.csv").write_text("\n".join(lines) + "\n")
    return tmp_path / "sensor_data.csv"


def test_xio_format_reproduces_the_shared_recording_bit_for_bit(tmp_path, capsys):
    source = _xio_original(tmp_path)
    assert main(["import", str(source), "--out", str(tmp_path / "xio.csv.gz")]) == 0
    out = capsys.readouterr().out
    shared, ours = read_imu_csv(XIO), read_imu_csv(tmp_path / "xio.csv.gz")
    # deg/s × (π/180) and g × 9.80665 of the 7-digit values give the shared doubles exactly
    for name in ("t", "gyr", "acc", "mag"):
        assert np.array_equal(getattr(ours, name), getattr(shared, name)), name
    assert np.isnan(ours.temp).all()
    meta = json.loads((tmp_path / "xio.json").read_text())
    assert meta["reference"] == "none" and "x-io" in meta["source"] and "x-io" in meta["sensor"]
    assert meta["rate_hz"] == 99.2125  # 1 / the median step, 6 digits (the shared sidecar says the nominal 100)
    assert "deg/s -> rad/s" in meta["notes"] and "g -> m/s²" in meta["notes"] and "temp" in meta["notes"]
    assert "recognised the x-io Technologies CSV format" in out
    assert f"{len(shared)} rows" in out and "next: imufmu train" in out


def test_imucal_format_reproduces_the_shared_recording_to_its_printed_digits(tmp_path):
    shared_cells = _cells(_shared(FERRARIS))
    a = read_imu_csv(FERRARIS)
    source = _write(tmp_path / "example_ferraris_session.csv", IMUCAL_HEADER.split(","),
                    [np.arange(len(a)), *np.degrees(a.gyr).T, *a.acc.T])
    result = import_recording(source, tmp_path / "ferraris.csv.gz")
    ours = _cells(result.path)
    assert len(ours) == len(shared_cells) == 10376
    worst = 0.0
    for mine, theirs in zip(ours, shared_cells):
        for x, y in zip(mine[:7], theirs[:7]):   # t, gyr, acc; the shared file prints 6 decimals / 9 digits
            half_unit = Decimal(1).scaleb(Decimal(y).as_tuple().exponent) / 2
            worst = max(worst, float(abs(Decimal(x) - Decimal(y)) / half_unit))
    assert worst <= 1.0  # within half a unit of the shared file's last digit, every cell
    assert all(c == "" for row in ours for c in row[7:])  # no magnetometer, no temperature
    meta = json.loads((tmp_path / "ferraris.json").read_text())
    assert meta["rate_hz"] == 102.4 and meta["reference"] == "none" and "imucal" in meta["source"]


def test_imucal_rate_can_be_overridden(tmp_path):
    d = _rows(n=50)
    source = _write(tmp_path / "s.csv", IMUCAL_HEADER.split(","), [np.arange(50), *np.degrees(d["gyr"]).T, *d["acc"].T])
    result = import_recording(source, tmp_path / "o.csv", ImportOptions(rate_hz=200.0))
    data = read_imu_csv(result.path)
    assert data.t[1] == 1.0 / 200.0 and data.meta["rate_hz"] == 200.0


# ------------------------------------------------------------------------ units: closed forms


@pytest.mark.parametrize("quantity, unit, value, expected", [
    ("gyr", "deg/s", 180.0, math.pi), ("gyr", "dps", 90.0, math.pi / 2), ("gyr", "°/s", 1.0, math.pi / 180),
    ("gyr", "rad/s", 1.5, 1.5), ("gyr", "rpm", 60.0, 2 * math.pi), ("gyr", "mdps", 1000.0, math.pi / 180),
    ("gyr", "counts:0.0152587890625deg/s", 65536.0, math.radians(1000.0)),
    ("gyr", "counts:1/131deg/s", 131.0, math.pi / 180),
    ("acc", "g", 1.0, 9.80665), ("acc", "mg", 1000.0, 9.80665), ("acc", "m/s^2", 9.0, 9.0), ("acc", "m/s²", 2.0, 2.0),
    ("acc", "counts:0.000598755g", 16384.0, 16384 * 0.000598755 * 9.80665),
    ("mag", "uT", 48.0, 48.0), ("mag", "µT", 48.0, 48.0), ("mag", "nT", 48000.0, 48.0), ("mag", "mT", 0.048, 48.0),
    ("mag", "mG", 480.0, 48.0), ("mag", "G", 0.48, 48.0), ("mag", "gauss", 0.48, 48.0), ("mag", "T", 48e-6, 48.0),
    ("mag", "counts:0.15uT", 320.0, 48.0),
    ("t", "s", 2.0, 2.0), ("t", "ms", 2000.0, 2.0), ("t", "us", 2e6, 2.0), ("t", "ns", 2e9, 2.0),
    ("temp", "C", 25.0, 25.0), ("temp", "K", 298.15, 25.0), ("temp", "F", 77.0, 25.0), ("temp", "F", -40.0, -40.0),
    ("temp", "counts:1/340C+36.53", 340.0, 37.53), ("temp", "counts:0.5C-10", 100.0, 40.0),
])
def test_unit_conversion_closed_forms(quantity, unit, value, expected):
    assert parse_unit(quantity, unit, "test").apply(value) == pytest.approx(expected, rel=1e-14, abs=1e-12)


def test_user_file_is_converted_with_the_given_units(tmp_path, capsys):
    d = _rows()
    source = _user_csv(tmp_path)
    assert main(["import", str(source), "--out", str(tmp_path / "u.csv.gz"), "--units", USER_UNITS[0]]) == 0
    out = capsys.readouterr().out
    data = read_imu_csv(tmp_path / "u.csv.gz")
    np.testing.assert_allclose(data.t, d["t"], rtol=1e-15, atol=1e-15)
    np.testing.assert_allclose(data.gyr, d["gyr"], rtol=1e-15)
    np.testing.assert_allclose(data.acc, d["acc"], rtol=1e-15)
    np.testing.assert_allclose(data.mag, d["mag"], rtol=1e-15)
    np.testing.assert_array_equal(data.temp, d["temp"])
    assert "'Status'" in out.split("not imported:")[1]            # the unmapped column is listed
    assert "Status" in data.meta["notes"]
    assert "nT -> µT (× 0.001)" in out and "ms -> s (× 0.001)" in out
    gyr_row = next(line for line in out.splitlines() if line.strip().startswith("GyroX"))
    low, high = d["gyr"][:, 0].min(), d["gyr"][:, 0].max()
    assert f"{low:.4g} .. {high:.4g} rad/s" in gyr_row               # the range after conversion
    assert "200 rows" in out and "1.99 s" in out and "100 Hz" in out


@pytest.mark.parametrize("delimiter, decimal_comma", [(",", False), (";", False), (";", True), ("\t", False),
                                                        ("\t", True), (" ", False)])
def test_every_delimiter_gives_the_same_recording(tmp_path, delimiter, decimal_comma):
    fmt = (lambda v: repr(v).replace(".", ",")) if decimal_comma else repr
    reference = import_recording(_user_csv(tmp_path, "ref.csv"), tmp_path / "ref_out.csv",
                                 ImportOptions(units=tuple(USER_UNITS)))
    source = _user_csv(tmp_path, "d.txt", delimiter, fmt)
    result = import_recording(source, tmp_path / "out.csv", ImportOptions(units=tuple(USER_UNITS)))
    assert _cells(result.path) == _cells(reference.path)


def test_header_units_are_used_and_the_command_line_wins(tmp_path):
    d = _rows()
    header = ["time_s", "gyro_x (deg/s)", "gyro_y (deg/s)", "gyro_z (deg/s)", "acc_x [g]", "acc_y [g]", "acc_z [g]"]
    source = _write(tmp_path / "h.csv", header, [d["t"], *np.degrees(d["gyr"]).T, *(d["acc"] / STANDARD_GRAVITY).T])
    data = read_imu_csv(import_recording(source, tmp_path / "a.csv").path)
    np.testing.assert_allclose(data.gyr, d["gyr"], rtol=1e-15)
    np.testing.assert_allclose(data.acc, d["acc"], rtol=1e-15)
    # the command line wins: the same numbers read as rad/s are 180/π times larger
    small = _write(tmp_path / "s.csv", header, [d["t"], *(d["gyr"] * 0.01).T, *(d["acc"] / STANDARD_GRAVITY).T])
    result = import_recording(small, tmp_path / "b.csv", ImportOptions(units=("gyr=rad/s",)))
    np.testing.assert_array_equal(read_imu_csv(result.path).gyr, d["gyr"] * 0.01)
    assert "--units gyr=rad/s overrides the header's 'deg/s'" in result.summary


@pytest.mark.parametrize("name, target, unit", [
    ("gyr_x", "gyr_x", None), ("gyro_x", "gyr_x", None), ("gx", "gyr_x", None), ("GyroY", "gyr_y", None),
    ("Gyroscope X (deg/s)", "gyr_x", "deg/s"), ("gyro_z_dps", "gyr_z", "dps"), ("acc_x", "acc_x", None),
    ("ax", "acc_x", None), ("Accelerometer X (g)", "acc_x", "g"), ("accel_y [m/s^2]", "acc_y", "m/s^2"),
    ("mag_x", "mag_x", None), ("Magnetometer X (uT)", "mag_x", "uT"), ("MagZ", "mag_z", None), ("mx", "mag_x", None),
    ("time", "t", None), ("t", "t", None), ("timestamp", "t", None), ("Time (s)", "t", "s"), ("time_ms", "t", "ms"),
    ("n_samples", "t", "samples"), ("temp", "temp", None), ("temperature", "temp", None),
    ("Temperature (degC)", "temp", "degC"), ("imu.gyro(:,2)", "gyr_y", None), ("raw_acc_z", "acc_z", None),
    ("linear_acceleration_x", None, None), ("qx", None, None), ("Barometer (hPa)", None, "hPa"), ("W", None, None),
])
def test_common_column_names_are_recognised(name, target, unit):
    assert recognise(name) == (target, unit)


# ------------------------------------------------------------------------------------- time


def test_absolute_clock_is_shifted_to_zero_and_said(tmp_path):
    d = _rows()
    source = _write(tmp_path / "c.csv", ["timestamp", "gx", "gy", "gz"], [1.7e12 + d["t"] * 1e3, *d["gyr"].T])
    result = import_recording(source, tmp_path / "c_out.csv", ImportOptions(units=("t=ms", "gyr=rad/s")))
    data = read_imu_csv(result.path)
    np.testing.assert_allclose(data.t, d["t"], atol=1e-9)   # ms since the epoch: 2^-12 ms resolution at 1.7e12
    assert data.t[0] == 0.0 and "began at 1700000000000 ms, shifted" in result.summary


def test_clock_stamps_need_no_unit(tmp_path):
    stamps = [f"2024-05-01T12:00:{k * 0.01:09.6f}" for k in range(100)]
    d = _rows(n=100)
    lines = ["Time,GX,GY,GZ"] + [f"{s},{g[0]!r},{g[1]!r},{g[2]!r}" for s, g in zip(stamps, d["gyr"].tolist())]
    (tmp_path / "iso.csv").write_text("\n".join(lines) + "\n")
    data = read_imu_csv(import_recording(tmp_path / "iso.csv", tmp_path / "iso_out.csv",
                                         ImportOptions(units=("gyr=rad/s",))).path)
    np.testing.assert_allclose(data.t, np.arange(100) * 0.01, atol=1e-6)


def test_counter_and_rate_give_time(tmp_path):
    d = _rows(n=100)
    counter = np.arange(100) + 4000.0
    counter[50:] += 3  # three lost samples: a gap of 4 steps in t
    source = _write(tmp_path / "n.csv", ["sample", "gx", "gy", "gz"], [counter, *d["gyr"].T])
    data = read_imu_csv(import_recording(source, tmp_path / "n_out.csv",
                                         ImportOptions(units=("gyr=rad/s",), rate_hz=200.0)).path)
    np.testing.assert_array_equal(data.t, (counter - 4000.0) / 200.0)


def test_no_time_column_uses_the_rate(tmp_path):
    d = _rows(n=100)
    source = _write(tmp_path / "r.csv", ["gx", "gy", "gz"], [*d["gyr"].T])
    result = import_recording(source, tmp_path / "r_out.csv", ImportOptions(units=("gyr=rad/s",), rate_hz=50.0))
    data = read_imu_csv(result.path)
    np.testing.assert_array_equal(data.t, np.arange(100) / 50.0)
    assert data.meta["rate_hz"] == 50.0 and "t = n / 50 Hz" in result.summary


def test_columns_map_and_triad_form(tmp_path):
    d = _rows()
    header = ["clock", "w1", "w2", "w3", "f1", "f2", "f3", "heater"]
    source = _write(tmp_path / "m.csv", header, [d["t"], *d["gyr"].T, *d["acc"].T, d["temp"]])
    result = import_recording(source, tmp_path / "m_out.csv", ImportOptions(
        columns=("t=clock,gyr=w1,w2,w3", "acc_x=f1,acc_y=f2,acc_z=f3", "aux_heater=heater"),
        units=("t=s,gyr=rad/s,acc=m/s2",)))
    data = read_imu_csv(result.path)
    np.testing.assert_array_equal(data.gyr, d["gyr"])
    np.testing.assert_array_equal(data.acc, d["acc"])
    np.testing.assert_array_equal(data.aux["aux_heater"], d["temp"])


def test_large_files_are_read_and_written_in_blocks_with_a_progress_bar(tmp_path, monkeypatch, capsys):
    source = _user_csv(tmp_path, n=1000)
    whole = import_recording(source, tmp_path / "whole.csv.gz", ImportOptions(units=tuple(USER_UNITS)))
    monkeypatch.setattr(source_table, "BLOCK_LINES", 7)
    monkeypatch.setattr(source_table, "PROGRESS_BYTES", 0)
    monkeypatch.setattr(io_module, "WRITE_BLOCK_ROWS", 13)
    blocks = import_recording(source, tmp_path / "blocks.csv.gz", ImportOptions(units=tuple(USER_UNITS)))
    assert blocks.path.read_bytes() == whole.path.read_bytes()   # the same gzip bytes, block by block
    assert "import: reading user.csv" in capsys.readouterr().err


# ------------------------------------------------------------------------------------ MATLAB


def test_mat_struct_with_matrices(tmp_path):
    d = _rows()
    scipy.io.savemat(tmp_path / "rec.mat", {"imu": {"gyro": np.degrees(d["gyr"]), "acc": d["acc"].T / STANDARD_GRAVITY,
                                                    "time": d["t"][:, None]}, "fs": 100.0})
    result = import_recording(tmp_path / "rec.mat", tmp_path / "mat.csv.gz",
                              ImportOptions(units=("gyr=deg/s,acc=g,t=s",)))
    data = read_imu_csv(result.path)
    np.testing.assert_allclose(data.gyr, d["gyr"], rtol=1e-15)
    np.testing.assert_allclose(data.acc, d["acc"], rtol=1e-15)   # a 3×N matrix is turned
    assert "imu.gyro(:,1)" in result.summary and "'fs (a single value, 100)'" in result.summary


def test_mat_separate_variables_named_by_columns(tmp_path):
    d = _rows()
    scipy.io.savemat(tmp_path / "v.mat", {"wx": d["gyr"][:, 0], "wy": d["gyr"][:, 1], "wz": d["gyr"][:, 2],
                                          "stamp": d["t"], "label": "run 3"})
    result = import_recording(tmp_path / "v.mat", tmp_path / "v.csv",
                              ImportOptions(columns=("t=stamp",), units=("gyr=rad/s,t=s",)))
    np.testing.assert_array_equal(read_imu_csv(result.path).gyr, d["gyr"])
    assert "label (not a numeric array" in result.summary


# ------------------------------------------------------------------- one-line errors via the CLI


def _cli(source: Path, tmp_path: Path, *extra: str) -> list[str]:
    return ["import", str(source), "--out", str(tmp_path / "out.csv.gz"), *extra]


def _v73(tmp_path: Path, marked: bool) -> Path:
    """A MATLAB v7.3 (HDF5) file's header: its text, or only the version bytes scipy reads."""
    text = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, HDF5 schema 1.00 ." if marked else b""
    path = tmp_path / "big.mat"
    path.write_bytes(text.ljust(124, b" ") + b"\x00\x02IM" + b"\x89HDF\r\n\x1a\n" + bytes(512))
    return path


ERRORS = [  # (name, how to make the input: tmp_path -> argv tail, needles)
    ("missing file", lambda p: _cli(p / "nope.csv", p), ["nope.csv", "not found"]),
    ("no header", lambda p: _cli(_write(p / "nh.csv", ["0", "1", "2"], [np.arange(3.0)] * 3), p),
     ["nh.csv", "header row is required"]),
    ("no unit", lambda p: _cli(_user_csv(p), p, "--units", "t=ms,acc=g,mag=nT,temp=C"),
     ["user.csv", "gyroscope columns 'GyroX', 'GyroY', 'GyroZ' carry no unit", "--units gyr="]),
    ("unknown unit", lambda p: _cli(_user_csv(p), p, "--units", "gyr=furlong/s"), ["--units gyr=furlong/s", "deg/s"]),
    ("counts without scale", lambda p: _cli(_write(p / "c.csv", ["t (s)", "gx (LSB)", "gy (LSB)", "gz (LSB)"],
                                                   [np.arange(20) / 100.0] * 4), p),
     ["c.csv", "column 'gx (LSB)'", "counts:0.0152587890625deg/s"]),
    ("bad counts", lambda p: _cli(_user_csv(p), p, "--units", "gyr=counts:deg/s"), ["counts:LSB_VALUE UNIT"]),
    ("unknown target", lambda p: _cli(_user_csv(p), p, "--columns", "gyro=GyroX"), ["unknown target 'gyro'"]),
    ("unknown source", lambda p: _cli(_user_csv(p), p, "--columns", "gyr_x=Nope"), ["gyr_x=Nope", "no such column",
                                                                                    "'GyroX'"]),
    ("partial triad", lambda p: _cli(_write(p / "pt.csv", ["t", "gx", "gy"], [np.arange(20.0)] * 3), p),
     ["pt.csv", "gyroscope: found gyr_x <- 'gx', gyr_y <- 'gy' but no gyr_z"]),
    ("no triad", lambda p: _cli(_write(p / "nt.csv", ["time", "pressure"], [np.arange(20.0)] * 2), p),
     ["nt.csv", "no column recognised"]),
    ("ambiguous", lambda p: _cli(_write(p / "am.csv", ["t", "gx", "gyro_x", "gy", "gz"], [np.arange(20.0)] * 5), p),
     ["am.csv", "'gx' and 'gyro_x' both look like gyr_x"]),
    ("no time", lambda p: _cli(_write(p / "nti.csv", ["gx", "gy", "gz"], [np.arange(20.0)] * 3), p,
                               "--units", "gyr=rad/s"), ["nti.csv", "no time column", "--rate HZ"]),
    ("counter without rate", lambda p: _cli(_write(p / "cn.csv", ["index", "gx", "gy", "gz"], [np.arange(20.0)] * 4),
                                            p, "--units", "gyr=rad/s"), ["cn.csv", "counts samples", "--rate"]),
    ("time not increasing", lambda p: _cli(_write(p / "ti.csv", ["t (s)", "gx", "gy", "gz"],
                                                  [np.array([0.0, 0.01, 0.01, 0.03])] * 4), p, "--units", "gyr=rad/s"),
     ["ti.csv, row 4, column 't (s)'", "not strictly increasing"]),
    ("ragged row", lambda p: _cli(_ragged(p), p, "--units", "gyr=rad/s"), ["rg.csv, row 6", "row has 5 fields, the header has 4"]),
    ("not a number", lambda p: _cli(_bad_cell(p), p, "--units", "gyr=rad/s"), ["bc.csv, row 5, column 'gy'",
                                                                               "not a number: 'oops'"]),
    ("degrees read as radians", lambda p: _cli(_user_csv(p), p, "--units", "t=ms,gyr=rad/s,acc=g,mag=nT,temp=C"),
     ["user.csv", "'GyroX, GyroY, GyroZ'", "looks like deg/s", "--units gyr="]),
    ("g read as m/s2", lambda p: _cli(_user_csv(p), p, "--units", "t=ms,gyr=deg/s,acc=m/s2,mag=nT,temp=C"),
     ["user.csv", "looks like g", "--units acc="]),
    ("value out of range", lambda p: _cli(_spike(p), p, "--units", "gyr=rad/s"),
     ["sp.csv, row 8, column 'gx'", "outside -100..100 rad/s"]),
    ("time in ms read as s", lambda p: _cli(_user_csv(p), p, "--units", "t=s,gyr=deg/s,acc=g,mag=nT,temp=C",
                                            "--rate", "100"), ["user.csv", "column 'Time'", "milliseconds"]),
    ("v7.3 by its text", lambda p: _cli(_v73(p, True), p), ["big.mat", "v7.3", "'-v7'"]),
    ("v7.3 by its version", lambda p: _cli(_v73(p, False), p), ["big.mat", "v7.3", "'-v7'"]),
    ("not a mat file", lambda p: _cli(_garbage(p / "x.mat"), p), ["x.mat", "cannot read as a MATLAB .mat file"]),
    ("no delimiter", lambda p: _cli(_garbage_text(p), p), ["gt.csv", "cannot tell the delimiter"]),
    ("bad out", lambda p: ["import", str(_user_csv(p)), "--out", str(p / "out.txt")], ["out.txt", "NAME.csv.gz"]),
    ("out is input", lambda p: ["import", str(_user_csv(p)), "--out", str(p / "user.csv")], ["would write over this input"]),
    ("bad reference", lambda p: _cli(_user_csv(p), p, "--reference", "vibes"), ["--reference vibes", "none"]),
    ("earth field form", lambda p: _cli(_user_csv(p), p, "--earth-field", "48,60"), ["--earth-field 48,60",
                                                                                     "NORM_UT,DIP_DEG"]),
    ("earth field range", lambda p: _cli(_user_csv(p), p, "--units", USER_UNITS[0], "--earth-field", "4800,60,2"),
     ["--earth-field 4800,60,2", "norm_ut"]),
    ("site", lambda p: _cli(_user_csv(p), p, "--site", "95,11,0.5"), ["--site 95,11,0.5", "latitude"]),
    ("site date", lambda p: _cli(_user_csv(p), p, "--site", "48,11,0.5,May"), ["date 'May'"]),
    ("rate", lambda p: _cli(_user_csv(p), p, "--rate", "-3"), ["--rate -3"]),
]


def _bad_cell(tmp_path: Path) -> Path:
    path = _write(tmp_path / "bc.csv", ["t (s)", "gx", "gy", "gz"], [np.arange(20) / 100.0] * 4)
    lines = path.read_text().splitlines()
    lines[4] = "0.03,0.0,oops,0.0"
    path.write_text("\n".join(lines) + "\n")
    return path


def _ragged(tmp_path: Path) -> Path:
    path = _write(tmp_path / "rg.csv", ["t (s)", "gx", "gy", "gz"], [np.arange(20) / 100.0] * 4)
    lines = path.read_text().splitlines()
    lines[5] += ",0.5"  # an extra field would shift the columns after it
    path.write_text("\n".join(lines) + "\n")
    return path


def _spike(tmp_path: Path) -> Path:
    gyr = np.zeros(200)
    gyr[6] = 250.0  # row 8 of the file (header is row 1); one sample in 200 leaves the 99th percentile at 0
    return _write(tmp_path / "sp.csv", ["t (s)", "gx", "gy", "gz"], [np.arange(200) / 100.0, gyr, gyr * 0, gyr * 0])


def _garbage(path: Path) -> Path:
    path.write_bytes(b"not a mat file at all" * 20)
    return path


def _garbage_text(tmp_path: Path) -> Path:
    (tmp_path / "gt.csv").write_text("a,b,c\n1;2\n3\n")
    return tmp_path / "gt.csv"


@pytest.mark.parametrize("name, argv, needles", ERRORS, ids=[e[0] for e in ERRORS])
def test_every_refusal_is_one_line_naming_the_input(tmp_path, capsys, name, argv, needles):
    fails(capsys, argv(tmp_path), *needles)
    assert not list(tmp_path.glob("out*")) and not list(tmp_path.glob(".out*"))  # nothing half-written


@pytest.mark.parametrize("make, row", [(lambda p: _bad_cell(p), 5), (lambda p: _ragged(p), 6), (lambda p: _spike(p), 8)])
def test_rows_are_named_right_across_blocks(tmp_path, capsys, monkeypatch, make, row):
    monkeypatch.setattr(source_table, "BLOCK_LINES", 2)  # rows 2-3, 4-5, 6-7, ...: every error in a later block
    fails(capsys, _cli(make(tmp_path), tmp_path, "--units", "gyr=rad/s"), f", row {row}")


def test_blank_lines_are_skipped_and_counted(tmp_path, capsys):
    path = _bad_cell(tmp_path)
    lines = path.read_text().splitlines()
    path.write_text("\n".join(lines[:2] + [""] + lines[2:]) + "\n")  # the bad row moves to line 6
    fails(capsys, _cli(path, tmp_path, "--units", "gyr=rad/s"), "bc.csv, row 6, column 'gy'")


def test_the_fuzz_tests_malformed_files_give_one_line_or_a_recording(tmp_path, capsys):
    """tests/test_cli_fuzz.py's malformed CSV and CSV.GZ inputs (gzip bombs among them) through import:
    each is imported (an extra column is only not imported) or refused in one line naming it."""
    from test_cli_fuzz import Cases
    cases = Cases(tmp_path, np.random.default_rng(15))
    cases.csv_cases()
    cases.csv_gz_cases()
    units = "t=s,gyr=rad/s,acc=m/s2,mag=uT,temp=C"
    refused = 0
    for case in cases.items:
        code = main(["import", str(tmp_path / case["needle"]), "--out", str(tmp_path / "o.csv"), "--units", units, "--force"])
        err = [line for line in capsys.readouterr().err.splitlines() if "%|" not in line]
        assert code in (0, 1), (case["what"], err)
        if code == 1:
            refused += 1
            assert len(err) == 1 and err[0].startswith("imufmu import: error:"), (case["what"], err)
            assert case["needle"] in err[0] and "np.float" not in err[0], (case["what"], err)
    assert refused >= len(cases.items) // 2, (refused, len(cases.items))


def test_sidecar_options_are_written(tmp_path):
    source = _user_csv(tmp_path)
    result = import_recording(source, tmp_path / "s.csv", ImportOptions(
        units=tuple(USER_UNITS), sensor="BMI270 on board rev B", reference="static", earth_field="48.6,64.1,"))
    meta = read_imu_csv(result.path).meta
    assert meta["sensor"] == "BMI270 on board rev B" and meta["reference"] == "static"
    assert meta["earth_field"] == {"norm_ut": 48.6, "dip_deg": 64.1, "declination_deg": None}
    site = import_recording(source, tmp_path / "t.csv", ImportOptions(units=tuple(USER_UNITS),
                                                                        site="48.15,11.57,0.52,2024-05-01"))
    assert read_imu_csv(site.path).meta["site"] == {"latitude_deg": 48.15, "longitude_deg": 11.57,
                                                    "altitude_km": 0.52, "date": "2024-05-01"}
