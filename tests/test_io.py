"""Tests of the imu-csv/1 data layer: exact round trips, deterministic bytes, every rejection
kind with its row/column, and loading every shared measured recording."""
from __future__ import annotations

import gzip
import json
from pathlib import Path

import numpy as np
import pytest

from contract.errors import DataError
from training.data.dataset import ImuData
from training.data.io import (find_recordings, load_many, read_imu_csv, recording_stem, require_sensors,
                              write_imu_csv)

SHARED_DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
N_ROWS = 60
META = {"rate_hz": 100.0, "sensor": "synthetic", "reference": "simulated",
        "earth_field": {"norm_ut": 48.0, "dip_deg": 60.0, "declination_deg": 2.5},
        "notes": "µT, °C — non-ASCII survives"}

# Sanity bounds for the shared recordings (values from the data set descriptions).
EARTH_FIELD_RANGE_UT = (20.0, 70.0)     # BROAD field ≈ 41.6 µT plus residual distortion
GRAVITY_RANGE_M_S2 = (9.5, 10.1)        # median specific-force norm ≈ g with sensor errors
QUATERNION_NORM_TOL = 1e-4              # ref_q stored with 7 significant digits
PAN_TEMPERATURE_RANGE_C = (10.0, 30.0)  # chamber cool-down from about 24 to 16 °C


# ----------------------------------------------------------------------------- fixtures


def make_data(rng_seed: int = 0, n: int = N_ROWS) -> ImuData:
    """A plausible recording with every optional group and NaNs at irregular places."""
    rng = np.random.default_rng(rng_seed)
    t = np.cumsum(rng.uniform(0.005, 0.015, n))
    gyr = rng.normal(0.0, 1.0, (n, 3))                       # rad/s
    acc = np.array([0.0, 0.0, -9.81]) + rng.normal(0.0, 0.3, (n, 3))
    mag = np.array([20.0, -3.0, 42.0]) + rng.normal(0.0, 1.0, (n, 3))
    temp = 25.0 + rng.normal(0.0, 0.5, n)
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    data = ImuData(t=t, gyr=gyr, acc=acc, mag=mag, temp=temp, ref_q=q,
                   ref_gyr=gyr + 0.01, ref_acc=acc - 0.1, ref_mag=mag * 0.99,
                   eval_mask=rng.uniform(size=n) > 0.3,
                   aux={"aux_heater_w": rng.uniform(0, 5, n), "aux_current_a": rng.normal(size=n)},
                   meta=dict(META), name="synthetic")
    data.mag[3, 1] = np.nan
    data.temp[[0, 7, 8]] = np.nan
    data.ref_q[10:14] = np.nan
    data.aux["aux_current_a"][-1] = np.nan
    data.gyr[5, 0] = -0.0
    data.acc[6, 2] = 1e-300
    return data


def assert_same(a: ImuData, b: ImuData) -> None:
    """Exact equality of every array (NaN positions included), aux, mask and metadata."""
    for name in ("t", "gyr", "acc", "mag", "temp", "ref_q", "ref_gyr", "ref_acc", "ref_mag"):
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None), name
        if x is not None:
            np.testing.assert_array_equal(x, y, err_msg=name)
            assert np.array_equal(np.signbit(x), np.signbit(y)), name
    assert (a.eval_mask is None) == (b.eval_mask is None)
    if a.eval_mask is not None:
        assert b.eval_mask.dtype == bool
        np.testing.assert_array_equal(a.eval_mask, b.eval_mask)
    assert list(a.aux) == list(b.aux)
    for key in a.aux:
        np.testing.assert_array_equal(a.aux[key], b.aux[key], err_msg=key)


def write_lines(path: Path, lines: list[str]) -> Path:
    """Write CSV text lines to `path` (plain text)."""
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def csv_lines(tmp_path: Path, data: ImuData | None = None) -> list[str]:
    """The text lines of `data` (default: make_data()) written as plain imu-csv/1."""
    written = write_imu_csv(data if data is not None else make_data(), tmp_path / "src.csv")
    return written.read_text(encoding="utf-8").splitlines()


def edit_column(lines: list[str], column: str, edit) -> list[str]:
    """Lines with the cells of `column` replaced by edit(cells) (cells include the header)."""
    rows = [line.split(",") for line in lines]
    i = rows[0].index(column)
    new_cells = edit([r[i] for r in rows])
    for r, cell in zip(rows, new_cells):
        if cell is None:
            del r[i]
        else:
            r[i] = cell
    return [",".join(r) for r in rows]


def rejection(path: Path) -> DataError:
    """The DataError that reading `path` raises."""
    with pytest.raises(DataError) as info:
        read_imu_csv(path)
    return info.value


# --------------------------------------------------------------------------- round trip


@pytest.mark.parametrize("file_name", ["rec.csv", "rec.csv.gz"])
def test_round_trip_is_exact(tmp_path, file_name):
    data = make_data()
    path = write_imu_csv(data, tmp_path / file_name)
    back = read_imu_csv(path)
    assert_same(data, back)
    assert back.name == "rec"
    assert back.meta == {"format": "imu-csv/1", **META}
    assert json.loads((tmp_path / "rec.json").read_text(encoding="utf-8"))["format"] == "imu-csv/1"


def test_gzip_file_is_really_gzip_without_name_or_time(tmp_path):
    path = write_imu_csv(make_data(), tmp_path / "rec.csv.gz")
    raw = path.read_bytes()
    assert raw[:2] == b"\x1f\x8b"
    assert raw[3] & 0x08 == 0                 # FNAME flag unset: no file name stored
    assert raw[4:8] == b"\0\0\0\0"            # MTIME = 0
    assert gzip.decompress(raw).startswith(b"t,gyr_x,")


@pytest.mark.parametrize("file_name", ["rec.csv", "rec.csv.gz"])
def test_rewrite_is_byte_identical(tmp_path, file_name):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    first = write_imu_csv(make_data(), tmp_path / "a" / file_name)
    second = write_imu_csv(read_imu_csv(first), tmp_path / "b" / file_name)
    assert first.read_bytes() == second.read_bytes()
    assert (tmp_path / "a" / "rec.json").read_bytes() == (tmp_path / "b" / "rec.json").read_bytes()


def test_minimal_file_without_optional_columns_or_sidecar(tmp_path):
    full = make_data()
    data = ImuData(t=full.t, gyr=full.gyr, acc=full.acc, mag=full.mag, temp=full.temp)
    path = write_imu_csv(data, tmp_path / "plain.csv")
    (tmp_path / "plain.json").unlink()
    back = read_imu_csv(path)
    assert_same(data, back)
    assert back.ref_q is None and back.eval_mask is None and back.aux == {}
    assert back.meta == {}
    assert path.read_text().splitlines()[0] == "t,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z,mag_x,mag_y,mag_z,temp"


def test_empty_cells_and_nan_text_are_nan(tmp_path):
    lines = csv_lines(tmp_path)
    lines = edit_column(lines, "temp", lambda c: [c[0], "", "nan", "NaN"] + c[4:])
    lines[5] = ",".join(lines[5].split(",")[:-1] + [""])  # empty last cell on line 6
    data = read_imu_csv(write_lines(tmp_path / "nan.csv", lines))
    assert np.isnan(data.temp[:3]).all()
    assert np.isnan(data.aux["aux_current_a"][4])


def test_windows_line_endings_are_accepted(tmp_path):
    data = make_data()
    lines = csv_lines(tmp_path, data)
    path = tmp_path / "crlf.csv"
    path.write_bytes(("\r\n".join(lines) + "\r\n").encode())
    assert_same(data, read_imu_csv(path))


def test_temperature_may_be_all_nan(tmp_path):
    data = make_data()
    data.temp[:] = np.nan
    back = read_imu_csv(write_imu_csv(data, tmp_path / "notemp.csv"))
    assert np.isnan(back.temp).all()


# --------------------------------------------------------------------------- rejections


def test_missing_file(tmp_path):
    err = rejection(tmp_path / "nothing.csv")
    assert "file not found" in str(err) and "nothing.csv" in str(err)


def test_missing_required_column(tmp_path):
    lines = edit_column(csv_lines(tmp_path), "mag_y", lambda c: [None] * len(c))
    err = rejection(write_lines(tmp_path / "bad.csv", lines))
    assert err.column == "mag_y" and "missing required column" in str(err)


def test_unknown_column(tmp_path):
    lines = csv_lines(tmp_path)
    lines = [lines[0] + ",speed"] + [line + ",1.0" for line in lines[1:]]
    err = rejection(write_lines(tmp_path / "bad.csv", lines))
    assert "column 'speed'" in str(err) and "unknown column" in str(err)


def test_incomplete_reference_quaternion(tmp_path):
    lines = edit_column(csv_lines(tmp_path), "ref_qz", lambda c: [None] * len(c))
    err = rejection(write_lines(tmp_path / "bad.csv", lines))
    assert err.column == "ref_qz" and "all together" in str(err)


def test_non_numeric_cell_names_row_and_column(tmp_path):
    lines = edit_column(csv_lines(tmp_path), "acc_y", lambda c: c[:3] + ["12a"] + c[4:])
    err = rejection(write_lines(tmp_path / "bad.csv", lines))
    # cells: index 0 = header (line 1), index 3 = line 4 in an editor
    assert str(err) == f"{tmp_path / 'bad.csv'}, row 4, column 'acc_y': not a number: '12a'"


def test_ragged_row_names_row(tmp_path):
    lines = csv_lines(tmp_path)
    lines[9] = lines[9] + ",3.0"
    err = rejection(write_lines(tmp_path / "bad.csv", lines))
    assert err.row == 10 and "cells" in str(err)


def test_non_increasing_time_names_first_row(tmp_path):
    # cells index i is line i + 1: line 22 repeats line 21's time, line 32 goes backwards
    lines = edit_column(csv_lines(tmp_path), "t",
                        lambda c: c[:21] + [c[20]] + c[22:31] + ["-1.0"] + c[32:])
    err = rejection(write_lines(tmp_path / "bad.csv", lines))
    assert err.row == 22 and err.column == "t" and "strictly increasing" in str(err)


def test_non_finite_time_names_row(tmp_path):
    lines = edit_column(csv_lines(tmp_path), "t", lambda c: c[:5] + [""] + c[6:])
    err = rejection(write_lines(tmp_path / "bad.csv", lines))
    assert err.row == 6 and err.column == "t" and "finite" in str(err)


def test_eval_mask_must_be_zero_or_one(tmp_path):
    lines = edit_column(csv_lines(tmp_path), "eval_mask", lambda c: c[:2] + ["2"] + c[3:])
    err = rejection(write_lines(tmp_path / "bad.csv", lines))
    assert err.row == 3 and err.column == "eval_mask"


def scaled(triad: str, factor: float) -> ImuData:
    """make_data() with one raw triad multiplied by `factor` (a unit mistake)."""
    data = make_data()
    setattr(data, triad, getattr(data, triad) * factor)
    return data


@pytest.mark.parametrize("triad, factor, words", [
    ("mag", 1000.0, "looks like nT"),
    ("mag", 0.01, "looks like gauss"),
    ("gyr", np.degrees(1.0), "deg/s given as rad/s"),
    ("acc", 1 / 9.81, "looks like g,"),
    ("acc", 1000 / 9.81, "mg or raw counts"),
])
def test_wrong_unit_is_rejected(tmp_path, triad, factor, words):
    err = rejection(write_imu_csv(scaled(triad, factor), tmp_path / "unit.csv"))
    assert words in str(err) and err.column == f"{triad}_*"


@pytest.mark.parametrize("triad, counts_per_unit", [("gyr", 16.4 * np.degrees(1.0)), ("acc", 4096 / 9.81),
                                                     ("mag", 1000.0)])
def test_raw_counts_are_named_as_counts(tmp_path, triad, counts_per_unit):
    """Whole-number readings beyond a physical unit's range may be raw ADC counts (a gyro at 16.4
    LSB/(°/s), an accelerometer at 4096 LSB/g, a magnetometer at 1000 LSB/µT): beside the physical unit
    they could be, the message says so and how to convert counts."""
    data = make_data()
    setattr(data, triad, np.round(getattr(data, triad) * counts_per_unit))
    err = rejection(write_imu_csv(data, tmp_path / "counts.csv"))
    assert "raw ADC counts" in str(err) and f"--units {triad}=counts:" in str(err)


def test_fractional_readings_are_not_called_counts(tmp_path):
    err = rejection(write_imu_csv(scaled("mag", 1000.0), tmp_path / "nt.csv"))
    assert "looks like nT" in str(err) and "counts" not in str(err)


def test_wrong_unit_in_reference_triad_is_rejected(tmp_path):
    data = make_data()
    data.ref_mag = data.ref_mag * 1000.0
    err = rejection(write_imu_csv(data, tmp_path / "unit.csv"))
    assert "looks like nT" in str(err) and err.column == "ref_mag_*"


def test_too_few_finite_samples_are_not_judged(tmp_path):
    data = scaled("mag", 0.01)  # gauss-like, but within the runtime's input limits
    data.mag[5:] = np.nan
    back = read_imu_csv(write_imu_csv(data, tmp_path / "few.csv"))
    assert np.isfinite(back.mag).all(axis=1).sum() == 4  # row 3 has a NaN from make_data


@pytest.mark.parametrize("sidecar, words", [
    ({"format": "imu-csv/0"}, "expected 'imu-csv/1'"),
    ({"rate_hz": 100}, "'format' is null"),
    ("[1, 2]", "JSON object"),
    ("{not json", "not valid JSON"),
])
def test_bad_sidecar_is_rejected(tmp_path, sidecar, words):
    path = write_imu_csv(make_data(), tmp_path / "rec.csv")
    text = sidecar if isinstance(sidecar, str) else json.dumps(sidecar)
    (tmp_path / "rec.json").write_text(text, encoding="utf-8")
    err = rejection(path)
    assert words in str(err) and err.path.endswith("rec.json")


def test_header_only_file_is_rejected(tmp_path):
    lines = csv_lines(tmp_path)[:1]
    err = rejection(write_lines(tmp_path / "empty.csv", lines))
    assert "no data rows" in str(err)


# ----------------------------------------------------------------- missing sensors


def test_all_nan_accelerometer_read_but_not_required(tmp_path):
    data = make_data()
    data.acc[:] = np.nan
    back = read_imu_csv(write_imu_csv(data, tmp_path / "noacc.csv"))
    assert np.isnan(back.acc).all()
    require_sensors(back, ["gyr", "mag", "temp"], "noacc.csv", "gyro calibration")
    with pytest.raises(DataError) as info:
        require_sensors(back, ["gyr", "acc"], "noacc.csv", "attitude estimation")
    assert str(info.value) == "noacc.csv: sensor 'acc' is all-NaN; attitude estimation needs it"


def test_require_sensors_rejects_unknown_sensor_name():
    with pytest.raises(ValueError):
        require_sensors(make_data(), ["accel"], "x.csv", "anything")


# ------------------------------------------------------------------------- folders


def test_find_recordings_and_load_many(tmp_path):
    write_imu_csv(make_data(1), tmp_path / "b.csv.gz")
    write_imu_csv(make_data(2), tmp_path / "a.csv")
    (tmp_path / "notes.txt").write_text("not a recording")
    paths = find_recordings(tmp_path)
    assert [p.name for p in paths] == ["a.csv", "b.csv.gz"]
    loaded = load_many(paths)
    assert [d.name for d in loaded] == ["a", "b"]
    assert_same(loaded[0], make_data(2))
    assert recording_stem("x/y.z.csv.gz") == "y.z"


def test_find_recordings_missing_folder(tmp_path):
    with pytest.raises(DataError, match="folder not found"):
        find_recordings(tmp_path / "absent")


# --------------------------------------------------------------- shared measured data


def shared_recordings() -> list:
    """One pytest param per shared recording, or one skipped param when the folder is absent."""
    if not SHARED_DATA.is_dir():
        return [pytest.param(None, marks=pytest.mark.skip(
            reason=f"shared measured data not found at {SHARED_DATA}"))]
    folders = sorted(p for p in SHARED_DATA.iterdir() if p.is_dir())
    return [pytest.param(p, id=f"{p.parent.name}/{p.name}")
            for folder in folders for p in find_recordings(folder)]


def median_norm(xyz: np.ndarray) -> float:
    """Median Euclidean norm of the rows of an (N, 3) array with finite values."""
    rows = xyz[np.isfinite(xyz).all(axis=1)]
    return float(np.median(np.linalg.norm(rows, axis=1)))


@pytest.mark.parametrize("path", shared_recordings())
def test_shared_recording_loads_and_is_sane(path):
    data = read_imu_csv(path)
    assert len(data) > 0 and data.meta["format"] == "imu-csv/1"
    if path.parent.name == "broad":
        check_broad(data)
    elif path.parent.name == "pan_thermal":
        check_pan_thermal(data, path)


def check_broad(data: ImuData) -> None:
    """BROAD: field tens of µT, gravity ≈ 9.8 m/s², unit reference quaternions, eval mask."""
    assert EARTH_FIELD_RANGE_UT[0] < median_norm(data.mag) < EARTH_FIELD_RANGE_UT[1]
    assert GRAVITY_RANGE_M_S2[0] < median_norm(data.acc) < GRAVITY_RANGE_M_S2[1]
    q = data.ref_q[np.isfinite(data.ref_q).all(axis=1)]
    assert len(q) > len(data) // 2
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=QUATERNION_NORM_TOL)
    assert data.eval_mask is not None and data.eval_mask.any()
    assert set(data.aux) == {"aux_pos_x", "aux_pos_y", "aux_pos_z"}


def check_pan_thermal(data: ImuData, path: Path) -> None:
    """PAN thermal log: no accelerometer, finite temperatures of the chamber cool-down."""
    assert np.isnan(data.acc).all()
    assert np.isfinite(data.temp).all()
    assert PAN_TEMPERATURE_RANGE_C[0] < data.temp.min() < data.temp.max() < PAN_TEMPERATURE_RANGE_C[1]
    with pytest.raises(DataError, match="sensor 'acc' is all-NaN"):
        require_sensors(data, ["acc"], path, "attitude estimation")


# ------------------------------------------------------- issue 15: inputs checked as they stream

C_GUARD = Path(__file__).resolve().parents[1] / "sources" / "ImuGuard.h"


def test_input_limits_are_the_c_guards():
    """training.data.input_limits mirrors sources/ImuGuard.h: one range for the loader and the runtime."""
    import re
    from training.data import input_limits
    text = C_GUARD.read_text()
    for py_name, c_name in input_limits.C_NAMES.items():
        match = re.search(rf"#define {c_name} \(?(-?[0-9.e+]+)\)?", text)
        assert match, c_name
        assert getattr(input_limits, py_name) == float(match.group(1)), c_name


@pytest.mark.parametrize("temp, text", [(-273.0, "-273 °C"), (1e6, "1e6 °C"), (125.5, "125.5 °C")])
def test_temperature_outside_the_runtime_range_is_refused(tmp_path, temp, text):
    data = make_data()
    data.temp[4] = temp                 # editor line 6
    err = rejection(write_imu_csv(data, tmp_path / "hot.csv"))
    assert (err.row, err.column) == (6, "temp")
    assert f"{text} is outside -60..125 °C" in str(err) and "IMU_GUARD_TEMP" in str(err)


@pytest.mark.parametrize("triad, axis, value", [("gyr", 0, 1e308), ("acc", 2, -2500.0), ("mag", 1, 1e4),
                                                ("ref_gyr", 1, np.inf)])
def test_values_beyond_the_runtime_limits_are_refused(tmp_path, triad, axis, value):
    data = make_data()
    getattr(data, triad)[9, axis] = value
    err = rejection(write_imu_csv(data, tmp_path / "big.csv"))
    assert (err.row, err.column) == (11, f"{triad}_{'xyz'[axis]}")
    assert "the range the runtime accepts" in str(err)


def test_sidecar_with_a_bom_is_accepted(tmp_path):
    path = write_imu_csv(make_data(), tmp_path / "bom.csv")
    side = tmp_path / "bom.json"
    side.write_bytes(b"\xef\xbb\xbf" + side.read_bytes())
    assert read_imu_csv(path).meta["rate_hz"] == META["rate_hz"]


@pytest.mark.parametrize("sep, name", [(";", "';'"), ("\t", "a tab")])
def test_another_delimiter_is_named(tmp_path, sep, name):
    path = write_imu_csv(make_data(), tmp_path / "semi.csv")
    path.write_text(path.read_text().replace(",", sep))
    err = rejection(path)
    assert err.row == 1 and f"separated by {name}" in str(err)


def test_a_line_longer_than_the_cap_is_refused_at_its_row(tmp_path):
    from training.data.io import MAX_LINE_CHARS
    path = write_imu_csv(make_data(), tmp_path / "long.csv")
    lines = path.read_text().splitlines()
    path.write_text("\n".join(lines[:4] + ["1" * (MAX_LINE_CHARS + 1)]) + "\n")
    err = rejection(path)
    assert err.row == 5 and "longer than" in str(err)


def test_gzip_bomb_is_refused_at_its_bad_row(tmp_path):
    """1 GiB of inflated text after a bad third row: refused at row 3 having allocated far less
    than it inflates to (bound: a quarter of it; the loader reads 4 Mi characters at a time and
    reserves one 1 Mi-row storage segment)."""
    import tracemalloc
    from training.data.io import REQUIRED_COLUMNS
    path = tmp_path / "bomb.csv.gz"
    head = gzip.compress((",".join(REQUIRED_COLUMNS) + "\n0,0,0,0,0,0,-9.8,20,0,40,25\nx\n").encode(), mtime=0)
    path.write_bytes(head + gzip.compress(b"1" * 2**24, mtime=0) * 64)
    tracemalloc.start()
    try:
        err = rejection(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert err.row == 3 and "cells" in str(err)
    assert peak < 2**30 / 4, f"{peak / 2**20:.0f} MiB"


def test_messages_show_plain_numbers(tmp_path):
    data = make_data()
    path = write_imu_csv(data, tmp_path / "order.csv")
    lines = path.read_text().splitlines()
    lines[3], lines[4] = lines[4], lines[3]
    path.write_text("\n".join(lines) + "\n")
    err = str(rejection(path))
    assert "time is not strictly increasing" in err and "np." not in err


def test_streaming_across_blocks_and_segments_is_exact(tmp_path, monkeypatch):
    """Tiny blocks and segments: rows spanning many of each read back exactly, and a bad row deep
    in the file is named by its editor line."""
    import training.data.io as imu_io
    monkeypatch.setattr(imu_io, "BLOCK_CHARS", 700)
    monkeypatch.setattr(imu_io, "SEGMENT_ROWS", 7)
    data = make_data(n=200)
    path = write_imu_csv(data, tmp_path / "blocks.csv.gz")
    assert_same(read_imu_csv(path), data)
    text = gzip.decompress(path.read_bytes()).decode().splitlines()
    text[150] = text[150].replace(",", ";", 1)             # editor line 151
    path.write_bytes(gzip.compress(("\n".join(text) + "\n").encode()))
    assert rejection(path).row == 151
