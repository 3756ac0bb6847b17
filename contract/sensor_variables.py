"""The one variable table of the virtual-sensor FMU (ImuSensor, issue 34; docs/virtual_sensor.md): the
true motion in, what the calibrated unit would output out, and its noise as parameters.

Everything else is derived from it: sources/sensor/config.h (value references, array enums, the slot
of every value reference and the declared ranges: `python -m contract.generate`, checked by
tests/test_generated.py) and the sensor FMU's modelDescription.xml (fmu/sensor_fmu.py). The outputs
carry the names of the ImuFusion FMU's raw inputs (gyr_x … temp), so an importer connects the two
name for name.
"""
from __future__ import annotations

import math

from contract.ranges import BOOLEAN, FIELD_NORM_MAX_UT, FIELD_NORM_MIN_UT, INT32_MAX, INTEGER, REAL, SettingRange
from contract.variables import AUX_INPUTS, Variable, _input, _output, _parameter

MODEL_NAME = "ImuSensor"

#: The three triads: name, unit, its noise units (density, instability, walk), a noise ceiling [unit] and the
#: largest full scale [unit] a parameter may declare.
TRIADS = (
    ("gyr", "rad/s", ("rad/s/sqrt(Hz)", "rad/s", "rad/s/sqrt(s)"), 1.0, 1.0e3),
    ("acc", "m/s2", ("m/s2/sqrt(Hz)", "m/s2", "m/s2/sqrt(s)"), 10.0, 1.0e4),
    ("mag", "uT", ("uT/sqrt(Hz)", "uT", "uT/sqrt(s)"), 100.0, 1.0e5),
)
#: The noise figures of each axis (the parameter name's middle part) and what they are.
FIGURES = (("noise_density", "white noise density N"),
           ("bias_instability", "bias instability B (flicker floor of the Allan deviation / 0.664)"),
           ("random_walk", "bias random walk K"))
AXES = ("x", "y", "z")

_TRUTH = (
    ("true_rate", "rad/s", "True angular rate about body {a}", (0.0, 0.0, 0.0)),
    ("true_accel", "m/s2", "True specific force along body {a}", (0.0, 0.0, -9.80665)),
)


def _inputs() -> list[Variable]:
    vr, out = 0, []
    for name, unit, text, starts in _TRUTH:
        for a, start in zip(AXES, starts):
            out.append(_input(f"{name}_{a}", vr, unit, text.format(a=a), start))
            vr += 1
    for c, start in zip("wxyz", (1.0, 0.0, 0.0, 0.0)):
        out.append(_input(f"true_q_{c}", vr, "1", f"True attitude quaternion {c}, Hamilton, body -> true NED "
                          "(the field comes from it when field_from_attitude)", start))
        vr += 1
    for a, start in zip(AXES, (20.0, 0.0, 40.0)):
        out.append(_input(f"true_field_{a}", vr, "uT", f"True magnetic field along body {a} (used when "
                          "field_from_attitude is off)", start))
        vr += 1
    out.append(_input("true_temp", vr, "degC", "Sensor temperature (NaN if unknown)", 25.0))
    vr += 1
    for k, name in enumerate(AUX_INPUTS):
        out.append(_input(name, vr + k, None, f"Auxiliary input {k + 1}, as the ImuFusion FMU's {name} (what the "
                          "trained correction terms use)", 0.0))
    return out


_RAW = {"gyr": "Raw angular rate about sensor {a} as the unit outputs it",
        "acc": "Raw specific force along sensor {a} as the unit outputs it",
        "mag": "Raw magnetic field along sensor {a} as the unit outputs it"}


def _outputs(first: int) -> list[Variable]:
    out, vr = [], first
    for triad, unit, *_ in TRIADS:
        for a in AXES:
            out.append(_output(f"{triad}_{a}", vr, unit, _RAW[triad].format(a=a)))
            vr += 1
    out.append(_output("temp", vr, "degC", "Sensor temperature as the unit outputs it"))
    return out


def _parameters(first: int) -> list[Variable]:
    vr = first
    out = [_parameter("seed", vr, 0.0, SettingRange(INTEGER, 0.0, float(INT32_MAX)),
                      "Seed of the noise generator: the same seed, the same recording"),
           _parameter("noise", vr + 1, 1.0, SettingRange(BOOLEAN, 0.0, 1.0),
                      "Add the noise, saturation and quantisation (off: the exact inverse of the corrections)"),
           _parameter("field_from_attitude", vr + 2, 1.0, SettingRange(BOOLEAN, 0.0, 1.0),
                      "Body field from true_q_* and the earth field (off: from true_field_*)"),
           _parameter("field_norm", vr + 3, 50.0, SettingRange(REAL, FIELD_NORM_MIN_UT, FIELD_NORM_MAX_UT, "uT"),
                      "Earth-field magnitude"),
           _parameter("field_dip", vr + 4, math.radians(60.0), SettingRange(REAL, -math.pi / 2, math.pi / 2, "rad"),
                      "Earth-field dip (inclination, positive down)", "deg"),
           _parameter("declination", vr + 5, 0.0, SettingRange(REAL, -math.pi, math.pi, "rad"),
                      "Magnetic declination (magnetic north east of true north)", "deg")]
    vr += 6
    for triad, _, units, ceiling, full in TRIADS:
        for (figure, text), unit in zip(FIGURES, units):
            for a in AXES:
                out.append(_parameter(f"{triad}_{figure}_{a}", vr, 0.0, SettingRange(REAL, 0.0, ceiling, unit),
                                      f"{text[0].upper()}{text[1:]} of the {triad} {a} axis"))
                vr += 1
    for triad, unit, _, _, full in TRIADS:
        out.append(_parameter(f"{triad}_lsb", vr, 0.0, SettingRange(REAL, 0.0, full, unit),
                              f"Quantisation step of the {triad} output (0 = none)"))
        out.append(_parameter(f"{triad}_full_scale", vr + 1, 0.0, SettingRange(REAL, 0.0, full, unit),
                              f"Saturation of the {triad} output at +-full scale (0 = none)"))
        vr += 2
    return out


def _table() -> tuple[Variable, ...]:
    inputs = _inputs()
    outputs = _outputs(len(inputs))
    return tuple(inputs + outputs + _parameters(len(inputs) + len(outputs)))


#: Every variable of the sensor FMU, value-reference order.
SENSOR_VARIABLES: tuple[Variable, ...] = _table()


def sensor_parameters() -> tuple[Variable, ...]:
    """The parameters, in the settings array's order."""
    return tuple(v for v in SENSOR_VARIABLES if v.causality == "parameter")


def noise_parameter_name(triad: str, figure: str, axis: int) -> str:
    """The parameter of one noise figure ("gyr", "noise_density", 0 -> gyr_noise_density_x)."""
    return f"{triad}_{figure}_{AXES[axis]}"
