"""The trained coefficients are FMU parameters (issue 32, contract/coefficient_parameters.py): one FMU
for every unit. An FMU built without a calibration (identity coefficients) with a unit's coefficients
and settings set before initialisation gives the outputs of the FMU that unit's calibration was compiled
into, bit for bit, in FMI 2 (one Real per coefficient) and FMI 3 (one Float64 array per block); a set
that does not fit the layout is refused at initialisation naming its block; the coefficients are fixed
once initialised."""
from __future__ import annotations

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException

from contract import coefficient_parameters as cp
from contract.layout import N_COEFFICIENTS, OFFSET_THERMAL, identity_coefficients
from fmu.cosim import FmuError, initialised_fmu, run_fmu
from fmu_cases import TRAINED_SETTINGS, synthetic_recording, trained_coefficients


def test_the_blocks_cover_the_coefficient_array_in_order():
    end = 0
    for block in cp.BLOCKS:
        assert block.offset == end, block.name
        end += block.size
    assert end == N_COEFFICIENTS
    values = cp.block_values(np.arange(N_COEFFICIENTS, dtype=float))
    assert np.concatenate(list(values.values())).tolist() == list(range(N_COEFFICIENTS))
    assert list(cp.scalar_values(np.arange(N_COEFFICIENTS, dtype=float)).values()) == list(range(N_COEFFICIENTS))


def test_a_generic_fmu_with_a_units_coefficients_is_that_units_fmu(identity_fmu, trained_fmu):
    t, raw = synthetic_recording(400)
    compiled = run_fmu(trained_fmu, t, raw)
    generic = run_fmu(identity_fmu, t, raw, parameters=TRAINED_SETTINGS, coefficients=trained_coefficients())
    np.testing.assert_array_equal(generic, compiled)
    assert not np.array_equal(run_fmu(identity_fmu, t, raw, parameters=TRAINED_SETTINGS), compiled)


def test_the_start_values_are_the_compiled_in_coefficients(trained_fmu, fmi_version):
    with initialised_fmu(trained_fmu) as fmu:
        refs = fmu.value_references
        expected = cp.parameter_values(trained_coefficients(), fmi_version)
        if fmi_version == 3:
            got = {name: list(fmu.getFloat64([refs[name]], nValues=len(v))) for name, v in expected.items()}
        else:
            got = dict(zip(expected, fmu.getReal([refs[name] for name in expected])))
    assert got == expected


def _bad(block_name: str, index: int, value: float) -> np.ndarray:
    coefficients = np.array(identity_coefficients())
    block = next(b for b in cp.BLOCKS if b.name == block_name)
    coefficients[block.offset + index] = value
    return coefficients


@pytest.mark.parametrize("block, index, value", [("layout_version", 0, 3.0), ("thermal_acc", 3, 7.0),
                                                 ("terms", 0, 65.0)])
def test_a_set_that_does_not_fit_is_refused_naming_its_block(identity_fmu, block, index, value):
    t, raw = synthetic_recording(10)
    with pytest.raises(FmuError, match=f"calibration.{block}"):
        run_fmu(identity_fmu, t, raw, coefficients=_bad(block, index, value))


def test_the_coefficients_are_fixed_once_initialised(identity_fmu, fmi_version):
    block = cp.BLOCKS[1]
    with initialised_fmu(identity_fmu) as fmu:
        vr = fmu.value_references[block.parameter if fmi_version == 3 else cp.scalar_name(block, 1)]
        with pytest.raises(FMICallException):
            if fmi_version == 3:
                fmu.setFloat64([vr], [0.0] * block.size)
            else:
                fmu.setReal([vr], [30.0])
        assert any("fixed after initialisation" in m for m in fmu.log_messages)


def test_fmi3_counts_the_values_an_array_parameter_carries(identity_fmu3):
    block = cp.BLOCKS[1]
    with initialised_fmu(identity_fmu3) as fmu:
        vr = fmu.value_references[block.parameter]
        with pytest.raises(FMICallException):
            fmu.getFloat64([vr])  # one value for a block of 37
        assert any(f"the {block.size} values the value references carry" in m for m in fmu.log_messages)
        # FMI 2's scalar coefficient references are not FMI 3 variables
        with pytest.raises(FMICallException):
            fmu.getFloat64([cp.FMI2_COEFFICIENT_VR + OFFSET_THERMAL])
