"""A calibration as a file: the trained model's FMU parameter values in an SSP parameter-value file
(SSV, fmu/ssv.py), so that one FMU serves every unit (issue 32).

`calibration.ssv` holds every FMU parameter `train` sets — the settings (contract/variables.py, with their
units) and the coefficient blocks (contract/coefficient_parameters.py, FMI 2 names `calibration.<block>[k]`;
fmu.ssv.read_ssv reads a block back as the list an FMI 3 array parameter takes) — and, as an annotation
of type AUX_ANNOTATION, which recording column each auxiliary input carries (the FMU's own map,
extra/imufusion/aux_inputs.json, is the build's; a unit's correction terms may use other columns).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from lxml import etree

from contract import coefficient_parameters as cp
from contract.errors import DataError
from contract.layout import SETTINGS
from contract.variables import by_name
from fmu.ssv import UNITS, SsvParameter, read_annotation, read_ssv, ssv_document, write_ssv

#: File name `train` writes beside model.json.
FILE_NAME = "calibration.ssv"
#: SSP annotation type of the auxiliary-input map (reverse domain name, SSP 1.0 "Annotations").
AUX_ANNOTATION = "org.imufusion.aux-inputs"
_AUX_NAMESPACE = "https://github.com/imufusion/ssv-aux-inputs"


def _setting_parameter(name: str, value: float) -> SsvParameter:
    """A setting as its declared type, with its unit where SSP can declare it (rad/s/sqrt(Hz) it cannot)."""
    variable = by_name(name)
    if variable.type == "Boolean":
        return SsvParameter(name, bool(value), description=variable.description)
    if variable.type == "Integer":
        return SsvParameter(name, int(value), description=variable.description)
    unit = variable.unit or "1"
    return SsvParameter(name, float(value), unit if unit in UNITS else None, variable.description)


def _aux_element(aux_inputs) -> etree._Element:
    """<aux:Inputs> with one <aux:Input slot column unit meaning/> per mapped auxiliary input, aux_1 first."""
    root = etree.Element(f"{{{_AUX_NAMESPACE}}}Inputs", nsmap={"aux": _AUX_NAMESPACE})
    for k, entry in enumerate(aux_inputs, start=1):
        etree.SubElement(root, f"{{{_AUX_NAMESPACE}}}Input", slot=f"aux_{k}", column=str(entry["column"]),
                         unit=str(entry.get("unit", "")), meaning=str(entry.get("meaning", "")))
    return root


def _parameters(coefficients, settings: dict[str, float]) -> list[SsvParameter]:
    """Every setting (by name; a missing one at its default) and every coefficient block as SSV parameters."""
    parameters = [_setting_parameter(key, settings.get(key, default)) for key, default in SETTINGS]
    blocks = cp.block_values(coefficients)
    return parameters + [SsvParameter(b.parameter, blocks[b.parameter], description=b.description) for b in cp.BLOCKS]


def calibration_document(coefficients, settings: dict[str, float], aux_inputs=(), name: str = "calibration",
                         description: str | None = None) -> bytes:
    """The SSV file's bytes: the whole coefficient array, the settings and the auxiliary-input map."""
    return ssv_document(_parameters(coefficients, settings), name, description,
                        annotations={AUX_ANNOTATION: _aux_element(aux_inputs)})


def write_calibration(path, coefficients, settings: dict[str, float], aux_inputs=(), name: str = "calibration",
                      description: str | None = None) -> Path:
    """Write the whole coefficient array, the settings (every one, by name) and the auxiliary-input map as
    the SSV file `path` (checked against the standard's XSD first); returns the path."""
    return write_ssv(path, _parameters(coefficients, settings), name, description,
                     annotations={AUX_ANNOTATION: _aux_element(aux_inputs)})


def read_calibration(path) -> tuple[np.ndarray, dict[str, float], list[dict]]:
    """(the whole coefficient array, the settings it holds by name, the auxiliary-input map) of the SSV file
    `path`. A setting it does not hold keeps the FMU's start value; every coefficient block must be there
    with its length. DataError naming the file and the parameter otherwise."""
    path = Path(path)
    values = read_ssv(path)
    elements = {cp.scalar_name(b, k): b for b in cp.BLOCKS for k in range(b.size)}
    known = {name for name, _ in SETTINGS} | {b.parameter for b in cp.BLOCKS} | set(elements)
    unknown = [name for name in values if name not in known]
    if unknown:
        raise DataError(path, f"parameter '{unknown[0]}' is not an ImuFusion FMU parameter")
    coefficients = np.empty(sum(b.size for b in cp.BLOCKS))
    for block in cp.BLOCKS:
        value = values.get(block.parameter)
        if not isinstance(value, list) or len(value) != block.size:
            raise DataError(path, f"coefficient block '{block.parameter}': {_shortfall(block, values)}, the FMU's "
                                  f"layout has {block.size} (a calibration.ssv of another imufmu version? retrain)")
        coefficients[block.offset:block.offset + block.size] = value
    settings = {name: float(values[name]) for name, _ in SETTINGS if name in values}
    return coefficients, settings, _aux_inputs(path)


def start_values(coefficients, settings: dict[str, float], fmi_version: int) -> dict[str, float | int | bool | list]:
    """The start values an importer sets for a unit (`fmpy.simulate_fmu(..., start_values=...)`): every
    setting as its declared type and the coefficient parameters of FMI `fmi_version` (2: a scalar per
    coefficient, 3: a list per block)."""
    typed = {}
    for name, value in settings.items():
        kind = by_name(name).type
        typed[name] = bool(value) if kind == "Boolean" else int(value) if kind == "Integer" else float(value)
    return typed | cp.parameter_values(coefficients, fmi_version)


def _shortfall(block: cp.CoefficientBlock, values: dict) -> str:
    """What a block lacks in the values read: its elements that are missing, or how many values it has."""
    value = values.get(block.parameter)
    if isinstance(value, list):
        return f"{len(value)} value(s)"
    missing = [k + 1 for k in range(block.size) if cp.scalar_name(block, k) not in values]
    if len(missing) == block.size:
        return "missing"
    return f"element(s) {', '.join(map(str, missing[:5]))}{' ...' if len(missing) > 5 else ''} missing"


def _aux_inputs(path: Path) -> list[dict]:
    element = read_annotation(path, AUX_ANNOTATION)
    if element is None:
        return []
    return [{"column": e.get("column"), "unit": e.get("unit", ""), "meaning": e.get("meaning", "")}
            for e in element.iterfind(f"{{{_AUX_NAMESPACE}}}Input")]
