"""Physical readings of a diagnosed effect: what the fitted coefficients mean in the units people use.

A lever arm of r = [...] m, a delay of n ms, a g-sensitivity of k (°/s)/g, a scale nonlinearity of
k %/(rad/s), a bias per temperature rate, per °C, per unit of an auxiliary signal. Families without
a physical reading get none (the report then lists the regressors only).
"""
from __future__ import annotations

import numpy as np

from training.data.earth import STANDARD_GRAVITY
from training.diagnosis.candidates import TRIAD_NAMES
from training.diagnosis.diagnose_fit import Fit
from training.display import DISPLAY

#: The unit 'g' of a g-sensitivity [(°/s)/g]: standard gravity, as in datasheets (IEEE Std 528).
G = STANDARD_GRAVITY


def _vector(v, digits: int = 3) -> str:
    return "[" + ", ".join(f"{x:.{digits}g}" for x in v) + "]"


def _per_component(candidate, coef: np.ndarray) -> np.ndarray:
    """(3, k) coefficients of a free family: component-major, k regressors each."""
    return coef.reshape(3, len(candidate.columns) // 3)


def lag_reading(triad: str, tau: float, rate_hz: float) -> str:
    """'the field lags the reference by 40.0 ms (4.00 samples at 100 Hz)'; tau [s] > 0 = lags."""
    return (f"the {TRIAD_NAMES[triad]} {'lags' if tau > 0 else 'leads'} the reference by "
            f"{abs(tau) * 1e3:.1f} ms ({abs(tau) * rate_hz:.2f} samples at {rate_hz:.0f} Hz)")


def _reading(candidate, coef: np.ndarray, rate_hz: float, aux_units: dict[str, str],
             lags: dict[str, float]) -> str | None:
    """One sentence for one fitted family, or None."""
    triad, name = candidate.triad, candidate.name
    unit, scale = DISPLAY[triad]
    if candidate.kind == "lag":
        return lag_reading(triad, lags.get(triad, -float(coef[0])), rate_hz)
    if name == "lever arm":
        return f"lever arm r = {_vector(coef)} m (|r| = {100 * np.linalg.norm(coef):.1f} cm) from the centre of rotation"
    k = _per_component(candidate, coef)
    if name == "specific force" and triad == "gyr":
        g = k * np.rad2deg(1.0) * G
        return f"g-sensitivity matrix [(°/s)/g], rows x y z: {'; '.join(_vector(row) for row in g)}"
    if name.endswith("signed square") and candidate.own:
        return f"scale nonlinearity {_vector(100 * np.diag(k))} %/({'rad/s' if triad == 'gyr' else DISPLAY[triad][0]}) per axis"
    if name.startswith("temperature rate"):
        return f"bias {_vector(k[:, 0] * scale / 60.0)} {unit} per °C/min"
    if name == "temperature":
        return f"bias drift {_vector(k[:, 0] * scale)} {unit}/°C"
    if name == "time":
        return f"drift {_vector(k[:, 0] * scale * 60.0)} {unit}/min (clamped to the fitted span)"
    if name.startswith("aux_") and k.shape[1] == 1:
        aux_unit = aux_units.get(name) or "unit"
        return f"{_vector(k[:, 0] * scale)} {unit} per {aux_unit} of {name}"
    return _largest(candidate, coef, unit, scale)


def _largest(candidate, coef: np.ndarray, unit: str, scale: float) -> str | None:
    """The largest coefficient of a free family of a triad, in the target's display unit per
    regressor unit: '0.003 m/s² per (m/s²)² on acc_x × acc_x*acc_y'."""
    units = {"gyr": "rad/s", "acc": "m/s²", "mag": "µT"}
    j = int(np.argmax(np.abs(coef)))
    (c, a, b, _), = candidate.columns[j]
    source = units.get(a.removeprefix("abs_").removeprefix("d_").split("_")[0])
    if source is None:
        return None
    if a.startswith("d_"):
        source = f"{source}/s"
    power = "" if b is None else "²"
    label = a if b is None else f"{a}*{b}"
    return (f"largest coefficient {coef[j] * scale:.3g} {unit} per ({source}){power} "
            f"on {candidate.triad}_{'xyz'[c]} × {label}")


def readings(fit: Fit, rate_hz: float, aux_units: dict[str, str] | None = None,
             lags: dict[str, float] | None = None) -> list[str]:
    """The physical readings of every family of a (joint) fit; `lags` [s] by triad, when the
    runtime's lag was refined beyond the fit's linearised estimate, replace that estimate."""
    out = []
    for candidate, coef in zip(fit.candidates, fit.coefficients()):
        text = _reading(candidate, np.asarray(coef), rate_hz, aux_units or {}, lags or {})
        if text:
            out.append(text)
    return out
