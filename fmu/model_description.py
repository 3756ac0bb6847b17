"""modelDescription.xml (FMI 2.0 co-simulation, source FMU) generated from the variable table."""
from __future__ import annotations

import math
from xml.sax.saxutils import quoteattr

from fmu.compiler import fmu_source_files
from fmu.variables import VARIABLES, Variable
from training.layout import settings_defaults

MODEL_NAME = "ImuFusion"
GENERATION_TOOL = "imufusion fmu package"

#: Default experiment: 10 s at 100 Hz.
DEFAULT_EXPERIMENT = {"startTime": 0.0, "stopTime": 10.0, "stepSize": 0.01}

#: Log categories, in the order of the LogCategory enum of sources/fmi2Functions.c.
LOG_CATEGORIES = (
    ("logEvents", "Instantiation, initialisation and other life-cycle events"),
    ("logStatusWarning", "Calls that return fmi2Warning"),
    ("logStatusError", "Calls that return fmi2Error, with the reason"),
)

_DEG = f'<DisplayUnit name="deg" factor="{180.0 / math.pi!r}"/>'
_DEG_S = f'<DisplayUnit name="deg/s" factor="{180.0 / math.pi!r}"/>'

#: Unit definitions: name -> inner XML (BaseUnit and display units). FMI 2.0 base-unit exponents
#: are integers, so rad/s/sqrt(Hz) = rad*s^(-1/2) has no BaseUnit.
UNITS = {
    "1": "<BaseUnit/>",
    "rad": f'<BaseUnit rad="1"/>{_DEG}',
    "rad/s": f'<BaseUnit rad="1" s="-1"/>{_DEG_S}',
    "rad/s/sqrt(Hz)": "",
    "m/s2": '<BaseUnit m="1" s="-2"/>',
    "uT": '<BaseUnit kg="1" A="-1" s="-2" factor="1e-06"/>',
    "degC": '<BaseUnit K="1" offset="273.15"/>',
    "s": '<BaseUnit s="1"/>',
}


def _start_text(variable: Variable, value: float | bool) -> str:
    """XML text of a start value (xs:double round-trip repr, or true/false)."""
    if variable.type == "Boolean":
        return "true" if value else "false"
    return repr(float(value))


def _variable_xml(variable: Variable, settings: dict) -> str:
    """One ScalarVariable element; parameter start values come from `settings`."""
    start = variable.start
    if variable.causality == "parameter":
        start = settings[variable.name]
    attributes = [f"name={quoteattr(variable.name)}", f'valueReference="{variable.value_reference}"',
                  f"description={quoteattr(variable.description)}", f'causality="{variable.causality}"',
                  f'variability="{variable.variability}"']
    if variable.causality == "parameter":
        attributes.append('initial="exact"')
    type_attributes = []
    if variable.unit is not None:
        type_attributes.append(f"unit={quoteattr(variable.unit)}")
    if variable.display_unit is not None:
        type_attributes.append(f"displayUnit={quoteattr(variable.display_unit)}")
    if start is not None:
        type_attributes.append(f'start="{_start_text(variable, start)}"')
    return (f'    <ScalarVariable {" ".join(attributes)}>\n'
            f'      <{variable.type} {" ".join(type_attributes)}/>\n'
            f'    </ScalarVariable>')


def _model_structure_xml() -> str:
    """Outputs (no direct feedthrough in co-simulation) and InitialUnknowns (every output)."""
    index = {v.name: i + 1 for i, v in enumerate(VARIABLES)}
    outputs = [v for v in VARIABLES if v.causality == "output"]
    lines = ["  <ModelStructure>", "    <Outputs>"]
    lines += [f'      <Unknown index="{index[v.name]}" dependencies=""/>' for v in outputs]
    lines += ["    </Outputs>", "    <InitialUnknowns>"]
    for v in outputs:
        # Before the first sample every output is constant except heading = declination.
        dependencies = str(index["declination"]) if v.name == "heading" else ""
        lines.append(f'      <Unknown index="{index[v.name]}" dependencies="{dependencies}"/>')
    lines += ["    </InitialUnknowns>", "  </ModelStructure>"]
    return "\n".join(lines)


def model_description_xml(settings: dict, guid: str, description: str,
                          source_files: list[str] | None = None) -> str:
    """Text of modelDescription.xml.

    settings: parameter start values by name (missing names take training.layout defaults);
    guid: the GUID also compiled into the binary; description: the model's one-line description;
    source_files: the .c files to list under SourceFiles (default: those of fmu.compiler).
    Raises KeyError for an unknown setting name.
    """
    values = settings_defaults()
    for name, value in settings.items():
        if name not in values:
            raise KeyError(f"unknown setting '{name}' (known: {', '.join(values)})")
        values[name] = value
    if source_files is None:
        source_files = [p.name for p in fmu_source_files() if p.suffix == ".c"]
    files = "\n".join(f"      <File name={quoteattr(name)}/>" for name in source_files)
    units = "\n".join(f"    <Unit name={quoteattr(name)}>{inner}</Unit>" if inner else f"    <Unit name={quoteattr(name)}/>"
                      for name, inner in UNITS.items())
    categories = "\n".join(f"    <Category name={quoteattr(n)} description={quoteattr(d)}/>" for n, d in LOG_CATEGORIES)
    experiment = " ".join(f'{k}="{v!r}"' for k, v in DEFAULT_EXPERIMENT.items())
    variables = "\n".join(_variable_xml(v, values) for v in VARIABLES)
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription
  fmiVersion="2.0"
  modelName="{MODEL_NAME}"
  guid={quoteattr(guid)}
  description={quoteattr(description)}
  generationTool="{GENERATION_TOOL}"
  variableNamingConvention="flat"
  numberOfEventIndicators="0">
  <CoSimulation
    modelIdentifier="{MODEL_NAME}"
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
  <UnitDefinitions>
{units}
  </UnitDefinitions>
  <LogCategories>
{categories}
  </LogCategories>
  <DefaultExperiment {experiment}/>
  <ModelVariables>
{variables}
  </ModelVariables>
{_model_structure_xml()}
</fmiModelDescription>
"""
