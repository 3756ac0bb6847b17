"""Flat array layouts shared by Python and the C runtime (sources/ImuLayout.h).

The C runtime receives trained coefficients and settings as flat `double` arrays: the FMU from
the generated header `sources/ImuCoefficientsData.h`, the batch library through ctypes. The
orders of the input, output and settings arrays are the variable table's (contract/variables.py,
value-reference order within each causality); the coefficient blocks are defined here.
tests/test_runtime.py pins the block sizes to the C side through `ImuBatchLayout()`.
"""
from __future__ import annotations

from contract.variables import AUX_INPUTS, VARIABLES

LAYOUT_VERSION = 4

#: Runtime inputs per sample, in order (units: rad/s, m/s², µT, °C, then the auxiliary inputs).
INPUTS = tuple(v.name for v in VARIABLES if v.causality == "input")
#: Runtime outputs per sample, in order.
OUTPUTS = tuple(v.name for v in VARIABLES if v.causality == "output")
#: Settings (FMU parameters), in order, with default values.
SETTINGS = tuple((v.name, v.default) for v in VARIABLES if v.causality == "parameter")
#: Declared type, range and unit (FMI spelling) of every setting, by name (SETTINGS order):
#: contract/schema.py checks --param values and model.json against it, tests/test_value_checks.py
#: pins the C runtime's ImuPipelineSettingsCheck to it.
SETTING_RANGES = {v.name: v.range for v in VARIABLES if v.causality == "parameter"}

TRIAD_ORDER = ("gyr", "acc", "mag")
MAX_DEGREE = 3
#: One triad block: enabled, t0 [°C], ts [°C], degree, A (3x3 row-major),
#: g[axis][k-1] for k = 1..MAX_DEGREE, b[axis][k] for k = 0..MAX_DEGREE, then (layout 4) the calibrated
#: temperature range: has_range (0/1), t_min [°C], t_max [°C] (the runtime clamps T to it).
TRIAD_BLOCK = 4 + 9 + 3 * MAX_DEGREE + 3 * (MAX_DEGREE + 1) + 3
#: Components a term may correct (index = target in the terms block): the compensated triads.
TERM_TARGETS = INPUTS[:9]
#: Signals that diagnosed correction terms may use (sources/ImuTerms.h ImuTermSignal, same order):
#: compensated triads, temperature [°C], its low-passed rate [°C/s], time since the first sample [s],
#: the time derivatives of the compensated triads, their absolute values (a signed power x·|x| is
#: the product x * abs_x), the constant 1 (a term on `one` alone is an offset), the raw
#: auxiliary inputs and the temperature rate low-passed over 1 s instead of 10 s.
TERM_SIGNALS = (TERM_TARGETS + ("temp", "temp_rate", "time")
                + tuple(f"d_{name}" for name in TERM_TARGETS)
                + tuple(f"abs_{name}" for name in TERM_TARGETS)
                + ("one",) + AUX_INPUTS + ("temp_rate_fast",))
TERMS_MAX = 64
#: Terms block: [count, then TERMS_MAX x (target, signal a, signal b or -1, coefficient, lo, hi)];
#: the runtime clamps the regressor s[a]·s[b] to [lo, hi].
TERM_ENTRY = 6
TERMS_BLOCK = 1 + TERM_ENTRY * TERMS_MAX
#: Blocks of the neural stages (sources/ImuElm.h IMU_ELM_BLOCK; all zeros = disabled), in order.
STAGE_BLOCKS = {"elm": 3 + 4 * 3 + 64 * (3 + 1 + 3),   # sources/ImuElm.h IMU_ELM_BLOCK
                "psobp": 7 + 3 * (4 * 16 + 1)}         # sources/ImuPsoBp.h IMU_PSOBP_BLOCK
#: Offsets of the blocks in the coefficient array (sources/ImuLayout.h).
OFFSET_THERMAL = 1
OFFSET_TERMS = OFFSET_THERMAL + len(TRIAD_ORDER) * TRIAD_BLOCK
OFFSET_ELM = OFFSET_TERMS + TERMS_BLOCK
OFFSET_PSOBP = OFFSET_ELM + STAGE_BLOCKS["elm"]
#: Whole coefficient array: [LAYOUT_VERSION, gyr, acc, mag thermal blocks, terms, elm, psobp blocks].
N_COEFFICIENTS = OFFSET_PSOBP + STAGE_BLOCKS["psobp"]


def settings_defaults() -> dict[str, float]:
    """Default value of every setting, by name."""
    return dict(SETTINGS)


def settings_array(overrides: dict[str, float] | None = None) -> list[float]:
    """Settings as the flat array the runtime takes; unknown names raise KeyError."""
    values = settings_defaults()
    for k, v in (overrides or {}).items():
        if k not in values:
            raise KeyError(f"unknown setting '{k}' (known: {', '.join(values)})")
        values[k] = float(v)
    return [values[name] for name, _ in SETTINGS]


def identity_block() -> list[float]:
    """A triad block that changes nothing: enabled, t0=25 °C, ts=1 °C, degree 0, A=I, g=b=0, no range."""
    a = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    return [1.0, 25.0, 1.0, 0.0] + a + [0.0] * (3 * MAX_DEGREE) + [0.0] * (3 * (MAX_DEGREE + 1)) + [0.0] * 3


def terms_block(terms: list[tuple[str, str, str | None, float, float, float]]) -> list[float]:
    """Terms block from (target, signal a, signal b or None, coefficient, lo, hi) tuples, by name;
    lo and hi [unit of s[a]·s[b]] bound the regressor (the runtime rejects lo > hi or non-finite)."""
    if len(terms) > TERMS_MAX:
        raise ValueError(f"{len(terms)} correction terms, at most {TERMS_MAX} fit in the runtime")
    block = [float(len(terms))]
    for target, a, b, coefficient, lo, hi in terms:
        block += [float(TERM_TARGETS.index(target)), float(TERM_SIGNALS.index(a)),
                  -1.0 if b is None else float(TERM_SIGNALS.index(b)), float(coefficient),
                  float(lo), float(hi)]
    return block + [0.0] * (TERMS_BLOCK - len(block))


def pack_coefficients(thermal_blocks: list[list[float]], terms: list[float] | None = None,
                      **stages: list[float]) -> list[float]:
    """The whole coefficient array from the gyr, acc, mag thermal blocks, a terms block and the
    neural stage blocks by name (STAGE_BLOCKS; an absent stage is disabled: all zeros)."""
    if len(thermal_blocks) != len(TRIAD_ORDER) or any(len(b) != TRIAD_BLOCK for b in thermal_blocks):
        raise ValueError(f"expected {len(TRIAD_ORDER)} thermal blocks of {TRIAD_BLOCK} values")
    terms = terms_block([]) if terms is None else list(terms)
    if len(terms) != TERMS_BLOCK:
        raise ValueError(f"terms block has {len(terms)} values, expected {TERMS_BLOCK}")
    values = [float(LAYOUT_VERSION)] + [float(v) for b in thermal_blocks for v in b] + terms
    for name in stages.keys() - STAGE_BLOCKS.keys():
        raise ValueError(f"unknown stage block '{name}' (known: {', '.join(STAGE_BLOCKS)})")
    for name, size in STAGE_BLOCKS.items():
        block = [float(v) for v in stages.get(name, [0.0] * size)]
        if len(block) != size:
            raise ValueError(f"{name} block has {len(block)} values, expected {size}")
        values += block
    return values


def identity_coefficients() -> list[float]:
    """The whole coefficient array of an untrained model (every stage is the identity)."""
    return pack_coefficients([identity_block()] * len(TRIAD_ORDER))
