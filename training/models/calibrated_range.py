"""What the calibrated ranges of a trained model are, in words (`imufmu train` prints them).

Every model of the chain carries the range of inputs it was fitted on (docs/fmu.md, 'Calibrated
range'): the gain/bias polynomials their temperature range (ThermalModel.t_range; outside it the
runtime continues them along their edge tangent for one span, thermal_continuation), the PSO-BP
network its temperature and temperature-rate ranges, the ELM its box of fields, each correction term
its regressor bounds (outside them the runtime clamps the input).
"""
from __future__ import annotations

from contract.layout import TRIAD_ORDER
from training.models.elm import ElmModel
from training.models.psobp import PsoBpModel
from training.models.thermal import ThermalModel

_NAMES = {"gyr": "gyroscope", "acc": "accelerometer", "mag": "magnetometer"}


def thermal_range_line(triad: str, model: ThermalModel) -> str | None:
    """The calibrated temperature range of one triad's gain/bias model; None when it is off, constant
    (degree 0: the temperature is no input) or has no range (training.artefact.unranged_notes)."""
    if not model.enabled or model.degree == 0 or model.t_range is None:
        return None
    return f"{_NAMES[triad]} gain/bias model: temperature {model.t_range[0]:.1f} … {model.t_range[1]:.1f} °C"


def psobp_range_line(model: PsoBpModel | None) -> str | None:
    """The temperature [°C] and rate [°C/s] ranges of the PSO-BP network, or None when it is off."""
    if model is None or not model.enabled:
        return None
    return (f"PSO-BP network: temperature {model.t_min:.1f} … {model.t_max:.1f} °C, "
            f"temperature rate {model.r_min:.3g} … {model.r_max:.3g} °C/s")


def elm_range_line(model: ElmModel | None) -> str | None:
    """The box of fields [µT] the ELM was fitted on, or None without one."""
    if model is None:
        return None
    axes = ", ".join(f"{axis} {a:.1f} … {b:.1f}" for axis, a, b in zip("xyz", model.x_norm.lo, model.x_norm.hi))
    return f"ELM field model: field {axes} µT"


def range_notes(thermal: dict[str, ThermalModel], elm_model: ElmModel | None, psobp_model: PsoBpModel | None,
                settings: dict[str, float]) -> list[str]:
    """One note per model the FMU applies (settings enable_elm / enable_psobp switch the stages)
    naming the input range it was calibrated on and what the FMU does outside it; it reports an
    excursion through the output calibration_valid."""
    continued = "continues the model along its tangent at the range edge (at most one span)" \
        if settings.get("thermal_continuation", 1.0) else "clamps the input"
    lines = [(thermal_range_line(triad, thermal[triad]), continued) for triad in TRIAD_ORDER]
    if settings.get("enable_psobp"):
        lines.append((psobp_range_line(psobp_model), "clamps the input"))
    if settings.get("enable_elm"):
        lines.append((elm_range_line(elm_model), "clamps the input"))
    return [f"calibrated range: {line}; outside it the FMU {action} and sets calibration_valid = 0"
            for line, action in lines if line is not None]
