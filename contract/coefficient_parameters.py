"""The trained coefficients as FMU parameters: one parameter per coefficient block (issue 32).

The coefficient array the runtime takes (contract/layout.py: layout version, the thermal blocks of
gyr, acc and mag, the correction terms, the ELM and the PSO-BP blocks) is exposed block by block:

- FMI 3: one Float64 array parameter per block, `calibration.<block>` with the block's length as its
  dimension, value reference FMI3_BLOCK_VR + block index;
- FMI 2 (no arrays): one Real parameter per coefficient, `calibration.<block>[k]` (k = 1..length, the
  bracket notation of FMI 2's structured naming for an array element), value reference
  FMI2_COEFFICIENT_VR + its index in the whole array.

Their start values are the coefficients the FMU was built with (its compiled-in
sources/ImuCoefficientsData.h), so a built FMU runs out of the box with its calibration; an importer
sets other values before initialisation (fmi2SetReal / fmi3SetFloat64 in Instantiated or
Initialization Mode) and the runtime checks the whole array at initialisation, naming the block that
does not fit (sources/ImuRuntime.c). The value references are outside the variable table's range and
below the FMI 3 time's (contract/variables.py, sources/config.h VR_TIME).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from contract.layout import (N_COEFFICIENTS, OFFSET_ELM, OFFSET_PSOBP, OFFSET_TERMS, OFFSET_THERMAL, STAGE_BLOCKS,
                             TERMS_BLOCK, TRIAD_BLOCK, TRIAD_ORDER)

#: Value reference of the first coefficient's FMI 2 scalar parameter (the others follow in array order).
FMI2_COEFFICIENT_VR = 100000
#: Value reference of the first block's FMI 3 array parameter (the others follow in block order).
FMI3_BLOCK_VR = 200000
#: Prefix of every coefficient parameter's name.
PREFIX = "calibration."
_TRIADS = {"gyr": "gyroscope", "acc": "accelerometer", "mag": "magnetometer"}


@dataclass(frozen=True)
class CoefficientBlock:
    """One block of the coefficient array: its parameter name (without PREFIX), first index, length and what it holds."""

    name: str
    offset: int
    size: int
    description: str

    @property
    def parameter(self) -> str:
        return PREFIX + self.name


#: The blocks in array order; together they cover the whole array (tests/test_coefficient_parameters.py).
BLOCKS: tuple[CoefficientBlock, ...] = (
    (CoefficientBlock("layout_version", 0, 1, "Coefficient layout version the parameter set was written for "
                                              "(must equal the FMU's)"),)
    + tuple(CoefficientBlock(f"thermal_{t}", OFFSET_THERMAL + k * TRIAD_BLOCK, TRIAD_BLOCK,
                             f"Gain/bias(T) model of the {_TRIADS[t]}: enabled, t0 [degC], ts [degC], degree, "
                             "A (3x3 row-major), gain and bias polynomial coefficients, calibrated temperature range")
            for k, t in enumerate(TRIAD_ORDER))
    + (CoefficientBlock("terms", OFFSET_TERMS, TERMS_BLOCK, "Correction terms: count, then (target, signal a, "
                                                            "signal b, coefficient, lo, hi) per term"),
       CoefficientBlock("elm", OFFSET_ELM, STAGE_BLOCKS["elm"], "Extreme learning machine of the magnetometer "
                                                                "(all zeros: disabled)"),
       CoefficientBlock("psobp", OFFSET_PSOBP, STAGE_BLOCKS["psobp"], "PSO-BP gyro bias network (all zeros: disabled)"))
)
assert BLOCKS[-1].offset + BLOCKS[-1].size == N_COEFFICIENTS


def problem_text(block: CoefficientBlock) -> str:
    """The runtime's message when a block does not fit the layout (sources/ImuRuntime.c)."""
    if block.name == "layout_version":
        return f"{block.parameter} is not this FMU's coefficient layout version"
    return (f"{block.parameter} does not fit the coefficient layout (a flag, degree, count, index or range "
            "outside what the block allows, or a value it uses not finite)")


def scalar_name(block: CoefficientBlock, k: int) -> str:
    """FMI 2 name of element k (0-based) of a block: calibration.<block>[k + 1]."""
    return f"{block.parameter}[{k + 1}]"


def block_values(coefficients) -> dict[str, list[float]]:
    """FMI 3 parameter name -> the block's values, from the whole coefficient array."""
    a = _whole(coefficients)
    return {b.parameter: a[b.offset:b.offset + b.size].tolist() for b in BLOCKS}


def scalar_values(coefficients) -> dict[str, float]:
    """FMI 2 parameter name -> value, from the whole coefficient array (array order)."""
    a = _whole(coefficients)
    return {scalar_name(b, k): float(a[b.offset + k]) for b in BLOCKS for k in range(b.size)}


def parameter_values(coefficients, fmi_version: int) -> dict[str, float | list[float]]:
    """The coefficient parameters' values for an FMU of `fmi_version` (2: scalars, 3: arrays)."""
    return scalar_values(coefficients) if fmi_version == 2 else block_values(coefficients)


def _whole(coefficients) -> np.ndarray:
    a = np.asarray(coefficients, dtype=np.float64).ravel()
    if a.size != N_COEFFICIENTS:
        raise ValueError(f"{a.size} coefficients, the layout has {N_COEFFICIENTS}")
    return a
