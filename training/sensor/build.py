"""`imufmu build-sensor-fmu`: the virtual-sensor FMU of a trained model (fmu/sensor_fmu.py): its chain compiled
in, its noise figures (model.json's "noise" block, training/noise) as the noise parameters' start values."""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

from contract.errors import ModelError
from contract.sensor_variables import AXES, FIGURES, TRIADS, noise_parameter_name
from fmu.sensor_fmu import pack_sensor_fmu
from training.artefact import coefficients_array, load_artefact, settings_dict


@dataclass
class SensorNoisePlan:
    """The noise parameters a model gives (name -> value) and, loudly, what it could not give."""

    parameters: dict[str, float] = field(default_factory=dict)
    unsupported: list[str] = field(default_factory=list)   # "gyr random_walk x: <why>"
    source: str = ""
    warnings: list[str] = field(default_factory=list)      # stages the sensor cannot run backwards faithfully


def noise_plan(noise: dict | None) -> SensorNoisePlan:
    """The sensor's noise parameters from a model's "noise" block (format imufusion-noise/1): each figure the
    data support, 0 for each they do not (listed in `unsupported` with the reason), the LSB where the data
    show one (the white noise density then without the quantisation's share). None (a model trained before the block existed): nothing, every figure unsupported."""
    plan = SensorNoisePlan()
    if not noise:
        plan.unsupported.append("the model has no noise characterisation (train it again with this version): "
                                "the sensor is noise-free unless the noise parameters are set")
        return plan
    plan.source = str(noise.get("source", ""))
    triads = noise.get("triads", {})
    rate = noise.get("rate_hz")
    for triad, *_ in TRIADS:
        entry = triads.get(triad)
        if entry is None:
            plan.unsupported.append(f"{triad}: not in the calibration data: no noise")
            continue
        for a, axis in enumerate(entry.get("axes", [])[:3]):
            for figure, _ in FIGURES:
                item = axis.get(figure) or {}
                value = float(item.get("value", 0.0))
                if item.get("supported") and math.isfinite(value) and value >= 0.0:
                    plan.parameters[noise_parameter_name(triad, figure, a)] = value
                else:
                    plan.unsupported.append(f"{triad} {figure} {AXES[a]}: {item.get('why') or 'not characterised'}")
        lsb = entry.get("lsb")
        if isinstance(lsb, (int, float)) and math.isfinite(lsb) and lsb > 0:
            plan.parameters[f"{triad}_lsb"] = float(lsb)
            _without_quantisation(plan.parameters, triad, float(lsb), rate)
    return plan


def _without_quantisation(parameters: dict[str, float], triad: str, lsb: float, rate_hz) -> None:
    """The measured white noise holds the quantisation's (σ² = lsb²/12 per sample, density² = lsb²/(12 fs)); the
    sensor rounds to the LSB itself, so its white-noise density parameters are the rest (else counted twice)."""
    if not isinstance(rate_hz, (int, float)) or not rate_hz > 0:
        return
    quantisation = lsb * lsb / (12.0 * rate_hz)
    for a in range(3):
        name = noise_parameter_name(triad, "noise_density", a)
        if name in parameters:
            parameters[name] = math.sqrt(max(parameters[name] ** 2 - quantisation, 0.0))


def anticausal_terms(terms: list[dict], rate_hz: float | None) -> list[str]:
    """The correction terms on a time derivative whose inverse is unstable: the corrector subtracts c · dx/dt
    with c > 0 (it delays the triad by c seconds), so the sensor would have to lead true time by c; its
    discrete inverse at the sampling interval h is stable only while c < h / 2 (pole c/h / (1 - c/h))."""
    h = 1.0 / rate_hz if rate_hz else None
    lines = []
    for term in terms:
        derivative = any(str(term.get(k) or "").startswith("d_") for k in ("a", "b"))
        if derivative and term.get("b") is None and float(term["coefficient"]) > 0.0 and (h is None or
                                                                                          term["coefficient"] >= h / 2):
            lines.append(f"term {term['target']} <- {term['a']} x {term['coefficient']:.4g} s delays the triad: the "
                         "virtual sensor would have to lead true time (its inverse diverges); set that term's "
                         "coefficient to 0 in model.json for the sensor, or accept a diverging output")
    return lines


def leading_triads(chain: dict[str, float]) -> list[str]:
    """The triads whose input leads true time (lag_* < 0): the sensor would need the future truth, so it
    extrapolates (ImuAlign's linear extrapolation), exact only for a triad that changes linearly."""
    return [f"{name} = {chain[name]:.4g} s: the {name[4:]} leads true time; the sensor extrapolates the truth that far "
            "(exact only where it changes linearly)" for name in ("lag_gyr", "lag_acc", "lag_mag") if chain.get(name, 0.0) < 0.0]


def field_parameters(chain: dict[str, float]) -> dict[str, float]:
    """The earth field the model was trained in (its declination, field_norm, field_dip settings)."""
    return {"declination": chain["declination"], "field_norm": chain["field_norm"], "field_dip": chain["field_dip"]}


def build_sensor_fmu(model_path: str | Path, out_path: str | Path, fmi_version: int = 2,
                     overrides: dict[str, float] | None = None) -> tuple[Path, SensorNoisePlan]:
    """The virtual-sensor FMU of the trained model at `model_path` at `out_path` (FMI 2 or 3): its chain, the
    field it was trained in and its noise figures as start values, `overrides` (parameter name -> value, e.g.
    data-sheet figures) last. Returns the FMU's path and the noise plan (what was not supported)."""
    artefact = load_artefact(model_path)
    try:
        noise = json.loads(Path(model_path).read_text()).get("noise")
    except (OSError, ValueError) as e:
        raise ModelError(f"{model_path}: cannot read the model ({e})") from e
    chain = settings_dict(artefact)
    plan = noise_plan(noise)
    parameters = {**field_parameters(chain), **plan.parameters, **(overrides or {})}
    plan.unsupported = [u for u in plan.unsupported if not _overridden(u, overrides or {})]
    rates = [d["rate_hz"] for d in artefact.training_data if isinstance(d.get("rate_hz"), (int, float))]
    plan.warnings = anticausal_terms(artefact.terms, max(rates) if rates else None) + leading_triads(chain)
    path = pack_sensor_fmu(coefficients_array(artefact), chain, parameters, out_path, fmi_version,
                           provenance=f"Model {Path(model_path).name}", rate_hz=max(rates) if rates else None)
    return path, plan


def _overridden(unsupported: str, overrides: dict[str, float]) -> bool:
    """Whether the unsupported figure named by the line (`triad figure axis: why`) was set by the user."""
    words = unsupported.split(":")[0].split()
    return len(words) == 3 and noise_parameter_name(words[0], words[1], AXES.index(words[2])) in overrides


def noise_summary_lines(plan: SensorNoisePlan, overrides: dict[str, float]) -> list[str]:
    """What the sensor's noise is, per triad and axis with units: each figure from the data, set by the user, or
    (loudly) not characterised and 0; then the stages the sensor cannot run backwards faithfully."""
    lines = [f"noise from: {plan.source or 'nothing (no noise block in the model)'}"]
    for triad, unit, units, *_ in TRIADS:
        for (figure, _), figure_unit in zip(FIGURES, units):
            values = []
            for a in range(3):
                name = noise_parameter_name(triad, figure, a)
                value = overrides.get(name, plan.parameters.get(name))
                tag = " (set)" if name in overrides else ""
                values.append(f"{value:.3g}{tag}" if value is not None else "0 (NOT characterised)")
            lines.append(f"  {triad} {figure:16s} x / y / z: {' / '.join(values)} {figure_unit}")
    if plan.unsupported:
        lines.append(f"WARNING: {len(plan.unsupported)} noise figure(s) the data could not support are 0 in the sensor "
                     "(it is quieter than the unit there); set them with --set NAME=VALUE:")
        lines += [f"  - {line}" for line in plan.unsupported]
    lines += [f"WARNING: {line}" for line in plan.warnings]
    return lines
