"""Every CLI verb turns bad input into one clear line on stderr and a non-zero exit status."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from cli_errors import fails
from training.cli import main

HEADER = "t,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z,mag_x,mag_y,mag_z,temp"


def _csv(tmp_path: Path, name: str, rows: list[str], header: str = HEADER) -> Path:
    """Write a small CSV recording and return its path."""
    p = tmp_path / name
    p.write_text("\n".join([header, *rows]) + "\n")
    return p


def _row(t: float, mag=(20.0, 0.0, 40.0), gyr=(0.01, 0.0, 0.0)) -> str:
    """One sample: level at rest, given field [µT] and rate [rad/s]."""
    return ",".join(str(v) for v in (t, *gyr, 0.0, 0.0, -9.81, *mag, 25.0))


def test_simulate_missing_scenario(tmp_path, capsys):
    fails(capsys, ["simulate", str(tmp_path / "nope.toml"), "--out", str(tmp_path)], "nope.toml")


def test_simulate_unknown_key(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "x"\nbogus_key = 3\n')
    fails(capsys, ["simulate", str(bad), "--out", str(tmp_path)], "bad.toml")


def test_train_missing_column(tmp_path, capsys):
    p = _csv(tmp_path, "nocol.csv", ["0,0,0,0,0,0,-9.81,20,0,40"], header=HEADER.rsplit(",", 1)[0])
    fails(capsys, ["train", str(p), "--out", str(tmp_path / "model")], "nocol.csv", "temp")


def test_train_non_increasing_time(tmp_path, capsys):
    p = _csv(tmp_path, "time.csv", [_row(0.0), _row(0.01), _row(0.01)])
    fails(capsys, ["train", str(p), "--out", str(tmp_path / "model")], "time.csv", "row 4")


def test_run_field_in_nanotesla(tmp_path, capsys):
    rows = [_row(0.01 * k, mag=(20000.0, 0.0, 40000.0)) for k in range(50)]
    p = _csv(tmp_path, "nt.csv", rows)
    fmu = tmp_path / "x.fmu"
    fmu.write_bytes(b"PK")
    fails(capsys, ["run", str(fmu), str(p), "--out", str(tmp_path / "o.csv")], "nt.csv", "nT")


def test_run_rates_in_degrees(tmp_path, capsys):
    rows = [_row(0.01 * k, gyr=(100.0, -80.0, 50.0)) for k in range(50)]
    p = _csv(tmp_path, "deg.csv", rows)
    fmu = tmp_path / "x.fmu"
    fmu.write_bytes(b"PK")
    fails(capsys, ["run", str(fmu), str(p), "--out", str(tmp_path / "o.csv")], "deg.csv", "deg")


def test_build_fmu_missing_model(tmp_path, capsys):
    fails(capsys, ["build-fmu", "--model", str(tmp_path / "m.json"), "--out", str(tmp_path / "a.fmu")],
           "m.json", "not found")


def test_build_fmu_model_not_json(tmp_path, capsys):
    m = tmp_path / "model.json"
    m.write_text("{ not json")
    fails(capsys, ["build-fmu", "--model", str(m), "--out", str(tmp_path / "a.fmu")], "model.json")


def test_validate_not_an_fmu(tmp_path, capsys):
    f = tmp_path / "broken.fmu"
    f.write_text("this is not a zip archive")
    fails(capsys, ["validate", str(f)], "broken.fmu")


def test_run_missing_fmu(tmp_path, capsys):
    p = _csv(tmp_path, "ok.csv", [_row(0.0), _row(0.01)])
    fails(capsys, ["run", str(tmp_path / "none.fmu"), str(p), "--out", str(tmp_path / "o.csv")],
           "none.fmu", "not found")


def test_usage_error_exits_2():
    with pytest.raises(SystemExit) as e:
        main(["run"])
    assert e.value.code == 2


def test_console_script_reports_error_and_status(tmp_path):
    """The installed entry point (python -m training.cli) exits non-zero with one stderr line."""
    r = subprocess.run([sys.executable, "-m", "training.cli", "validate", str(tmp_path / "no.fmu")],
                       capture_output=True, text=True)
    assert r.returncode == 1
    assert r.stderr.strip().count("\n") == 0 and "no.fmu" in r.stderr


def test_diagnose_missing_model(tmp_path, capsys):
    p = _csv(tmp_path, "rec.csv", [_row(0.0), _row(0.01)])
    fails(capsys, ["diagnose", str(p), "--model", str(tmp_path / "none.json"), "--out", str(tmp_path / "d")],
           "none.json", "not found")


def test_compare_thermal_missing_data(tmp_path, capsys):
    fails(capsys, ["compare-thermal", str(tmp_path / "gone.csv.gz"), "--out", str(tmp_path / "c")],
           "gone.csv.gz", "not found")


def test_build_fmu_rejects_unknown_fmi_version():
    with pytest.raises(SystemExit) as e:
        main(["build-fmu", "--model", "m.json", "--out", "x.fmu", "--fmi", "4"])
    assert e.value.code == 2


def test_compare_thermal_without_gyro_reference(tmp_path, capsys):
    p = _csv(tmp_path, "noref.csv", [_row(0.01 * k) for k in range(50)])
    fails(capsys, ["compare-thermal", str(p), "--out", str(tmp_path / "c")], "noref.csv", "static")


def test_validate_names_the_first_problem(tmp_path, capsys):
    import zipfile
    f = tmp_path / "escape.fmu"
    with zipfile.ZipFile(f, "w") as zf:
        zf.writestr("modelDescription.xml", "<x/>")
        zf.writestr("../../escape.txt", "x")
    fails(capsys, ["validate", str(f)], "escape.fmu", "1 problem(s)", "contains '..'")


def test_run_refuses_an_fmu_archive_with_an_absolute_entry(tmp_path, capsys):
    import zipfile
    p = _csv(tmp_path, "ok.csv", [_row(0.01 * k) for k in range(50)])
    f = tmp_path / "abs.fmu"
    with zipfile.ZipFile(f, "w") as zf:
        zf.writestr("modelDescription.xml", "<x/>")
        zf.writestr("/tmp/imufusion-escape.txt", "x")
    fails(capsys, ["run", str(f), str(p), "--out", str(tmp_path / "o.csv")], "abs.fmu", "absolute path")


@pytest.mark.parametrize("argv, victim", [
    (["diagnose", "{d}/data.csv", "--model", "{d}/m/model.json", "--out", "{d}/m"], "m/model.json"),
    (["run", "{d}/ImuFusion.fmu", "{d}/data.csv", "--out", "{d}/data.csv"], "data.csv"),
    (["build-fmu", "--model", "{d}/m/model.json", "--out", "{d}/m/model.json"], "m/model.json"),
    (["train", "{d}/m/model.json", "--out", "{d}/m"], "m/model.json"),
])
def test_a_verb_never_writes_over_its_own_input(tmp_path, capsys, argv, victim):
    """Issue 31 item 5: `diagnose --model m/model.json --out m` replaced the model it read. Each is one
    line naming the input, before anything is read or written; the input keeps its bytes."""
    (tmp_path / "m").mkdir()
    for name in ("data.csv", "m/model.json", "ImuFusion.fmu"):
        (tmp_path / name).write_text(f"the original {name}\n")
    assert main([a.format(d=tmp_path) for a in argv]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{tmp_path / victim}: imufmu {argv[0]} would write over this input" in err[0], err
    assert (tmp_path / victim).read_text() == f"the original {victim}\n"
