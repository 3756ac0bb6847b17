"""`imufmu train` writes the noise block (imufusion-noise/1) into model.json under "noise", imu.yaml
beside it and a few lines in its summary; `imufmu noise DATA --out DIR` writes noise.json, imu.yaml,
the Allan plots and noise.md, and refuses a bad file in one line that names it."""
from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

from training.artefact import load_artefact
from training.cli import main
from training.data.dataset import ImuData
from training.data.io import write_imu_csv
from training.noise.characterise import FORMAT

#: The small static log of tests/test_train_static.py's kind: 400 s of a still gyro at 50 Hz (no acc,
#: no field), white noise σ per sample; train takes about 2 s on it.
RATE_HZ, SAMPLES, SIGMA = 50.0, 20000, 1e-3


@pytest.fixture(scope="module")
def static_log(tmp_path_factory):
    rng = np.random.default_rng(0)
    n = SAMPLES
    nan3 = np.full((n, 3), np.nan)
    data = ImuData(t=np.arange(n) / RATE_HZ, gyr=0.01 + rng.normal(0.0, SIGMA, (n, 3)), acc=nan3, mag=nan3.copy(),
                   temp=np.full(n, 20.0), ref_gyr=np.zeros((n, 3)), meta={"rate_hz": RATE_HZ, "reference": "static"},
                   name="still")
    return write_imu_csv(data, tmp_path_factory.mktemp("noise_train") / "still.csv.gz")


@pytest.fixture(scope="module")
def trained(static_log, tmp_path_factory):
    out = tmp_path_factory.mktemp("noise_trained") / "model"
    assert main(["train", str(static_log), "--out", str(out), "--allow-partial", "--allow-identity"]) == 0
    return out


def test_train_writes_the_noise_block_and_imu_yaml(trained):
    doc = json.loads((trained / "model.json").read_text(encoding="utf-8"))
    block = doc["noise"]
    assert block["format"] == FORMAT and block["rate_hz"] == RATE_HZ
    assert "still.csv: static" in block["source"] or "still: static" in block["source"]
    assert set(block["triads"]) == {"gyr"}  # no accelerometer, no magnetometer recorded
    for axis in block["triads"]["gyr"]["axes"]:
        n = axis["noise_density"]
        assert n["supported"] and n["value"] == pytest.approx(SIGMA / np.sqrt(RATE_HZ), rel=0.05)
    assert load_artefact(trained / "model.json").noise == block
    kalibr = yaml.safe_load((trained / "imu.yaml").read_text(encoding="utf-8"))
    assert kalibr["gyroscope_noise_density"] == pytest.approx(
        max(a["noise_density"]["value"] for a in block["triads"]["gyr"]["axes"]), rel=1e-5)
    assert "noise (68 % CI" in (trained / "calibration.md").read_text(encoding="utf-8")


def test_noise_verb_writes_its_outputs(static_log, tmp_path, capsys):
    out = tmp_path / "noise"
    assert main(["noise", str(static_log), "--out", str(out)]) == 0
    for name in ("noise.json", "imu.yaml", "allan_gyr.png", "noise.md"):
        assert (out / name).is_file(), name
    block = json.loads((out / "noise.json").read_text(encoding="utf-8"))["noise"]
    assert block["format"] == FORMAT
    printed = capsys.readouterr().out
    assert "rad/s/√Hz" in printed and "wrote" in printed


def test_noise_verb_refuses_a_bad_file_in_one_line_naming_it(tmp_path, capsys):
    bad = tmp_path / "broken.csv"
    bad.write_text("t,gyr_x\n0,1\n", encoding="utf-8")
    assert main(["noise", str(bad), "--out", str(tmp_path / "n")]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("imufmu noise: error:") and "broken.csv" in err
    assert not (tmp_path / "n").exists()
