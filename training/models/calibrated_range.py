"""What the calibrated ranges of a trained model are, in words (`imufmu train` prints them).

Every model of the chain carries the range of inputs it was fitted on, and the runtime evaluates
it with its inputs clamped to that range (docs/fmu.md, 'Calibrated range'): the gain/bias
polynomials their temperature range (ThermalModel.t_range), the PSO-BP network its temperature
and temperature-rate ranges, the ELM its box of fields, each correction term its regressor bounds.
"""
from __future__ import annotations

import numpy as np

from contract.layout import TRIAD_ORDER
from training.models.thermal import ThermalModel

_NAMES = {"gyr": "gyroscope", "acc": "accelerometer", "mag": "magnetometer"}


def thermal_range_line(triad: str, model: ThermalModel) -> str | None:
    """The calibrated temperature range of one triad's gain/bias model; None when it is off, constant
    (degree 0: the temperature is no input) or has no range (training.artefact.unranged_notes)."""
    if not model.enabled or model.degree == 0 or model.t_range is None:
        return None
    return f"{_NAMES[triad]} gain/bias model: temperature {model.t_range[0]:.1f} … {model.t_range[1]:.1f} °C"


def psobp_range_line(block: list[float]) -> str | None:
    """The temperature [°C] and rate [°C/s] ranges of the PSO-BP block, or None when it is off."""
    if not block or block[0] == 0.0:
        return None
    t_min, t_max, r_min, r_max = block[3:7]
    return (f"PSO-BP network: temperature {t_min:.1f} … {t_max:.1f} °C, "
            f"temperature rate {r_min:.3g} … {r_max:.3g} °C/s")


def elm_range_line(block: list[float]) -> str | None:
    """The box of fields [µT] the ELM block was fitted on, or None when it is off."""
    if not block or block[0] == 0.0:
        return None
    lo, hi = np.asarray(block[3:6]), np.asarray(block[6:9])
    axes = ", ".join(f"{axis} {a:.1f} … {b:.1f}" for axis, a, b in zip("xyz", lo, hi))
    return f"ELM field model: field {axes} µT"


def range_notes(thermal: dict[str, ThermalModel], blocks: dict[str, list[float]],
                settings: dict[str, float]) -> list[str]:
    """One note per model the FMU applies (settings enable_elm / enable_psobp switch the stages)
    naming the input range it was calibrated on; the FMU clamps each model's inputs to it and
    reports an excursion through the output calibration_valid."""
    lines = [thermal_range_line(triad, thermal[triad]) for triad in TRIAD_ORDER]
    if settings.get("enable_psobp"):
        lines.append(psobp_range_line(blocks.get("psobp", [])))
    if settings.get("enable_elm"):
        lines.append(elm_range_line(blocks.get("elm", [])))
    return [f"calibrated range: {line}; outside it the FMU clamps the input and sets calibration_valid = 0"
            for line in lines if line is not None]
