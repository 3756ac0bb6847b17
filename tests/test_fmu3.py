"""The ImuFusion FMI 3.0 FMU (validity and exports: tests/test_fmu.py): golden outputs, FMU state across processes, instances."""
from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.model_description import read_build_description

from contract import coefficient_parameters
from contract.variables import VARIABLES
from fmu.build_description import BUILD_DESCRIPTION
from fmu.compiler import fmu_source_files
from fmu.cosim import Stepper, initialised_fmu, run_fmu, step_samples, step_sizes
from fmu.model_description import FMI3_TYPES, LOG_CATEGORIES, TIME_VALUE_REFERENCE
from fmu_cases import GOLDEN_TOLERANCE, TRAINED_SETTINGS, synthetic_recording, trained_coefficients
from contract.layout import settings_array
from training.runtime import run_batch


@pytest.fixture(scope="module")
def recording():
    """(t, raw, h): a 300-sample recording with variable steps, a gap and NaN temperatures."""
    t, raw = synthetic_recording(300)
    return t, raw, step_sizes(t, 0.01)


def test_build_description_lists_the_fmi3_sources(trained_fmu3):
    with zipfile.ZipFile(trained_fmu3) as zf:
        assert BUILD_DESCRIPTION in zf.namelist()
    configuration = read_build_description(str(trained_fmu3))[0]
    assert configuration.modelIdentifier == "ImuFusion"
    files = configuration.sourceFileSets[0].sourceFiles
    assert sorted(files) == sorted(p.name for p in fmu_source_files(fmi_version=3) if p.suffix == ".c")
    assert "fmi3Functions.c" in files and "fmi2Functions.c" not in files


def test_model_description_follows_the_table(trained_fmu3):
    md = read_model_description(str(trained_fmu3))
    assert md.fmiVersion == "3.0"
    cs = md.coSimulation
    assert cs.canHandleVariableCommunicationStepSize and cs.canGetAndSetFMUstate and cs.canSerializeFMUstate
    got = {v.name: (v.valueReference, v.causality, v.type) for v in md.modelVariables
           if not v.name.startswith(coefficient_parameters.PREFIX)}
    expected = {v.name: (v.value_reference, v.causality, FMI3_TYPES[v.type]) for v in VARIABLES}
    assert got == {**expected, "time": (TIME_VALUE_REFERENCE, "independent", "Float64")}
    # the coefficient parameters: one Float64 array per block, its start the block compiled in
    arrays = {v.name: (v.valueReference, [d.start for d in v.dimensions], [float(x) for x in v.start.split()])
              for v in md.modelVariables if v.name.startswith(coefficient_parameters.PREFIX)}
    blocks = coefficient_parameters.block_values(trained_coefficients())
    assert arrays == {name: (coefficient_parameters.FMI3_BLOCK_VR + k, [len(values)], values)
                      for k, (name, values) in enumerate(blocks.items())}
    assert [c.name for c in md.logCategories] == [name for name, _ in LOG_CATEGORIES]
    assert all(v.description for v in md.modelVariables)


def test_fmu_equals_batch_runtime(trained_fmu3, recording):
    t, raw, _ = recording
    fmu_out = run_fmu(trained_fmu3, t, raw)
    batch_out = run_batch(trained_coefficients(), settings_array(TRAINED_SETTINGS), t, raw)
    np.testing.assert_allclose(fmu_out, batch_out, rtol=0, atol=GOLDEN_TOLERANCE)
    assert np.all(np.isfinite(fmu_out))


@pytest.mark.parametrize("split", [0, 1, 75, 150, 151, 299])
def test_state_restore_at_any_step_is_bit_identical(trained_fmu3, recording, split):
    t, raw, h = recording
    uninterrupted = run_fmu(trained_fmu3, t, raw, parameters=TRAINED_SETTINGS)
    with initialised_fmu(trained_fmu3, t[0], TRAINED_SETTINGS) as fmu:
        head = step_samples(fmu, t[:split], raw[:split], h[:split])
        state = fmu.getFMUState()
        first = step_samples(fmu, t[split:], raw[split:], h[split:])
        fmu.setFMUState(state)
        second = step_samples(fmu, t[split:], raw[split:], h[split:])
        fmu.freeFMUState(state)
    np.testing.assert_array_equal(np.vstack([head, first]), uninterrupted)
    np.testing.assert_array_equal(second, first)


#: Run in a fresh interpreter: restore a serialized state from a file, continue, save the outputs.
_RESTORE_SCRIPT = """
import sys
import numpy as np
from fmu.cosim import initialised_fmu, step_samples
fmu_path, state_path, data_path, out_path = sys.argv[1:]
data = np.load(data_path)
with initialised_fmu(fmu_path, 0.0) as fmu:
    restored = fmu.deserializeFMUState(open(state_path, "rb").read())
    fmu.setFMUState(restored)
    fmu.freeFMUState(restored)
    np.save(out_path, step_samples(fmu, data["t"], data["raw"], data["h"]))
"""


def test_serialized_state_restores_in_another_process(trained_fmu3, recording, tmp_path):
    t, raw, h = recording
    split = 170
    uninterrupted = run_fmu(trained_fmu3, t, raw, parameters=TRAINED_SETTINGS)
    with initialised_fmu(trained_fmu3, t[0], TRAINED_SETTINGS) as fmu:
        step_samples(fmu, t[:split], raw[:split], h[:split])
        state = fmu.getFMUState()
        (tmp_path / "state.bin").write_bytes(bytes(fmu.serializeFMUState(state)))
        fmu.freeFMUState(state)
    np.savez(tmp_path / "data.npz", t=t[split:], raw=raw[split:], h=h[split:])
    subprocess.run([sys.executable, "-c", _RESTORE_SCRIPT, str(trained_fmu3), str(tmp_path / "state.bin"),
                    str(tmp_path / "data.npz"), str(tmp_path / "out.npy")], check=True, cwd=Path(__file__).parent.parent)
    np.testing.assert_array_equal(np.load(tmp_path / "out.npy"), uninterrupted[split:])


def test_interleaved_instances_equal_each_alone(trained_fmu3, recording):
    t, raw, h = recording
    other = raw.copy()
    other[:, 6:9] *= 1.1  # a different field for the second instance
    alone_a = run_fmu(trained_fmu3, t, raw, parameters=TRAINED_SETTINGS)
    alone_b = run_fmu(trained_fmu3, t, other, parameters={"declination": -0.2})
    together_a, together_b = np.empty_like(alone_a), np.empty_like(alone_b)
    with initialised_fmu(trained_fmu3, t[0], TRAINED_SETTINGS, instance_name="a") as a, \
            initialised_fmu(trained_fmu3, t[0], {"declination": -0.2}, instance_name="b") as b:
        sa, sb = Stepper(a), Stepper(b)
        for k in range(len(t)):
            sa.set_inputs(raw[k])
            sb.set_inputs(other[k])
            sb.do_step(t[k], h[k])
            sa.do_step(t[k], h[k])
            together_a[k], together_b[k] = sa.get_outputs(), sb.get_outputs()
    np.testing.assert_array_equal(together_a, alone_a)
    np.testing.assert_array_equal(together_b, alone_b)
    assert not np.array_equal(alone_a, alone_b)


def test_reset_returns_to_the_initial_state(trained_fmu3, recording):
    t, raw, h = recording
    with initialised_fmu(trained_fmu3, t[0], TRAINED_SETTINGS) as fmu:
        first = step_samples(fmu, t, raw, h)
        fmu.reset()
        fmu.enterInitializationMode(startTime=t[0])
        fmu.exitInitializationMode()
        second = step_samples(fmu, t, raw, h)
    np.testing.assert_array_equal(first, second)
