"""The closed loop of issue 34 item 3 (training.sensor.closed_loop, docs/virtual_sensor.md "Closed loop"): a
recording's truth -> the virtual-sensor FMU -> the ImuFusion FMU, co-simulated by a second importer (Ecos, through
ecospy) with two FMUs, checked against the truth, against the same loop stepped by fmpy, and run by the campaign
with noise seeds.

The model is small and built here: tests/fmu_cases.py's non-identity gain/bias(T) blocks (degree 2, misaligned,
biased) and TRAINED_SETTINGS (the thermal model on, a magnetometer lag of 2 samples: LAGS) saved as a model.json, its
ImuFusion FMU and its sensor FMU with the noise the simulator gives the shared mems_grade unit
(training.sensor.datasheet). The recording: 10 s of the mems_grade scenario helper (tests/scenario_files.py),
with exact truth.
"""
from __future__ import annotations

import numpy as np
import pytest

from contract.layout import TRIAD_BLOCK
from fmu_cases import TRAINED_SETTINGS, trained_coefficients
from scenario_files import MEMS_GRADE, turn_scenario
from training.artefact import ModelArtefact
from training.cli import main
from training.data.io import read_imu_csv, write_imu_csv
from training.evaluate import ACCEPTANCE
from training.fleet.campaign import CampaignError, campaign_runs, parse_variation, run_partition
from training.models.thermal import ThermalModel
from training.sensor import closed_loop as cl

#: Noise off, the sensor is the exact inverse of the ImuFusion FMU's corrections (issue 34 item 2): the corrected
#: rate, aligned by ALIGNMENT_STEPS, returns the truth to rounding (the gyro does not lead: LAGS).
#: A one-step misalignment costs > 0.1 °/s on the turns' ramps.
EXACT_RATE_DPS = 1e-9
#: The closed loop's accuracy bound is the product's acceptance (training.evaluate.ACCEPTANCE: 0.05 °/s rate,
#: 1° roll and pitch, 2° yaw, 1 µT field), which the main job's recordings of the same mems_grade unit meet: the
#: sensor adds that unit's white noise (0.03 °/s per sample at 100 Hz) and bias walk and nothing the model does
#: not know, so the loop must meet it too. Measured on this recording: rate 0.030 °/s, roll 0.03°, yaw 0.05°.
BOUNDS = {f"{k}": v for k, v in ACCEPTANCE.items()}
#: fmpy on the recording's own times against Ecos's grid (t + h accumulated): the steps differ in the last bits,
#: which moves the attitude integration by rounding only; rates and fields, which do not integrate, are equal.
#: Largest metric difference measured: 4.4e-6° here (roll), 3e-7° on eval_rotations; bound 1e-4°, well below
#: anything the metrics resolve (their 4 printed digits are 1e-3° at best).
GRID_METRIC_TOLERANCE = 1e-4


#: The model's lags: the magnetometer's, +2 samples, as TRAINED_SETTINGS; the gyro's 0. A gyro that leads true
#: time (TRAINED_SETTINGS' lag_gyr = -0.015 s) makes the sensor output a rate ahead of the truth it is given,
#: which a causal sensor can only extrapolate (ImuAlign, 2 x(t) - x(t - lag)): noise off, the corrected rate is
#: then 0.060 °/s RMS from the truth on this recording (0.23 °/s at most, at the ramps' corners; -0.02 s:
#: 0.106 °/s). Reported with issue 34 item 2; this test's model keeps the inverse exact.
LAGS = {"lag_gyr": 0.0, "lag_mag": 0.02}


def _model(path):
    """tests/fmu_cases.py's coefficients and settings (LAGS) as a saved model.json (100 Hz data)."""
    c = trained_coefficients()
    thermal = {triad: ThermalModel.from_block(c[1 + k * TRIAD_BLOCK:1 + (k + 1) * TRIAD_BLOCK])
               for k, triad in enumerate(("gyr", "acc", "mag"))}
    artefact = ModelArtefact(seed=0, thermal=thermal, settings={**TRAINED_SETTINGS, **LAGS},
                             training_data=[{"name": "fmu_cases", "samples": 1000, "rate_hz": 100.0}])
    return artefact.save(path)


@pytest.fixture(scope="module")
def loop(tmp_path_factory):
    """(sensor FMU, ImuFusion FMU, recording path, tmp folder)."""
    from training.fmu_build import build_fmu_from_model
    from training.sensor.build import build_sensor_fmu
    from training.sensor.datasheet import datasheet_noise
    from training.simulator import load_scenario, simulate
    tmp = tmp_path_factory.mktemp("closed_loop")
    model = _model(tmp / "model" / "model.json")
    fusion = build_fmu_from_model(model, tmp / "ImuFusion.fmu")
    sensor, _ = build_sensor_fmu(model, tmp / "ImuSensor.fmu", 2, overrides=datasheet_noise(MEMS_GRADE))
    scenario = turn_scenario(tmp / "turns.toml", axis="z", rate_dps=60.0, angle_deg=90.0, hold_s=2.0, rest_s=1.0,
                             pitch_deg=10.0, extra='''[[segment]]
type = "rotations"
axes = ["x", "y"]
rates_dps = [45.0, 45.0]
angle_deg = 45.0
ramp_s = 0.5
rest_s = 1.0
''')
    data = write_imu_csv(simulate(load_scenario(scenario)), tmp / "turns.csv.gz")
    return sensor, fusion, data, tmp


@pytest.fixture(scope="module")
def ecos_run(loop):
    """The ecospy closed loop, seed 1."""
    sensor, fusion, data, _ = loop
    return cl.closed_loop(sensor, fusion, data, seed=1, importer="ecospy")


def test_the_ecospy_loop_of_two_fmus_follows_the_truth(ecos_run):
    result = ecos_run
    assert result.importer == "ecospy" and result.step_s == 0.01
    assert np.all(np.isnan(result.outputs[-cl.ALIGNMENT_STEPS:]))  # the last sample's estimate is not out yet
    assert np.isfinite(result.outputs[:-cl.ALIGNMENT_STEPS, :9]).all()
    for key, bound in BOUNDS.items():
        assert result.metrics[key] <= bound, (key, result.metrics[key])
    assert result.metrics["rate_err_dps"] > 0.01  # the sensor's noise is in it (0.03 °/s per sample)


def test_noise_off_the_loop_returns_the_truth_at_the_measured_alignment(loop):
    sensor, fusion, data, _ = loop
    traj = cl.trajectory(read_imu_csv(data), fusion)
    stepped = cl.run_fmpy(sensor, fusion, traj, cl.sensor_parameters(0, traj.sensor_parameters, {"noise": 0.0}),
                          traj.fusion_parameters)
    scan = cl.alignment_scan(stepped, traj.body, (0, 1, 2))
    assert min(scan, key=scan.get) == cl.ALIGNMENT_STEPS == 1
    assert scan[cl.ALIGNMENT_STEPS] < EXACT_RATE_DPS
    assert min(scan[0], scan[2]) > 100 * EXACT_RATE_DPS


def test_ecospy_equals_fmpy_bit_for_bit_on_the_same_grid(loop, ecos_run):
    sensor, fusion, data, _ = loop
    traj = cl.trajectory(read_imu_csv(data), fusion)
    params = cl.sensor_parameters(1, traj.sensor_parameters)
    on_grid = cl.run_fmpy(sensor, fusion, traj, params, traj.fusion_parameters,
                          t=cl.ecos_grid(len(traj.t), ecos_run.step_s), h=ecos_run.step_s)
    assert np.array_equal(ecos_run.stepped, on_grid, equal_nan=True)
    own = cl.closed_loop(sensor, fusion, data, seed=1, importer="fmpy")  # the recording's own times
    for key, value in ecos_run.metrics.items():
        assert own.metrics[key] == pytest.approx(value, abs=GRID_METRIC_TOLERANCE), key


def test_the_campaign_draws_a_noise_seed_per_run_and_repeats_it(loop):
    sensor, fusion, data, _ = loop
    runs = run_partition([0, 1, 2], str(fusion), str(data), (), 5, str(sensor))
    assert len({r["seed"] for r in runs}) == 3 and not any(r["failed"] for r in runs)
    assert len({r["rate_err_dps"] for r in runs}) == 3  # each seed its own noise
    assert run_partition([1], str(fusion), str(data), (), 5, str(sensor)) == runs[1:2]  # run 1 alone: the same
    fixed = run_partition([0, 1], str(fusion), str(data), (parse_variation("seed=choice(7)", sensor=True),), 5,
                          str(sensor))
    assert [r["seed"] for r in fixed] == [7.0, 7.0]
    assert {k: v for k, v in fixed[0].items() if k != "run"} == {k: v for k, v in fixed[1].items() if k != "run"}


def test_the_campaign_runs_the_closed_loop_on_dask(loop, tmp_path):
    sensor, fusion, data, _ = loop
    runs = campaign_runs(fusion, data, 2, (), seed=5, workers=1, progress=False, sensor_path=sensor)
    assert runs == run_partition([0, 1], str(fusion), str(data), (), 5, str(sensor))


def _one_line_error(capsys, argv, text):
    assert main(argv) == 1
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and text in err, err
    return err


def test_a_sensor_fmu_that_is_not_one_is_refused_in_one_line(loop, capsys):
    sensor, fusion, data, tmp = loop
    with pytest.raises(cl.ClosedLoopError, match="not an ImuSensor FMU"):
        cl.closed_loop(fusion, fusion, data)
    with pytest.raises(cl.ClosedLoopError, match="not an ImuFusion FMU"):
        cl.closed_loop(sensor, sensor, data)
    with pytest.raises(CampaignError, match="--sensor: .*not an ImuSensor FMU"):
        campaign_runs(fusion, data, 1, (), workers=1, progress=False, sensor_path=fusion)


def test_a_recording_without_truth_is_refused_in_one_line(loop, tmp_path):
    sensor, fusion, data, _ = loop
    from dataclasses import replace
    bare = write_imu_csv(replace(read_imu_csv(data), ref_gyr=None, ref_q=None), tmp_path / "bare.csv.gz")
    with pytest.raises(cl.ClosedLoopError, match="lacks ref_gyr_x..z, ref_qw..ref_qz"):
        cl.closed_loop(sensor, fusion, bare)
    with pytest.raises(CampaignError, match="lacks ref_gyr_x..z, ref_qw..ref_qz"):
        campaign_runs(fusion, bare, 1, (), workers=1, progress=False, sensor_path=sensor)


def test_what_a_closed_loop_cannot_do_is_refused(loop, tmp_path):
    sensor, fusion, data, _ = loop
    full = read_imu_csv(data)
    gap = write_imu_csv(full.slice(np.r_[0:300, 301:len(full)]), tmp_path / "gap.csv.gz")
    with pytest.raises(cl.ClosedLoopError, match="run it with --importer fmpy"):
        cl.closed_loop(sensor, fusion, gap, importer="ecospy")
    assert np.isfinite(cl.closed_loop(sensor, fusion, gap, importer="fmpy").metrics["tilt_err_deg"])
    for text in ("noise_gyr=uniform(0,0.01)",):
        with pytest.raises(CampaignError, match="with --sensor: the virtual sensor makes the noise"):
            campaign_runs(fusion, data, 1, (parse_variation(text),), workers=1, progress=False, sensor_path=sensor)
    with pytest.raises(CampaignError, match="needs --sensor"):
        parse_variation("gyr_noise_density_x=uniform(0,1e-4)")


def test_the_cli_prints_the_errors_with_units_and_writes_outputs_and_plot(loop, ecos_run, tmp_path, capsys):
    sensor, fusion, data, _ = loop
    out = tmp_path / "loop"
    assert main(["closed-loop", "--sensor", str(sensor), "--fusion", str(fusion), str(data), "--out", str(out),
                 "--seed", "1"]) == 0
    printed = capsys.readouterr().out
    assert "co-simulated by ecospy; outputs aligned 1 step back" in printed
    assert "| corrected rate error RMS [°/s] |" in printed and "| heading error RMS [°] |" in printed
    assert sorted(p.name for p in out.iterdir() if not p.name.startswith(".")) == sorted(cl.OUTPUT_FILES)
    written = np.loadtxt(out / "outputs.csv", delimiter=",", skiprows=1)
    np.testing.assert_array_equal(written[:, 1:], ecos_run.outputs)  # the same ecospy run, seed 1, to the bit


def test_the_cli_refuses_in_one_line(loop, tmp_path, capsys):
    sensor, fusion, data, _ = loop
    _one_line_error(capsys, ["closed-loop", "--sensor", str(fusion), "--fusion", str(fusion), str(data), "--out",
                             str(tmp_path / "a")], "not an ImuSensor FMU")
    _one_line_error(capsys, ["campaign", str(fusion), str(data), "--runs", "1", "--sensor", str(fusion), "--out",
                             str(tmp_path / "b"), "--workers", "1"], "not an ImuSensor FMU")
    _one_line_error(capsys, ["campaign", str(fusion), str(data), "--runs", "1", "--sensor", str(sensor), "--vary",
                             "noise_gyr=uniform(0,0.01)", "--out", str(tmp_path / "c"), "--workers", "1"],
                    "the virtual sensor makes the noise")
