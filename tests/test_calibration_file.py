"""A calibration is a file (issue 32): `imufmu train` writes calibration.ssv (SSP SSV 1.0, valid against the
standard's XSD, units declared) beside model.json, and `imufmu run FMU DATA --calibration unit.ssv` runs a
generic FMU (no calibration compiled in) with it: the outputs are those of the FMU the unit's calibration was
compiled into, bit for bit. fmpy's own SSV reader reads the file."""
from __future__ import annotations

import numpy as np
import pytest
from fmpy.ssp.ssd import read_ssv as fmpy_read_ssv

from contract import coefficient_parameters as cp
from contract.errors import DataError
from contract.layout import identity_coefficients
from fmu.ssv import validate_ssv
from fmu.validator import validate_fmu
from training.artefact import coefficients_array, load_artefact, settings_dict
from fmu.calibration_file import read_calibration, write_calibration
from training.cli import main
from training.data.io import read_imu_csv, write_imu_csv
from training.fmu_build import build_fmu
from training.main_job import SCENARIO_DIR
from training.simulator import load_scenario, simulate


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """(folder of `imufmu train` on a short calibration session, a recording to run)."""
    tmp = tmp_path_factory.mktemp("calibration_file")
    data = simulate(load_scenario(SCENARIO_DIR / "variants" / "diag_calibration_clean.toml"))
    path = write_imu_csv(data, tmp / "session.csv.gz")
    assert main(["train", str(path), "--out", str(tmp / "unit"), "--allow-partial"]) == 0
    run = write_imu_csv(data.slice(np.arange(0, 500)), tmp / "run.csv.gz")
    return tmp, run


def test_train_writes_a_valid_calibration_file_fmpy_reads(trained):
    tmp, _ = trained
    ssv = tmp / "unit" / "calibration.ssv"
    assert validate_ssv(ssv) == []
    artefact = load_artefact(tmp / "unit" / "model.json")
    coefficients, settings, _ = read_calibration(ssv)
    np.testing.assert_array_equal(coefficients, coefficients_array(artefact))
    assert settings == {k: float(v) for k, v in settings_dict(artefact).items()}
    names = {p.name for p in fmpy_read_ssv(str(ssv)).parameters}
    assert {cp.scalar_name(b, k) for b in cp.BLOCKS for k in range(b.size)} <= names
    assert "field_norm" in names and 'unit="uT"' in ssv.read_text()
    assert 'name="unit"' in ssv.read_text()  # the unit folder's name, not the staging folder's


@pytest.mark.parametrize("fmi", [2, 3])
def test_a_generic_fmu_runs_the_unit_from_its_calibration_file(trained, fmi):
    tmp, run = trained
    artefact = load_artefact(tmp / "unit" / "model.json")
    compiled = build_fmu(coefficients_array(artefact), settings_dict(artefact), tmp / f"unit{fmi}.fmu", fmi_version=fmi)
    generic = tmp / f"generic{fmi}.fmu"  # build-fmu without a model: no calibration compiled in, the unit embedded
    ssv = tmp / "unit" / "calibration.ssv"
    assert main(["build-fmu", "--out", str(generic), "--fmi", str(fmi), "--variant", f"unit-A={ssv}"]) == 0
    assert validate_fmu(generic) == []  # every embedded set checked against the model description
    outputs = {}
    for name, fmu, extra in (("compiled", compiled, []), ("generic", generic, ["--calibration", str(ssv)]),
                             ("embedded", generic, ["--variant", "unit-A"])):
        out = tmp / f"{name}{fmi}.csv"
        assert main(["run", str(fmu), str(run), "--out", str(out), *extra]) == 0
        outputs[name] = np.genfromtxt(out, delimiter=",", names=True)
    for name in ("generic", "embedded"):
        assert outputs[name].dtype.names == outputs["compiled"].dtype.names
        for column in outputs["compiled"].dtype.names:
            np.testing.assert_array_equal(outputs[name][column], outputs["compiled"][column], err_msg=f"{name} {column}")


def test_a_calibration_of_another_layout_is_refused_naming_the_block(tmp_path):
    coefficients = np.array(identity_coefficients())
    path = write_calibration(tmp_path / "unit.ssv", coefficients, {})
    text = path.read_text()
    last = cp.scalar_name(cp.BLOCKS[-1], cp.BLOCKS[-1].size - 1)
    start = text.index(f'name="{last}"')
    (tmp_path / "short.ssv").write_text(text[:text.rindex("<ssv:Parameter ", 0, start)] + text[text.index("</ssv:Parameter>", start) + 16:])
    with pytest.raises(DataError, match=r"short.ssv: coefficient block 'calibration.psobp': 201 value\(s\)"):
        read_calibration(tmp_path / "short.ssv")


def test_the_auxiliary_input_map_travels_with_the_calibration(tmp_path):
    aux = [{"column": "aux_motor_current", "unit": "A", "meaning": "motor current"},
           {"column": "aux_supply_voltage", "unit": "V", "meaning": ""}]
    path = write_calibration(tmp_path / "unit.ssv", np.array(identity_coefficients()), {}, aux)
    assert validate_ssv(path) == []
    assert read_calibration(path)[2] == aux


def test_the_default_experiment_steps_at_the_sensors_rate(trained):
    # the calibration session is simulated at 50 Hz: the FMU consumes one sample per step
    from fmpy import read_model_description
    from fmu.model_description import default_experiment
    tmp, _ = trained
    assert load_artefact(tmp / "unit" / "model.json").training_data[0]["rate_hz"] == pytest.approx(50.0, rel=1e-9)
    fmu = tmp / "from_model.fmu"
    assert main(["build-fmu", "--model", str(tmp / "unit" / "model.json"), "--out", str(fmu)]) == 0
    assert float(read_model_description(str(fmu)).defaultExperiment.stepSize) == pytest.approx(0.02, rel=1e-9)
    assert default_experiment(())["stepSize"] == 0.01  # no calibration data (the generic FMU): 100 Hz
