"""Whether the online hard/soft-iron particle filter is on (the setting enable_pf): decided by running
it over the calibration recordings (issue 29).

The filter exists for a hard-iron change after the calibration — a magnet, a battery, a steel mount
that moves near the sensor — which turns the heading by the change over the horizontal field. Its
change test is set to the calibrated field's own residual (training.models.pf_settings), and until
the test fires the filter holds the trained calibration: its hard-iron output stays exactly 0. So the
recordings answer the question with the FMU's own code (training.runtime.run_batch at the trained
coefficients and settings): where the filter declares a change in a calibration recording, the
field around this sensor does change, and the filter is switched on; where it declares none in any,
it would only add its cost (docs/BENCHMARKS.md speed table) and stays off. Either way the note says
what the filter saw; a user who expects a change the recordings did not show sets enable_pf = 1.
"""
from __future__ import annotations

import numpy as np

from training.data.dataset import ImuData

#: The filter's hard-iron outputs.
HARD_IRON = ("hard_iron_x", "hard_iron_y", "hard_iron_z")


def largest_hard_iron_change(coefficients: np.ndarray, settings: dict[str, float], data: ImuData) -> float:
    """Largest |hard-iron change| [µT] the particle filter declares over a recording (0: none)."""
    from contract.layout import OUTPUTS, settings_array
    from training.data.dataset import recording_parameters
    from training.runtime import run_batch
    s = settings_array({**settings, **recording_parameters(data), "enable_pf": 1.0})
    out = run_batch(coefficients, np.asarray(s), data.t - data.t[0], data.inputs([]))
    h = np.linalg.norm(out[:, [OUTPUTS.index(n) for n in HARD_IRON]], axis=1)
    return float(np.nanmax(h)) if np.isfinite(h).any() else 0.0


def pf_switch(coefficients: np.ndarray, settings: dict[str, float], datasets: list[ImuData],
              notes: list[str]) -> dict[str, float]:
    """{"enable_pf": 1.0 or 0.0} from the particle filter run over the recordings with a magnetometer
    (see the module), with a note; {} without a magnetometer (the default stays, noted)."""
    usable = [d for d in datasets if d.has("mag")]
    if not usable:
        notes.append("enable_pf = 0 (the FMU's default): no magnetometer recorded")
        return {}
    changes = {d.name: largest_hard_iron_change(coefficients, settings, d) for d in usable}
    changed = {name: h for name, h in changes.items() if h > 0.0}
    if changed:
        seen = ", ".join(f"{name}: {h:.2f} µT" for name, h in changed.items())
        notes.append(f"enable_pf = 1: the online hard/soft-iron filter, run over the calibration recordings, declares a "
                     f"hard-iron change ({seen}): the field around this sensor changes, and the filter follows it")
        return {"enable_pf": 1.0}
    notes.append(f"enable_pf = 0: the online hard/soft-iron filter, run over the {len(usable)} calibration "
                 "recording(s), declares no hard-iron change; set enable_pf = 1 where a magnet, a battery or a "
                 "mount may move near the sensor after calibration")
    return {"enable_pf": 0.0}
