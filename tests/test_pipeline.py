"""The main job end to end: simulated calibration -> trained model -> FMU -> fmpy co-simulation.

Asserts against simulator truth on evaluation scenarios that were not used for training, with the
acceptance bounds of issue 2 (training.evaluate.ACCEPTANCE, justified there).
"""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from training.attitude.replay import CANDIDATES
from training.evaluate import ACCEPTANCE
from training.main_job import DEFAULT_EVALUATIONS, run_main_job

#: FMU through fmpy and the batch library run the same C code on the same doubles; the only
#: admissible difference is none at all, 1e-12 leaves room for nothing but printing round-off.
FMU_BATCH_TOLERANCE = 1e-12


@pytest.fixture(scope="module")
def summary(tmp_path_factory):
    return run_main_job(tmp_path_factory.mktemp("pipeline"), seed=0)


def test_fmu_validates(summary):
    assert summary.validation_problems == []


def test_at_least_two_held_out_scenarios(summary):
    assert len(summary.scenarios) == len(DEFAULT_EVALUATIONS) >= 2


@pytest.mark.parametrize("metric", sorted(ACCEPTANCE))
def test_accuracy_against_truth(summary, metric):
    for s in summary.scenarios:
        assert s.corrected[metric] <= ACCEPTANCE[metric], (s.name, metric, s.corrected[metric])


def test_compensation_beats_raw_sensors(summary):
    for s in summary.scenarios:
        for metric in ("rate_err_dps", "field_err_ut"):
            assert s.corrected[metric] < 0.5 * s.raw[metric], (s.name, metric)


def test_fmu_equals_batch_runtime(summary):
    for s in summary.scenarios:
        assert s.fmu_vs_batch_max_diff <= FMU_BATCH_TOLERANCE, s.name


def test_outputs_finite(summary):
    for s in summary.scenarios:
        assert np.all(np.isfinite(s.out)), s.name


def test_report_and_summary_written(summary):
    out = Path(summary.out_dir)
    report = (out / "report.md").read_text()
    assert "ImuFusion FMU" in report and "plots/" in report
    data = json.loads((out / "summary.json").read_text())
    assert data["passed"] is True
    for s in summary.scenarios:
        assert (out / "plots" / f"{s.name}.png").stat().st_size > 10_000


def test_the_uniform_simulated_field_keeps_the_magnetometer(summary):
    """The simulated earth field is uniform: train keeps the magnetometer for the heading and says why
    (the non-uniform case: tests/test_magnetic_trust.py)."""
    model = json.loads((Path(summary.out_dir) / "model" / "model.json").read_text())
    assert model["settings"]["mag_heading"] == 1.0
    assert any(n.startswith("mag_heading = 1: the magnetometer corrects the heading") for n in model["notes"])


def test_the_unchanged_simulated_field_leaves_the_particle_filter_off(summary):
    """The simulated field around the sensor never changes: the particle filter, run over the
    calibration recording, declares no hard-iron change, so train leaves it off and says so (the
    change case: tests/test_field_changes.py)."""
    model = json.loads((Path(summary.out_dir) / "model" / "model.json").read_text())
    assert model["settings"]["enable_pf"] == 0.0
    assert any(n.startswith("enable_pf = 0: the online hard/soft-iron filter, run over the 1 calibration")
               for n in model["notes"])


def test_train_writes_the_filter_settings_its_replay_measured_best(summary):
    """The simulated calibration recording carries an attitude reference: train replays it through the
    FMU's filter for every replayed setting (training.attitude.replay.CANDIDATES), writes the value with
    the lower total attitude error (one recording: lower on every recording is lower in total) and
    notes both figures; the simulator's samples are instantaneous, so gyro_hold is 0 (the trapezoid)."""
    model = json.loads((Path(summary.out_dir) / "model" / "model.json").read_text())
    assert model["settings"]["gyro_hold"] == 0.0
    for name in CANDIDATES:
        note = next(n for n in model["notes"] if n.startswith(f"{name} = ") and "chosen by replaying" in n)
        figures = dict(re.findall(r"([0-9.]+): ([0-9.]+)°", note.split("RMSE", 1)[1]))
        best = min(figures, key=lambda v: float(figures[v]))
        assert model["settings"][name] == float(best), note


def test_main_job_reproduces_the_golden_record(summary):
    """The main job's artefact and FMU outputs equal the record taken before the redesign of issue
    17 (tests/golden.py: to 1e-9 + 1e-5 relative, the floating-point spread between CPUs; angles modulo
    2π): moving code changes no number."""
    import golden
    assert golden.differences(summary) == {}


def test_the_generic_fmu_with_the_trained_calibration_file_is_the_trained_fmu(summary, tmp_path):
    """Issue 32 on the golden records' ground: the FMU built without a calibration (build-fmu without a
    model), with the main job's trained set applied from its calibration.ssv, gives the compiled FMU's outputs
    bit for bit on every evaluation scenario and on the first 20 s of BROAD trial 01."""
    import golden
    from fmu.calibration_file import read_calibration, write_calibration
    from fmu.cosim import run_fmu
    from training.artefact import coefficients_array, load_artefact, settings_dict
    from training.data.io import read_imu_csv
    from training.fmu_build import build_fmu_from_model
    from training.main_job import recording_parameters
    artefact = load_artefact(summary.model_path)
    ssv = write_calibration(tmp_path / "calibration.ssv", coefficients_array(artefact), settings_dict(artefact),
                            artefact.aux_inputs)
    coefficients, settings, aux = read_calibration(ssv)
    generic = build_fmu_from_model(None, tmp_path / "generic.fmu")
    for s in summary.scenarios:
        out = run_fmu(generic, s.data.t, s.data.inputs([a["column"] for a in aux]),
                      parameters=settings | recording_parameters(s.data), coefficients=coefficients)
        np.testing.assert_array_equal(out, s.out, err_msg=s.name)
    compiled = golden.broad_outputs(Path(summary.fmu_path))
    if compiled is not None:
        data = read_imu_csv(golden.BROAD_TRIAL).slice(slice(0, golden.BROAD_SAMPLES))
        out = run_fmu(generic, data.t, data.inputs(), parameters=settings | recording_parameters(data),
                      coefficients=coefficients)
        np.testing.assert_array_equal(out, compiled)
