"""The fleet's ELM: the magnetometer's nonlinear error of a unit type, learnt from every unit at once.

A unit's own ELM (training.train, ELM_FITTER) gets 16 nodes and 60 back-tuning steps, the budget
that keeps `train` within seconds, on the one unit's data. What is left after each unit's linear
calibration is, for a type whose nonlinearity comes from its design (the sensing element, the
board), the same function of the calibrated field on every unit. The fleet can afford the runtime's
full ELM (IMU_ELM_MAX_HIDDEN nodes) on the compass rows of all its units, and a new unit
calibrated from a short recording gets it through `train --prior`, where it competes with the
unit's own ELM on the unit's held-out data (training.train._elm_stage).

Whether the type has such a common nonlinearity is measured, never assumed: every
HOLDOUT_EVERY-th unit is held out, the ELM is fitted on the others and scored on them, and the
fleet carries an ELM only when it lowers their field error by elm.MIN_GAIN (as a unit's own
ELM must). Units whose nonlinearities differ give no gain there and no fleet ELM.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from contract.errors import ModelError
from training.models import elm

#: The fleet ELM's fitter: the runtime's node cap, a classic ELM of random nodes (β by least
#: squares) back-tuned by Adam on seeded batches. On the 12-unit fleet of docs/fleet.md it fits in
#: ~10 s and leaves 0.089-0.098 µT on new units' held-out tests; on the same pooled rows the per-unit
#: budget left 0.125-0.188 µT, 32 / 64 grown nodes 0.10-0.12 / 0.087-0.099 µT in 12 s / 41 s.
FLEET_ELM_FITTER = dict(max_hidden=elm.MAX_HIDDEN, fixed_hidden=elm.MAX_HIDDEN, tune_steps=3000, tune_batch=8192)
#: Most compass rows one fit sees (a seeded sample of the pooled rows): bounds the fit's time
#: whatever the fleet's size; 12 units give ~28 000.
MAX_ROWS = 60_000
#: Every n-th unit (sorted by name, starting with the first) is held out to test the fleet ELM.
HOLDOUT_EVERY = 4
#: Fewest units a fleet ELM is learnt from (as the gain/bias prior, training.models.prior).
MIN_UNITS = 5


def _pooled(rows: list[tuple[np.ndarray, np.ndarray]], seed: int) -> tuple[np.ndarray, np.ndarray]:
    """The units' (field, reference) rows stacked, at most MAX_ROWS of them (a seeded sample)."""
    x, y = np.concatenate([r[0] for r in rows]), np.concatenate([r[1] for r in rows])
    if len(x) > MAX_ROWS:
        keep = np.sort(np.random.default_rng(seed).choice(len(x), MAX_ROWS, replace=False))
        x, y = x[keep], y[keep]
    return x, y


def _rms(a: np.ndarray) -> float:
    return float(np.sqrt(np.mean(a ** 2)))


def fit_fleet_elm(rows_by_unit: dict[str, tuple[np.ndarray, np.ndarray]], seed: int = 0,
                  progress=None) -> tuple[elm.ElmModel | None, dict]:
    """The fleet ELM from each unit's compass rows {unit: (calibrated field, reference field) [µT]},
    and its stats: units, rows, the held-out units' field error RMS before / after [µT], enabled,
    reason. None when there are too few units or the held-out units gain less than elm.MIN_GAIN.
    `progress`: called once after each of the two fits."""
    units = sorted(u for u, r in rows_by_unit.items() if r is not None and len(r[0]))
    if len(units) < MIN_UNITS:
        return None, {"units": len(units), "enabled": False,
                      "reason": f"fewer than {MIN_UNITS} units with a magnetometer reference"}
    held = units[::HOLDOUT_EVERY]
    fitter = elm.ElmFitter(**FLEET_ELM_FITTER)
    trial = fitter.fit(*_pooled([rows_by_unit[u] for u in units if u not in held], seed), seed)
    progress and progress()
    test_x = np.concatenate([rows_by_unit[u][0] for u in held])
    test_y = np.concatenate([rows_by_unit[u][1] for u in held])
    before, after = _rms(test_x - test_y), _rms(elm.elm_apply(trial, test_x) - test_y)
    stats = {"units": len(units), "held_out_units": held, "unit": "µT", "rms_before": before, "rms_after": after,
             "enabled": after <= (1.0 - elm.MIN_GAIN) * before}
    if not stats["enabled"]:
        return None, {**stats, "reason": f"on the held-out units the fleet ELM moves the field error {before:.3g} -> "
                                         f"{after:.3g} µT, not a {elm.MIN_GAIN:.0%} gain: the units do not share a "
                                         "nonlinearity it can learn"}
    x, y = _pooled([rows_by_unit[u] for u in units], seed)
    model = fitter.fit(x, y, seed)
    progress and progress()
    return model, {**stats, "rows": len(x), "hidden": model.hidden}


def fleet_elm_json(model: elm.ElmModel | None, stats: dict) -> dict:
    """fleet.json 'elm': the stats, and the model (training.models.elm.to_json) when there is one."""
    return {**stats, **({"model": elm.to_json(model)} if model is not None else {})}


def load_fleet_elm(path: str | Path) -> elm.ElmModel | None:
    """The fleet ELM of a fleet.json, None when the fleet carries none; ModelError names the file and
    the problem."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text()).get("elm", {})
        return elm.from_json(doc["model"]) if "model" in doc else None
    except (OSError, ValueError, TypeError, AttributeError) as e:
        raise ModelError(f"{path}: its fleet ELM cannot be read ({type(e).__name__}: {e})") from None
