"""modelDescription.xml (FMI 2.0 and FMI 3.0 co-simulation, source FMU) generated from the variable table."""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from xml.sax.saxutils import quoteattr

from fmu.compiler import check_fmi_version, fmu_source_files
from fmu.provenance import generation_tool
from contract import coefficient_parameters as cp
from contract.variables import Variable, variable_table
from contract.layout import identity_coefficients, settings_defaults

MODEL_NAME = "ImuFusion"

#: Default experiment: 10 s at 100 Hz; the step follows the sensor's rate where the calibration data give it
#: (`default_experiment`).
DEFAULT_EXPERIMENT = {"startTime": 0.0, "stopTime": 10.0, "stepSize": 0.01}


def default_experiment(training_data: Sequence[dict] = ()) -> dict:
    """DEFAULT_EXPERIMENT with the step of the sensor's rate: 1 / the median `rate_hz` [Hz] of the calibration
    recordings (ModelArtefact.training_data; the FMU consumes one sample per step), when any gives one."""
    rates = [float(d["rate_hz"]) for d in training_data if isinstance(d.get("rate_hz"), (int, float))
             and math.isfinite(d["rate_hz"]) and d["rate_hz"] > 0]
    return {**DEFAULT_EXPERIMENT, "stepSize": 1.0 / float(np.median(rates))} if rates else dict(DEFAULT_EXPERIMENT)

#: Log categories, in the order of the ModelLogCategory enum of sources/model.h.
LOG_CATEGORIES = (
    ("logEvents", "Instantiation, initialisation and other life-cycle events"),
    ("logBadInput", "Bad input (not finite, saturated, out of range, bad step size): one Warning when an "
                    "episode starts (the FMU holds its last valid estimate), one OK message when it ends"),
    ("logStatusWarning", "Other calls that return a Warning"),
    ("logStatusError", "Calls that return an Error, with the reason"),
)

#: Value reference of the FMI 3 independent variable "time" (VR_TIME in sources/config.h).
TIME_VALUE_REFERENCE = 1000000
_TIME_XML = (f'    <Float64 name="time" valueReference="{TIME_VALUE_REFERENCE}" causality="independent" '
             'variability="continuous" description="Simulation time (communication point)" unit="s"/>')

#: FMI 3 type element of each variable-table type.
FMI3_TYPES = {"Real": "Float64", "Boolean": "Boolean", "Integer": "Int32"}

_DEG = f'<DisplayUnit name="deg" factor="{180.0 / math.pi!r}"/>'
_DEG_S = f'<DisplayUnit name="deg/s" factor="{180.0 / math.pi!r}"/>'

#: Unit definitions: name -> inner XML (BaseUnit and display units). FMI 2.0 base-unit exponents
#: are integers, so rad/s/sqrt(Hz) = rad*s^(-1/2) and the other noise units have no BaseUnit. A
#: model description declares those its variables use (`_shared_sections`).
UNITS = {
    "1": "<BaseUnit/>",
    "rad": f'<BaseUnit rad="1"/>{_DEG}',
    "rad/s": f'<BaseUnit rad="1" s="-1"/>{_DEG_S}',
    "rad/s/sqrt(Hz)": "",
    "rad/s/sqrt(s)": "",
    "m/s2/sqrt(Hz)": "",
    "m/s2/sqrt(s)": "",
    "uT/sqrt(Hz)": "",
    "uT/sqrt(s)": "",
    "m/s2": '<BaseUnit m="1" s="-2"/>',
    "uT": '<BaseUnit kg="1" A="-1" s="-2" factor="1e-06"/>',
    "degC": '<BaseUnit K="1" offset="273.15"/>',
    "s": '<BaseUnit s="1"/>',
    "1/s": '<BaseUnit s="-1"/>',
}


def _start_text(variable: Variable, value: float | bool) -> str:
    """XML text of a start value (xs:double round-trip repr, an integer, or true/false)."""
    if variable.type == "Boolean":
        return "true" if value else "false"
    if variable.type == "Integer":
        return str(int(value))
    return repr(float(value))


def _start(variable: Variable, settings: dict) -> float | bool | None:
    """Start value of a variable: parameters from `settings`, the others from the table."""
    return settings[variable.name] if variable.causality == "parameter" else variable.start


def _common_attributes(variable: Variable) -> list[str]:
    """name, valueReference, description, causality, variability (and initial for parameters)."""
    attributes = [f"name={quoteattr(variable.name)}", f'valueReference="{variable.value_reference}"',
                  f"description={quoteattr(variable.description)}", f'causality="{variable.causality}"',
                  f'variability="{variable.variability}"']
    if variable.causality == "parameter":
        attributes.append('initial="exact"')
    return attributes


def _range_attributes(variable: Variable) -> list[str]:
    """min and max of a Real or Integer with a declared range (contract.layout.SETTING_RANGES,
    inclusive in FMI; an open bound is refused by the FMU at initialisation)."""
    if variable.type == "Boolean":
        return []
    return [f'{key}="{_start_text(variable, value)}"'
            for key, value in (("min", variable.min), ("max", variable.max)) if value is not None]


def _unit_attributes(variable: Variable, start) -> list[str]:
    """unit, displayUnit, min, max and start attributes (those that apply)."""
    attributes = []
    if variable.type == "Real":  # a Real without a unit in the table is dimensionless; integers carry none
        attributes.append(f"unit={quoteattr(variable.unit or '1')}")
    if variable.display_unit is not None:
        attributes.append(f"displayUnit={quoteattr(variable.display_unit)}")
    attributes += _range_attributes(variable)
    if start is not None:
        attributes.append(f'start="{_start_text(variable, start)}"')
    return attributes


def _variable_xml3(variable: Variable, settings: dict) -> str:
    """One FMI 3 variable element (Float64, Boolean or Int32)."""
    attributes = _common_attributes(variable) + _unit_attributes(variable, _start(variable, settings))
    return f'    <{FMI3_TYPES[variable.type]} {" ".join(attributes)}/>'


def _variable_xml(variable: Variable, settings: dict) -> str:
    """One ScalarVariable element; parameter start values come from `settings`."""
    attributes = _common_attributes(variable)
    type_attributes = _unit_attributes(variable, _start(variable, settings))
    return (f'    <ScalarVariable {" ".join(attributes)}>\n'
            f'      <{variable.type} {" ".join(type_attributes)}/>\n'
            f'    </ScalarVariable>')


def _coefficient_xml(coefficients, fmi_version: int) -> list[str]:
    """The coefficient parameters (contract/coefficient_parameters.py) with the built coefficients as start
    values: FMI 3 one Float64 array per block, FMI 2 one Real per coefficient. Their units differ within a
    block (contract/layout.py), so they declare none."""
    values = [float(v) for v in coefficients]
    head = 'causality="parameter" variability="fixed" initial="exact"'
    if fmi_version == 3:
        return [f'    <Float64 name={quoteattr(b.parameter)} valueReference="{cp.FMI3_BLOCK_VR + k}" '
                f'description={quoteattr(b.description)} {head} '
                f'start="{" ".join(repr(v) for v in values[b.offset:b.offset + b.size])}">\n'
                f'      <Dimension start="{b.size}"/>\n    </Float64>'
                for k, b in enumerate(cp.BLOCKS)]
    return [f'    <ScalarVariable name={quoteattr(cp.scalar_name(b, j))} valueReference="{cp.FMI2_COEFFICIENT_VR + b.offset + j}" '
            f'description={quoteattr(f"{b.description}: element {j + 1} of {b.size}")} {head}>\n'
            f'      <Real start="{values[b.offset + j]!r}"/>\n    </ScalarVariable>'
            for b in cp.BLOCKS for j in range(b.size)]


def _initial_dependencies(variable: Variable, variables: tuple[Variable, ...]) -> list[Variable]:
    """What an output depends on before the first sample: heading = declination, the rest constant."""
    return [v for v in variables if v.name == "declination"] if variable.name == "heading" else []


def _model_structure_xml(fmi_version: int, variables: tuple[Variable, ...]) -> str:
    """Outputs (no direct feedthrough in co-simulation) and InitialUnknowns (every output).

    FMI 2 refers to variables by their 1-based index, FMI 3 by value reference.
    """
    index = {v.name: i + 1 for i, v in enumerate(variables)}
    outputs = [v for v in variables if v.causality == "output"]
    if fmi_version == 3:
        lines = ["  <ModelStructure>"]
        lines += [f'    <Output valueReference="{v.value_reference}" dependencies=""/>' for v in outputs]
        for v in outputs:
            dependencies = " ".join(str(d.value_reference) for d in _initial_dependencies(v, variables))
            lines.append(f'    <InitialUnknown valueReference="{v.value_reference}" dependencies="{dependencies}"/>')
        return "\n".join(lines + ["  </ModelStructure>"])
    lines = ["  <ModelStructure>", "    <Outputs>"]
    lines += [f'      <Unknown index="{index[v.name]}" dependencies=""/>' for v in outputs]
    lines += ["    </Outputs>", "    <InitialUnknowns>"]
    for v in outputs:
        dependencies = " ".join(str(index[d.name]) for d in _initial_dependencies(v, variables))
        lines.append(f'      <Unknown index="{index[v.name]}" dependencies="{dependencies}"/>')
    lines += ["    </InitialUnknowns>", "  </ModelStructure>"]
    return "\n".join(lines)


def _settings_values(settings: dict) -> dict:
    """Every setting by name: contract.layout defaults overridden by `settings`; KeyError for unknown names."""
    values = settings_defaults()
    for name, value in settings.items():
        if name not in values:
            raise KeyError(f"unknown setting '{name}' (known: {', '.join(values)})")
        values[name] = value
    return values


def _shared_sections(table: tuple[Variable, ...], experiment: dict) -> str:
    """UnitDefinitions (those of `table`'s Reals, "1" and "s"), LogCategories and DefaultExperiment (the same in FMI 2
    and FMI 3)."""
    used = {"1", "s"} | {v.unit for v in table if v.type == "Real" and v.unit}  # "s": FMI 3 time
    units = "\n".join(f"    <Unit name={quoteattr(name)}>{inner}</Unit>" if inner else f"    <Unit name={quoteattr(name)}/>"
                      for name, inner in UNITS.items() if name in used)
    categories = "\n".join(f"    <Category name={quoteattr(n)} description={quoteattr(d)}/>" for n, d in LOG_CATEGORIES)
    experiment = " ".join(f'{k}="{v!r}"' for k, v in experiment.items())
    return f"""  <UnitDefinitions>
{units}
  </UnitDefinitions>
  <LogCategories>
{categories}
  </LogCategories>
  <DefaultExperiment {experiment}/>"""


def _generation_attributes(built: str | None) -> str:
    """generationTool (our distribution and version) and, when known, generationDateAndTime
    (xs:dateTime, UTC): attribute lines of fmiModelDescription, the same in FMI 2 and FMI 3."""
    lines = [f"  generationTool={quoteattr(generation_tool())}"]
    if built is not None:
        lines.append(f"  generationDateAndTime={quoteattr(built)}")
    return "\n".join(lines)


def _fmi3_xml(values: dict, guid: str, description: str, table: tuple[Variable, ...], built: str | None,
              extra: list[str], experiment: dict, model_name: str) -> str:
    """Text of an FMI 3.0 modelDescription.xml (sources are listed in buildDescription.xml); `extra`: variable
    elements after the table's (the coefficient parameters)."""
    variables = "\n".join([_TIME_XML] + [_variable_xml3(v, values) for v in table] + extra)
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription
  fmiVersion="3.0"
  modelName="{model_name}"
  instantiationToken={quoteattr(guid)}
  description={quoteattr(description)}
{_generation_attributes(built)}
  variableNamingConvention="flat">
  <CoSimulation
    modelIdentifier="{model_name}"
    canHandleVariableCommunicationStepSize="true"
    maxOutputDerivativeOrder="0"
    canGetAndSetFMUState="true"
    canSerializeFMUState="true"
    providesDirectionalDerivatives="false"
    providesAdjointDerivatives="false"
    hasEventMode="false"/>
{_shared_sections(table, experiment)}
  <ModelVariables>
{variables}
  </ModelVariables>
{_model_structure_xml(3, table)}
</fmiModelDescription>
"""


def model_description_xml(settings: dict, guid: str, description: str,
                          source_files: list[str] | None = None, fmi_version: int = 2,
                          aux_inputs: Sequence[dict] = (), built: str | None = None, coefficients=None,
                          training_data: Sequence[dict] = ()) -> str:
    """Text of modelDescription.xml for FMI `fmi_version` (2 or 3).

    settings: parameter start values by name (missing names take contract.layout defaults);
    guid: the GUID (FMI 3: instantiation token) also compiled into the binary; description: the
    model's one-line description; source_files: the .c files to list under SourceFiles (FMI 2
    only; default: those of fmu.compiler; FMI 3 lists them in buildDescription.xml); aux_inputs:
    the model's ModelArtefact.aux_inputs, which describe the auxiliary inputs; built: the build
    time for generationDateAndTime (fmu.provenance.build_time; None: the attribute is left out);
    coefficients: the coefficient array compiled in, the coefficient parameters' start values (None: the
    untrained model's, contract.layout.identity_coefficients); training_data: the model's
    ModelArtefact.training_data, whose sample rates set the default experiment's step (`default_experiment`).
    Raises KeyError for an unknown setting name, BuildError for another FMI version.
    """
    values = _settings_values(settings)
    table = variable_table(aux_inputs)
    coefficients = identity_coefficients() if coefficients is None else coefficients
    if source_files is None:
        source_files = [p.name for p in fmu_source_files(fmi_version=2) if p.suffix == ".c"]
    return description_xml(MODEL_NAME, table, values, guid, description, source_files, fmi_version, built,
                           _coefficient_xml(coefficients, check_fmi_version(fmi_version)),
                           default_experiment(training_data))


def description_xml(model_name: str, table: tuple[Variable, ...], values: dict, guid: str, description: str,
                    source_files: list[str], fmi_version: int, built: str | None, extra: list[str],
                    experiment: dict) -> str:
    """Text of the modelDescription.xml of any FMU of this source tree: `model_name` (also the model identifier),
    its variable `table` with the parameters' start `values` by name, `extra` variable elements after them,
    the .c `source_files` (FMI 2 lists them; FMI 3 in buildDescription.xml). Used by `model_description_xml`
    (ImuFusion) and fmu.sensor_fmu (the virtual sensor)."""
    if check_fmi_version(fmi_version) == 3:
        return _fmi3_xml(values, guid, description, table, built, extra, experiment, model_name)
    files = "\n".join(f"      <File name={quoteattr(name)}/>" for name in source_files)
    variables = "\n".join([_variable_xml(v, values) for v in table] + extra)
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription
  fmiVersion="2.0"
  modelName="{model_name}"
  guid={quoteattr(guid)}
  description={quoteattr(description)}
{_generation_attributes(built)}
  variableNamingConvention="flat"
  numberOfEventIndicators="0">
  <CoSimulation
    modelIdentifier="{model_name}"
    canHandleVariableCommunicationStepSize="true"
    canInterpolateInputs="false"
    maxOutputDerivativeOrder="0"
    canGetAndSetFMUstate="true"
    canSerializeFMUstate="true"
    providesDirectionalDerivative="false">
    <SourceFiles>
{files}
    </SourceFiles>
  </CoSimulation>
{_shared_sections(table, experiment)}
  <ModelVariables>
{variables}
  </ModelVariables>
{_model_structure_xml(fmi_version, table)}
</fmiModelDescription>
"""
