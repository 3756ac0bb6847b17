"""The ImuFusion FMU: validity and exports for FMI 2.0 and 3.0; for FMI 2.0 the model description, binary, variable table, co-simulation, FMU state."""
from __future__ import annotations

import ctypes
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
from fmpy.logging import addLoggerProxy
from fmpy.validation import validate_fmu as fmpy_validate_fmu

from contract import coefficient_parameters
from contract.errors import BuildError, ModelError
from contract.layout import (INPUTS, N_COEFFICIENTS, OUTPUTS, SETTINGS,
                             identity_coefficients, settings_array)
from contract.variables import VARIABLES, by_name
from fmu.compiler import SOURCE_DIR, compile_binary
from fmu.cosim import FmuError, initialised_fmu, run_fmu, step_samples, step_sizes
from fmu.header import coefficient_header, read_header_arrays
from fmu.model_description import LOG_CATEGORIES, model_description_xml
from fmu.validator import FMI2_CS_FUNCTIONS, FMI3_FUNCTIONS, exported_symbols, fmutool_problems, validate_fmu
from training.fmu_build import build_fmu
from training.runtime import run_batch
from fmu_cases import GOLDEN_TOLERANCE, TRAINED_SETTINGS, synthetic_recording, trained_coefficients

#: FMI version -> (the functions its co-simulation binary exports, how many the standard names).
EXPORTS = {2: (FMI2_CS_FUNCTIONS, 34), 3: (FMI3_FUNCTIONS, 75)}


def test_fmpy_and_full_validation_find_no_problems(trained_fmu):
    assert fmpy_validate_fmu(str(trained_fmu)) == []
    assert validate_fmu(trained_fmu) == []  # symbols, fmutool -check, smoke run, shipped reference result


def test_binary_exports_exactly_the_fmi_cosimulation_functions(trained_fmu, fmi_version):
    functions, count = EXPORTS[fmi_version]
    assert len(functions) == count
    assert exported_symbols(trained_fmu) == functions


def test_unknown_variable_names_the_known_ones():
    with pytest.raises(KeyError, match="unknown FMU variable 'gyr_w' .*gyr_x"):
        by_name("gyr_w")


def test_model_description_follows_table_and_settings(trained_fmu2):
    md = read_model_description(str(trained_fmu2))
    assert md.coSimulation.canHandleVariableCommunicationStepSize
    assert md.coSimulation.canGetAndSetFMUstate and md.coSimulation.canSerializeFMUstate
    got = {v.name: (v.valueReference, v.causality, v.type, v.unit) for v in md.modelVariables
           if not v.name.startswith(coefficient_parameters.PREFIX)}
    # A Real without a unit in the table is declared dimensionless ("1"); Booleans and Integers have none.
    assert got == {v.name: (v.value_reference, v.causality, v.type,
                            (v.unit or "1") if v.type == "Real" else None) for v in VARIABLES}
    # the coefficient parameters: one Real per coefficient, its start the coefficient compiled in
    coefficients = {v.name: (v.valueReference, float(v.start)) for v in md.modelVariables
                    if v.name.startswith(coefficient_parameters.PREFIX)}
    trained = coefficient_parameters.scalar_values(trained_coefficients())
    assert list(coefficients) == list(trained)
    assert [start for _, start in coefficients.values()] == list(trained.values())
    assert [vr for vr, _ in coefficients.values()] == list(range(coefficient_parameters.FMI2_COEFFICIENT_VR,
                                                                 coefficient_parameters.FMI2_COEFFICIENT_VR + len(trained)))
    starts = {v.name: v.start for v in md.modelVariables if v.causality == "parameter"
              and not v.name.startswith(coefficient_parameters.PREFIX)}
    booleans = {v.name for v in VARIABLES if v.type == "Boolean"}
    assert {k: float(v == "true") if k in booleans else float(v) for k, v in starts.items()} \
        == {**dict(SETTINGS), **TRAINED_SETTINGS}
    sources = md.buildConfigurations[0].sourceFileSets[0].sourceFiles
    expected = sorted(p.name for p in SOURCE_DIR.glob("*.c") if p.name != "fmi3Functions.c")
    assert sorted(sources) == expected


def test_fmu_without_thermal_model_passes_raw_signals_through(trained_fmu2):
    t, raw = synthetic_recording(200)
    out = run_fmu(trained_fmu2, t, raw, parameters={"enable_thermal": False, "lag_gyr": 0.0, "lag_mag": 0.0})
    np.testing.assert_allclose(out[:, :9], raw[:, :9], rtol=0, atol=1e-12)


def test_fmu_equals_batch_runtime_on_variable_steps(trained_fmu2):
    t, raw = synthetic_recording()
    fmu_out = run_fmu(trained_fmu2, t, raw)
    # Both run the same guard (sources/ImuGuard.c): the batch gets the RAW recording, NaN stretch
    # of the temperature included, and holds the last valid temperature through it as the FMU does.
    assert np.isnan(raw[:, INPUTS.index("temp")]).any()
    batch_out = run_batch(trained_coefficients(), settings_array(TRAINED_SETTINGS), t, raw)
    assert fmu_out.shape == (t.size, len(OUTPUTS))
    np.testing.assert_allclose(fmu_out, batch_out, rtol=0, atol=GOLDEN_TOLERANCE, equal_nan=True)
    np.testing.assert_allclose(fmu_out[:, OUTPUTS.index("heading")],
                               fmu_out[:, OUTPUTS.index("yaw")] + TRAINED_SETTINGS["declination"],
                               rtol=0, atol=1e-12)


def test_fmu_equals_batch_runtime_on_bad_input(trained_fmu2):
    # The batch library runs the FMU's input/time/output guard (sources/ImuGuard.c), so the two
    # agree on any input and the batch outputs stay finite.
    t, raw = synthetic_recording()
    raw[30, 0], raw[31, 1], raw[32:35, 2] = np.nan, np.inf, 1e300         # bad gyroscope samples
    raw[50:70, 6:9] = 0.0                                                 # all-zero field stretch
    raw[90:100, 9], raw[100:105, 9], raw[400, 9] = 400.0, -100.0, np.inf  # temperature out of range
    raw[120, 3:6] = -np.inf                                               # bad accelerometer sample
    fmu_out = run_fmu(trained_fmu2, t, raw)
    batch_out = run_batch(trained_coefficients(), settings_array(TRAINED_SETTINGS), t, raw)
    assert np.all(np.isfinite(batch_out))
    np.testing.assert_allclose(fmu_out, batch_out, rtol=0, atol=GOLDEN_TOLERANCE)


def test_parameters_are_set_by_name(trained_fmu2):
    t, raw = synthetic_recording(50)
    params = {"declination": -0.1, "enable_thermal": False}
    fmu_out = run_fmu(trained_fmu2, t, raw, parameters=params)
    batch_out = run_batch(trained_coefficients(), settings_array({**TRAINED_SETTINGS, **params}), t, raw)
    np.testing.assert_allclose(fmu_out, batch_out, rtol=0, atol=GOLDEN_TOLERANCE, equal_nan=True)
    with pytest.raises(FmuError, match="not a parameter"):
        run_fmu(trained_fmu2, t, raw, parameters={"gyr_x": 1.0})


#: FMI version -> (an invalid parameter value, what the error must say about it).
INVALID_PARAMETERS = {2: ({"field_norm": -1.0}, "field_norm"),
                      3: ({"gyro_noise": -1.0}, "gyro_noise must be finite and within [0, 0.1]")}


def test_invalid_parameter_fails_initialisation_naming_it(trained_fmu, fmi_version):
    parameters, message = INVALID_PARAMETERS[fmi_version]
    t, raw = synthetic_recording(5)
    with pytest.raises(FmuError, match=f"fmi{fmi_version}ExitInitializationMode") as info:
        run_fmu(trained_fmu, t, raw, parameters=parameters)
    assert message in str(info.value)


@pytest.mark.parametrize("name, value", [("pf_particles", 2.9), ("pf_particles", 4294967298.0),
                                         ("enable_pf", 0.5), ("enable_thermal", 2.0)])
def test_run_fmu_refuses_integer_and_boolean_values_it_would_have_to_round(trained_fmu2, name, value):
    """int(2.9) = 2 particles, bool(0.5) = filter on: the library path refuses, naming the parameter."""
    t, raw = synthetic_recording(5)
    with pytest.raises(FmuError, match=name):
        run_fmu(trained_fmu2, t, raw, parameters={name: value})


def test_parameters_cannot_be_set_after_initialisation(trained_fmu2):
    with pytest.raises(FmuError, match="parameters are fixed"):
        with initialised_fmu(trained_fmu2) as fmu:
            fmu.setReal([by_name("field_norm").value_reference], [40.0])


def _restore_midway(fmu_path, t, raw, params, k):
    """(outputs before sample k, outputs after it, outputs after it again from the state saved at k)."""
    h = step_sizes(t, 0.01)
    with initialised_fmu(fmu_path, t[0], params) as fmu:
        head = step_samples(fmu, t[:k], raw[:k], h[:k])
        state = fmu.getFMUstate()
        first = step_samples(fmu, t[k:], raw[k:], h[k:])
        fmu.setFMUstate(state)
        second = step_samples(fmu, t[k:], raw[k:], h[k:])
        fmu.freeFMUstate(state)
    return head, first, second


def test_fmu_state_restore_continues_identically(trained_fmu2):
    t, raw = synthetic_recording(300)
    head, first, second = _restore_midway(trained_fmu2, t, raw, TRAINED_SETTINGS, 120)
    np.testing.assert_array_equal(first, second)
    np.testing.assert_array_equal(np.vstack([head, first]),
                                  run_fmu(trained_fmu2, t, raw, parameters=TRAINED_SETTINGS))


def test_particle_filter_in_the_fmu_equals_batch_and_its_state_is_restored(trained_fmu2):
    # The filter (particles, power sums, generator) is part of the FMU state: a restore in the
    # middle of the run continues bit-identically, and the FMU equals the batch runtime.
    t, raw = synthetic_recording(600)
    params = {**TRAINED_SETTINGS, "enable_pf": True, "pf_decimation": 4, "pf_hold_prior": False}
    fmu_out = run_fmu(trained_fmu2, t, raw, parameters=params)
    batch_out = run_batch(trained_coefficients(), settings_array(params), t, raw)
    np.testing.assert_allclose(fmu_out, batch_out, rtol=0, atol=GOLDEN_TOLERANCE, equal_nan=True)
    assert np.all(fmu_out[:, OUTPUTS.index("pf_neff")] > 0.0)
    _, first, second = _restore_midway(trained_fmu2, t, raw, params, 300)
    np.testing.assert_array_equal(first, second)
    np.testing.assert_array_equal(first, fmu_out[300:])


def test_serialized_fmu_state_restores_identically(trained_fmu2):
    t, raw = synthetic_recording(300)
    h, k = step_sizes(t, 0.01), 200
    with initialised_fmu(trained_fmu2, t[0], TRAINED_SETTINGS) as fmu:
        step_samples(fmu, t[:k], raw[:k], h[:k])
        state = fmu.getFMUstate()
        data = fmu.serializeFMUstate(state)
        fmu.freeFMUstate(state)
        first = step_samples(fmu, t[k:], raw[k:], h[k:])
        restored = fmu.deSerializeFMUstate(data)
        fmu.setFMUstate(restored)
        fmu.freeFMUstate(restored)
        second = step_samples(fmu, t[k:], raw[k:], h[k:])
    np.testing.assert_array_equal(first, second)


def test_header_round_trips_coefficients_exactly():
    c = trained_coefficients()
    c[-4:] = [0.1, 1.0 / 3.0, 5e-324, -0.0]
    text = coefficient_header(c, {"field_norm": 1.0 / 7.0}, "{guid}", "test */ provenance")
    coefficients, settings, guid = read_header_arrays(text)
    assert coefficients.tobytes() == c.tobytes()
    assert settings.tolist() == settings_array({"field_norm": 1.0 / 7.0})
    assert guid == "{guid}"
    assert "test * / provenance" in text


def test_wrong_coefficient_length_is_a_model_error(tmp_path):
    with pytest.raises(ModelError, match=str(N_COEFFICIENTS)):
        coefficient_header(np.zeros(N_COEFFICIENTS - 1), {}, "{guid}", "")
    with pytest.raises(ModelError):
        build_fmu(np.zeros(N_COEFFICIENTS + 1), {}, tmp_path / "bad.fmu")
    with pytest.raises(ModelError, match="unknown setting"):
        build_fmu(np.array(identity_coefficients()), {"gain": 1.0}, tmp_path / "bad.fmu")
    assert not (tmp_path / "bad.fmu").exists()


def test_compiler_warning_is_a_build_error_with_the_output(tmp_path):
    (tmp_path / "sources").mkdir()
    # Only a -Wextra warning (unused parameter): the build treats warnings as errors.
    (tmp_path / "sources" / "warns.c").write_text("int warns(int unused_argument) { return 0; }\n")
    (tmp_path / "modelDescription.xml").write_text(
        model_description_xml({}, "{guid}", "warns", source_files=["warns.c"]))
    with pytest.raises(BuildError, match="unused_argument"):
        compile_binary(tmp_path)


def test_reset_returns_to_the_instantiated_state(trained_fmu2):
    t, raw = synthetic_recording(100)
    h = step_sizes(t, 0.01)
    with initialised_fmu(trained_fmu2, t[0], TRAINED_SETTINGS) as fmu:
        first = step_samples(fmu, t, raw, h)
        fmu.reset()
        assert fmu.getReal([by_name("field_norm").value_reference]) == [TRAINED_SETTINGS["field_norm"]]
        fmu.setupExperiment(startTime=t[0])
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        second = step_samples(fmu, t, raw, h)
    np.testing.assert_array_equal(first, second)


def test_instantiate_rejects_a_foreign_guid(trained_fmu2, tmp_path):
    md = read_model_description(str(trained_fmu2))
    fmu = FMU2Slave(guid="{not-this-fmu}", unzipDirectory=extract(str(trained_fmu2), tmp_path),
                    modelIdentifier=md.coSimulation.modelIdentifier)
    with pytest.raises(Exception, match="Failed to instantiate"):
        fmu.instantiate()
    fmu.freeLibrary()


_FMPY_DEFAULT_LOGGER_AFTER_RUN = """
import gc, sys
import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from contract.layout import INPUTS
from fmu.cosim import run_fmu
path, unzipped = sys.argv[1], sys.argv[2]
for _ in range(3):
    run_fmu(path, np.arange(3) * 0.01, np.zeros((3, len(INPUTS))))
gc.collect()
md = read_model_description(path)
fmu = FMU2Slave(guid="{not-this-fmu}", unzipDirectory=extract(path, unzipped),
                modelIdentifier=md.coSimulation.modelIdentifier)
try:
    fmu.instantiate()
except Exception:
    print("refused")
"""


def test_fmpy_default_logger_still_works_after_runs_in_the_same_process(trained_fmu2, tmp_path):
    """fmpy's message proxy keeps one static pointer to a Python logger: a logger made per run and
    freed afterwards left it dangling, and the next FMU logging through fmpy's defaults crashed the
    process (fmu/fmi2_logger.py). In a child process, so that a crash is a failure, not the end."""
    result = subprocess.run([sys.executable, "-c", _FMPY_DEFAULT_LOGGER_AFTER_RUN, str(trained_fmu2),
                             str(tmp_path / "unzipped")], capture_output=True, text=True, timeout=300,
                            cwd=Path(__file__).resolve().parents[1])
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.strip().splitlines()[-1] == "refused"


def test_the_log_still_reaches_run_fmu_after_other_code_repointed_the_proxy(trained_fmu2):
    """fmpy's simulate_fmu (or any caller) points fmpy's message proxy at its own logger; run_fmu
    must point it back, or the FMU's messages (here: the invalid parameter named) go elsewhere."""
    foreign = []
    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(lambda *message: foreign.append(message))
    addLoggerProxy(ctypes.byref(callbacks))   # what simulate_fmu(..., logger=...) does
    t, raw = synthetic_recording(5)
    with pytest.raises(FmuError, match="invalid parameter: field_norm"):
        run_fmu(trained_fmu2, t, raw, parameters={"field_norm": -1.0})
    assert foreign == []


def test_start_values_in_binary_match_model_description(trained_fmu2, tmp_path):
    md = read_model_description(str(trained_fmu2))
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(trained_fmu2), tmp_path),
                    modelIdentifier=md.coSimulation.modelIdentifier)
    fmu.instantiate()
    reals = [v for v in md.modelVariables if v.start is not None and v.type == "Real"]
    got = fmu.getReal([v.valueReference for v in reals])
    thermal = fmu.getBoolean([by_name("enable_thermal").value_reference])
    fmu.freeInstance()
    assert got == [float(v.start) for v in reals]
    assert thermal == [1]


def test_fmutool_check_finds_no_problems(trained_fmu2):
    assert fmutool_problems(trained_fmu2) == []


def test_log_categories_match_the_binary():
    names = re.search(r"logCategoryNames\[MODEL_LOG_CATEGORY_COUNT\] = \{(.*?)\};",
                      (SOURCE_DIR / "ModelCore.c").read_text(), re.S).group(1)
    assert re.findall(r'"(\w+)"', names) == [name for name, _ in LOG_CATEGORIES]


def test_every_variable_has_a_description_and_reals_a_unit(trained_fmu2):
    md = read_model_description(str(trained_fmu2))
    assert md.defaultExperiment.stepSize and md.defaultExperiment.stopTime
    units = {u.name: u for u in md.unitDefinitions}
    for v in md.modelVariables:
        assert v.description, v.name
        # FMI 2 allows a unit on Real variables only; a coefficient block mixes units (contract/layout.py)
        if v.type == "Real" and not v.name.startswith(coefficient_parameters.PREFIX):
            assert v.unit in units, v.name
    assert {d.name for d in units["rad"].displayUnits} == {"deg"}
    assert {d.name for d in units["rad/s"].displayUnits} == {"deg/s"}
    assert all(by_name(n).display_unit == "deg" for n in ("roll", "pitch", "yaw", "heading"))
