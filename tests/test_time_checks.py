"""Time that is checked (issue 15): t not in seconds is refused at load, gaps are reported."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from cli_errors import fails
from contract.errors import DataError
from training.cli import main
from training.data.dataset import ImuData
from training.data.io import (GAP_STEP_FACTOR, MIN_MEDIAN_STEP_S, RATE_TOLERANCE, read_imu_csv,
                              report_load_notes, time_gaps, write_imu_csv)

RATE_HZ = 100.0
N = 400


def recording(t: np.ndarray | None = None, rate_hz: float | None = RATE_HZ) -> ImuData:
    """A level sensor at rest with small noise, sampled at `t` [s] (default: N samples at RATE_HZ)."""
    if t is None:
        t = np.arange(N) / RATE_HZ
    n = len(t)
    rng = np.random.default_rng(1)
    meta = {"sensor": "synthetic", "reference": "none"}
    if rate_hz is not None:
        meta["rate_hz"] = rate_hz
    return ImuData(t=np.asarray(t, dtype=float), gyr=rng.normal(0.0, 1e-3, (n, 3)),
                   acc=np.array([0.0, 0.0, -9.81]) + rng.normal(0.0, 0.01, (n, 3)),
                   mag=np.array([20.0, 0.0, 40.0]) + rng.normal(0.0, 0.1, (n, 3)),
                   temp=np.full(n, 25.0), meta=meta, name="rec")


def write(data: ImuData, path: Path) -> Path:
    return write_imu_csv(data, path)


def loads_with_notes(path: Path) -> tuple[ImuData, list[str]]:
    notes: list[str] = []
    with report_load_notes(notes.append):
        data = read_imu_csv(path)
    return data, notes


def fake_fmu(tmp_path: Path) -> Path:
    fmu = tmp_path / "x.fmu"
    fmu.write_bytes(b"PK")
    return fmu


# ------------------------------------------------------------------- unit of t


@pytest.mark.parametrize("scale, unit, factor", [(1e3, "milliseconds", "factor 1000"),
                                                 (1e6, "microseconds", "factor 1e6"),
                                                 (1e9, "nanoseconds", "factor 1e9")])
def test_t_not_in_seconds_is_refused_by_the_loader(tmp_path, scale, unit, factor):
    path = write(recording(np.arange(N) / RATE_HZ * scale), tmp_path / "scaled.csv")
    with pytest.raises(DataError) as info:
        read_imu_csv(path)
    msg = str(info.value)
    assert msg.startswith(str(path)) and "column 't'" in msg
    assert f"t looks like {unit} ({factor})" in msg and "rate_hz 100 (step 0.01 s)" in msg
    assert "convert t to seconds" in msg


def test_milliseconds_message_in_full(tmp_path):
    path = write(recording(np.arange(N) * 10.0), tmp_path / "ms.csv")
    with pytest.raises(DataError) as info:
        read_imu_csv(path)
    assert str(info.value) == (f"{path}, column 't': t steps by 10 (median) but the sidecar says rate_hz 100 "
                               f"(step 0.01 s): t looks like milliseconds (factor 1000); convert t to seconds")


@pytest.mark.parametrize("verb", ["run", "train"])
@pytest.mark.parametrize("scale, unit", [(1e3, "milliseconds"), (1e6, "microseconds")])
def test_t_not_in_seconds_is_refused_by_the_cli(tmp_path, capsys, verb, scale, unit):
    path = write(recording(np.arange(N) / RATE_HZ * scale), tmp_path / "scaled.csv.gz")
    argv = ["run", str(fake_fmu(tmp_path)), str(path), "--out", str(tmp_path / "o.csv")] if verb == "run" \
        else ["train", str(path), "--out", str(tmp_path / "model")]
    fails(capsys, argv, "scaled.csv.gz", unit)


def test_other_mismatch_with_rate_is_refused_without_naming_a_unit(tmp_path):
    path = write(recording(np.arange(N) / RATE_HZ * 2.0), tmp_path / "slow.csv")
    with pytest.raises(DataError) as info:
        read_imu_csv(path)
    msg = str(info.value)
    assert "a factor 2 apart" in msg and "looks like" not in msg


@pytest.mark.parametrize("factor", [1.0 / RATE_TOLERANCE * 1.01, 1.0, RATE_TOLERANCE * 0.99])
def test_steps_within_the_tolerance_are_accepted(tmp_path, factor):
    read_imu_csv(write(recording(np.arange(N) / RATE_HZ * factor), tmp_path / "ok.csv"))


def test_tiny_steps_without_rate_are_refused(tmp_path):
    path = write(recording(np.arange(N) * 1e-11, rate_hz=None), tmp_path / "tiny.csv")
    with pytest.raises(DataError) as info:
        read_imu_csv(path)
    msg = str(info.value)
    assert "tiny.csv" in msg and "t steps by 1e-11 (median)" in msg and "100 kHz" in msg


def test_tiny_steps_with_rate_are_refused(tmp_path):
    with pytest.raises(DataError, match="t steps by 1e-11"):
        read_imu_csv(write(recording(np.arange(N) * 1e-11), tmp_path / "tiny.csv"))


def test_fast_imu_without_rate_is_accepted(tmp_path):
    read_imu_csv(write(recording(np.arange(N) * MIN_MEDIAN_STEP_S * 1.01, rate_hz=None), tmp_path / "fast.csv"))


@pytest.mark.parametrize("rate", [0, -100, "100", float("nan"), True])
def test_bad_rate_in_sidecar_is_refused(tmp_path, rate):
    path = write(recording(), tmp_path / "rec.csv")
    meta = json.loads((tmp_path / "rec.json").read_text())
    meta["rate_hz"] = rate
    (tmp_path / "rec.json").write_text(json.dumps(meta))
    with pytest.raises(DataError) as info:
        read_imu_csv(path)
    assert info.value.path.endswith("rec.json") and "rate_hz" in str(info.value)


def test_correct_file_loads_bit_identically_and_quietly(tmp_path):
    data = recording(np.cumsum(np.random.default_rng(2).uniform(0.008, 0.012, N)))
    path = write(data, tmp_path / "good.csv.gz")
    back, notes = loads_with_notes(path)
    assert notes == []
    for name in ("t", "gyr", "acc", "mag", "temp"):
        assert np.array_equal(getattr(back, name), getattr(data, name)), name
    assert write(back, tmp_path / "again.csv.gz").read_bytes() == path.read_bytes()


# ------------------------------------------------------------------------- gaps


def hour_gap_times() -> np.ndarray:
    """N samples at RATE_HZ with a one-hour gap after t = 2 s."""
    t = np.arange(N) / RATE_HZ
    t[t > 2.0] += 3600.0
    return t


def test_one_hour_gap_is_reported_and_the_data_loads(tmp_path):
    data = recording(hour_gap_times())
    path = write(data, tmp_path / "gap.csv")
    back, notes = loads_with_notes(path)
    assert np.array_equal(back.t, data.t)
    assert notes == [f"{path}: 1 gap in time (longest 3600 s at t = 2 s; steps > {GAP_STEP_FACTOR:g} × "
                     "the nominal 0.01 s); the runtime restarts the attitude across a step longer than 100 nominal "
                     "steps and counts a shorter loss as unmeasured motion, restarting once it could amount to "
                     "10° (docs/fmu.md, 'Time steps')"]


def test_gaps_are_counted_and_the_longest_named():
    t = np.arange(100) / RATE_HZ
    t[30:] += 0.5
    t[60:] += 7.0
    t[90:] += (GAP_STEP_FACTOR - 1.0) / RATE_HZ * 0.99   # a step just under the threshold: no gap
    gaps = time_gaps(t, RATE_HZ)
    assert (gaps.count, gaps.longest_s, gaps.longest_at_s) == (2, pytest.approx(7.01), t[59])
    assert gaps.threshold_s == pytest.approx(GAP_STEP_FACTOR / RATE_HZ)
    assert time_gaps(t).nominal_step_s == pytest.approx(1.0 / RATE_HZ)   # median without a rate


def test_no_notes_outside_a_report_block(tmp_path):
    read_imu_csv(write(recording(hour_gap_times()), tmp_path / "gap.csv"))   # nothing raised, nothing kept


@pytest.mark.parametrize("verb", ["run", "train", "diagnose"])
def test_cli_prints_one_gap_line_per_file(tmp_path, capsys, verb):
    path = write(recording(hour_gap_times()), tmp_path / "gap.csv")
    if verb == "run":
        argv = ["run", str(fake_fmu(tmp_path)), str(path), "--out", str(tmp_path / "o.csv")]
    elif verb == "train":
        argv = ["train", str(path), "--out", str(tmp_path / "model"), "--allow-identity"]
    else:
        still = write(recording(), tmp_path / "still.csv")
        assert main(["train", str(still), "--out", str(tmp_path / "model"), "--allow-identity"]) == 0
        capsys.readouterr()
        argv = ["diagnose", str(path), "--model", str(tmp_path / "model" / "model.json"),
                "--out", str(tmp_path / "diag")]
    main(argv)   # the fake FMU fails after loading, diagnose finds no reference: the line comes first
    out = capsys.readouterr().out.splitlines()
    lines = [line for line in out if "gap in time" in line]
    assert lines == [f"{path}: 1 gap in time (longest 3600 s at t = 2 s; steps > {GAP_STEP_FACTOR:g} × "
                     "the nominal 0.01 s); the runtime restarts the attitude across a step longer than 100 nominal "
                     "steps and counts a shorter loss as unmeasured motion, restarting once it could amount to "
                     "10° (docs/fmu.md, 'Time steps')"]
