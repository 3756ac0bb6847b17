"""Calibrating and running a unit needs no C compiler (issue 32): with the artefacts `imufmu prebuild` wrote
(the runtime library, the generic FMUs) and neither a compiler nor CMake nor binutils on PATH, `imufmu train`
calibrates, `imufmu build-fmu` embeds the unit in the prebuilt generic FMU, `imufmu validate` finds 0 problems and
`imufmu run` gives the outputs of the unit's own compiled FMU bit for bit. Stale prebuilt artefacts and a
trained FMU that would need compiling are refused in one line."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

from fmu.calibration_file import read_calibration
from fmu.prebuilt import MANIFEST
from training.data.io import write_imu_csv
from training.fmu_build import build_fmu, build_prebuilt
from training.main_job import SCENARIO_DIR
from training.simulator import load_scenario, simulate


def _imufmu(tmp, *args: str, prebuilt=None) -> subprocess.CompletedProcess:
    """`imufmu ARGS` in tmp with an empty PATH (no cc, cmake, nm) and its own runtime cache."""
    empty = tmp / "empty-path"
    empty.mkdir(exist_ok=True)
    env = {"HOME": str(tmp), "PATH": str(empty), "IMUFUSION_CACHE": str(tmp / "cache"),
           "IMUFUSION_PREBUILT": str(prebuilt or tmp / "prebuilt"), "OMP_NUM_THREADS": "1"}
    return subprocess.run([sys.executable, "-m", "training.cli", *args], cwd=tmp, env=env, capture_output=True,
                          text=True)


@pytest.fixture(scope="module")
def unit(tmp_path_factory):
    """(folder, the recording to run): prebuilt artefacts, and `imufmu train` on a calibration session run
    without a compiler."""
    tmp = tmp_path_factory.mktemp("without_compiler")
    build_prebuilt(tmp / "prebuilt")
    data = simulate(load_scenario(SCENARIO_DIR / "variants" / "diag_calibration_clean.toml"))
    write_imu_csv(data, tmp / "session.csv.gz")
    run = write_imu_csv(data.slice(np.arange(0, 400)), tmp / "run.csv.gz")
    assert shutil.which("cc", path=str(tmp)) is None
    done = _imufmu(tmp, "train", "session.csv.gz", "--out", "unit", "--allow-partial")
    assert done.returncode == 0, done.stderr
    assert not (tmp / "cache").exists()  # nothing was compiled: the prebuilt runtime library ran
    return tmp, run


def test_a_unit_is_calibrated_and_run_without_a_compiler_as_its_compiled_fmu(unit):
    tmp, run = unit
    coefficients, settings, _ = read_calibration(tmp / "unit" / "calibration.ssv")
    compiled = build_fmu(coefficients, settings, tmp / "compiled.fmu")  # here, with the compiler
    assert _imufmu(tmp, "run", str(compiled), str(run), "--out", "compiled.csv").returncode == 0
    done = _imufmu(tmp, "build-fmu", "--out", "generic.fmu", "--variant", "unit=unit/calibration.ssv")
    assert done.returncode == 0, done.stderr
    done = _imufmu(tmp, "validate", "generic.fmu")
    assert done.returncode == 0 and "0 problems" in done.stdout, done.stdout + done.stderr
    for name, extra in (("variant", ["--variant", "unit"]), ("file", ["--calibration", "unit/calibration.ssv"])):
        done = _imufmu(tmp, "run", "generic.fmu", str(run), "--out", f"{name}.csv", *extra)
        assert done.returncode == 0, done.stderr
        assert (tmp / f"{name}.csv").read_bytes() == (tmp / "compiled.csv").read_bytes(), name


def test_a_trained_fmu_without_a_compiler_is_refused_naming_the_way_round(unit):
    tmp, _ = unit
    done = _imufmu(tmp, "build-fmu", "--model", "unit/model.json", "--out", "trained.fmu")
    assert done.returncode != 0 and "Traceback" not in done.stderr
    assert "needs a C compiler and CMake" in done.stderr and "--variant unit=" in done.stderr


def test_prebuilt_artefacts_of_other_sources_are_refused(unit):
    tmp, _ = unit
    stale = tmp / "stale"
    shutil.copytree(tmp / "prebuilt", stale)
    manifest = json.loads((stale / MANIFEST).read_text())
    (stale / MANIFEST).write_text(json.dumps({**manifest, "key": "0" * 20}))
    done = _imufmu(tmp, "train", "session.csv.gz", "--out", "unit2", "--allow-partial", prebuilt=stale)
    assert done.returncode != 0 and "Traceback" not in done.stderr
    assert "built from other sources" in done.stderr and "imufmu prebuild" in done.stderr
    os.remove(stale / MANIFEST)
    done = _imufmu(tmp, "train", "session.csv.gz", "--out", "unit2", "--allow-partial", prebuilt=stale)
    assert "holds no prebuilt artefacts" in done.stderr
