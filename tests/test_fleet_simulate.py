"""`imufmu simulate-fleet`: units drawn from the population the sensor type declares.

Truth here is the declaration itself: the spread tables of scenarios/sensors/mems_grade.toml. The
statistical bounds are 4 standard errors of the estimate (false-failure odds below 1e-4 per check).
"""
import json
from pathlib import Path

import numpy as np
import pytest

from contract.errors import ScenarioError
from training.cli import main
from training.fleet.simulate import simulate_fleet, unit_seeds
from training.fleet.spec import load_fleet
from training.simulator.population import draw_unit, nominal, spreads

ROOT = Path(__file__).resolve().parent.parent
FLEET = ROOT / "scenarios" / "fleet" / "mems_grade.toml"
SENSOR = ROOT / "scenarios" / "sensors" / "mems_grade.toml"
#: Draws of the population statistics test.
DRAWS = 4000
#: Standard errors allowed on a sample mean or standard deviation.
STANDARD_ERRORS = 4.0


def test_units_follow_the_declared_population():
    spec = load_fleet(FLEET)
    declared = spreads(spec.sensor_raw, SENSOR)
    rng = np.random.default_rng(0)
    units = [draw_unit(spec.sensor_raw, SENSOR, rng) for _ in range(DRAWS)]
    base = nominal(spec.sensor_raw)
    for name, sigma in declared.items():
        triad, key = name.split(".", 1)
        values = np.array([np.asarray(u[triad][key], dtype=float) for u in units])
        centre = np.asarray(base[triad][key], dtype=float)
        assert np.all(np.abs(values.mean(axis=0) - centre) <= STANDARD_ERRORS * sigma / np.sqrt(DRAWS) + 1e-15), name
        if key == "soft_iron":  # symmetric perturbation: off-diagonals have σ/√2
            sigma = np.where(np.eye(3, dtype=bool), sigma, sigma / np.sqrt(2.0))
        assert np.all(np.abs(values.std(axis=0) - sigma) <= STANDARD_ERRORS * sigma / np.sqrt(2 * DRAWS)), name
        if key == "soft_iron":
            assert np.allclose(values, np.transpose(values, (0, 2, 1)))


def test_a_unit_does_not_depend_on_the_fleet_size_and_a_seed_repeats_bytes(tmp_path):
    simulate_fleet(FLEET, 1, tmp_path / "one", seed=7, progress=False)
    simulate_fleet(FLEET, 2, tmp_path / "two", seed=7, progress=False)
    for sub in ("calibration/calibration.csv.gz", "test/test_handheld.csv.gz", "unit.json"):
        assert (tmp_path / "one/unit_0000" / sub).read_bytes() == (tmp_path / "two/unit_0000" / sub).read_bytes()
    first, second = (json.loads((tmp_path / "two" / u / "unit.json").read_text()) for u in ("unit_0000", "unit_0001"))
    assert first["sensor"]["gyr"]["bias_dps"] != second["sensor"]["gyr"]["bias_dps"]
    assert first["sensor"]["gyr"]["lsb_dps"] == second["sensor"]["gyr"]["lsb_dps"]  # no spread declared
    assert unit_seeds(7, 1, 2) != unit_seeds(8, 1, 2)
    summary = json.loads((tmp_path / "two" / "fleet_simulation.json").read_text())
    assert summary["units"] == ["unit_0000", "unit_0001"] and summary["test"] == ["test_handheld"]


def test_the_recorded_unit_has_the_drawn_gyro_bias(tmp_path):
    """The first 3 s of the calibration are at rest at 10 °C: the mean gyro error there is the drawn
    bias plus its temperature terms (sensors.py, ΔT = −15 °C), to the noise (0.03 °/s per sample)."""
    simulate_fleet(FLEET, 1, tmp_path, seed=3, progress=False)
    from training.data.io import read_imu_csv
    d = read_imu_csv(tmp_path / "unit_0000/calibration/calibration.csv.gz")
    g = json.loads((tmp_path / "unit_0000/unit.json").read_text())["sensor"]["gyr"]
    dt = -15.0
    expected = np.deg2rad(np.array(g["bias_dps"]) + np.array(g["bias_t1_dps_per_c"]) * dt
                          + np.array(g["bias_t2_dps_per_c2"]) * dt ** 2)
    rest = d.t < 2.5
    measured = np.mean(d.gyr[rest] - d.ref_gyr[rest], axis=0)
    assert np.all(np.abs(measured - expected) < np.deg2rad(0.02)), (np.rad2deg(measured), np.rad2deg(expected))


@pytest.mark.parametrize("spread, problem", [("bias_nope = 0.1", "sets no 'bias_nope'"),
                                             ("bias_dps = -0.1", "σ ≥ 0"),
                                             ("bias_dps = [0.1, 0.2]", "shape")])
def test_a_bad_spread_is_named_with_its_file_and_key(tmp_path, spread, problem):
    sensor = tmp_path / "sensors" / "mems_grade.toml"
    sensor.parent.mkdir()
    text = SENSOR.read_text().replace("[gyr.spread]\n", f"[gyr.spread]\n{spread}\n")
    sensor.write_text(text.replace("bias_dps = 0.15", "") if "bias_dps" in spread else text)
    fleet = tmp_path / "fleet" / "f.toml"
    fleet.parent.mkdir()
    for f in ("calibration.toml", "test_handheld.toml"):
        (fleet.parent / f).write_text((FLEET.parent / f).read_text())
    fleet.write_text(FLEET.read_text())
    with pytest.raises(ScenarioError, match=problem) as e:
        load_fleet(fleet)
    assert "mems_grade.toml: [gyr.spread]" in str(e.value)


def test_cli_refuses_a_scenario_that_is_not_a_fleet_file(tmp_path, capsys):
    assert main(["simulate-fleet", str(ROOT / "scenarios" / "calibration.toml"), "--devices", "2",
                 "--out", str(tmp_path)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "key 'fleet': missing" in err[0]


def test_a_smaller_fleet_into_the_folder_of_a_larger_one_leaves_none_of_its_units(tmp_path):
    """Issue 31 item 5: --devices 2 into a 4-unit folder left units 3-4 of another seed; a folder that
    is not one of the earlier run's units is left alone."""
    simulate_fleet(FLEET, 3, tmp_path, seed=1, progress=False)
    (tmp_path / "notes").mkdir()
    simulate_fleet(FLEET, 1, tmp_path, seed=2, progress=False)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fleet_simulation.json", "notes", "unit_0000"]
    assert json.loads((tmp_path / "fleet_simulation.json").read_text())["units"] == ["unit_0000"]
