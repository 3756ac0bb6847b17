"""The fleet ELM (training.models.fleet_elm): the magnetometer nonlinearity a unit type shares,
learnt from all its units, carried only when units it never saw gain from it.

Truth: compass rows (calibrated field, reference field) of synthetic units, each the reference
through a cubic distortion d_i = Σ_j c_ij (v_j / 50 µT)³ [µT] (the simulator's form) plus 0.05 µT
of noise. A type whose units share c must give a fleet ELM that removes most of it on a new unit;
a type whose units each have their own c must give none.
"""
import json

import numpy as np
import pytest

from contract.errors import ModelError
from training.models import elm, fleet_elm
from training.models.fleet_elm import MIN_UNITS, fit_fleet_elm, fleet_elm_json, load_fleet_elm

#: The simulator's mems_grade cubic coefficients [µT] (scenarios/sensors/mems_grade.toml).
CUBIC = np.array([[1.5, 0.5, -0.3], [0.4, -1.2, 0.6], [-0.5, 0.3, 1.0]])
NOISE_UT = 0.05


def _unit_rows(cubic: np.ndarray, seed: int, rows: int = 1500) -> tuple[np.ndarray, np.ndarray]:
    """(distorted field, reference) [µT] of one unit: references of norm 50 µT in all directions."""
    rng = np.random.default_rng(seed)
    v = rng.standard_normal((rows, 3))
    v *= 50.0 / np.linalg.norm(v, axis=1, keepdims=True)
    return v + (v / 50.0) ** 3 @ cubic.T + NOISE_UT * rng.standard_normal((rows, 3)), v


def _rms(a):
    return float(np.sqrt(np.mean(a ** 2)))


@pytest.fixture
def quick_fitter(monkeypatch):
    """The fleet fitter with a tenth of its back-tuning steps: the tests check the logic, the
    budget's accuracy is measured by benchmarks/fleet_prior.py."""
    monkeypatch.setattr(fleet_elm, "FLEET_ELM_FITTER", {**fleet_elm.FLEET_ELM_FITTER, "tune_steps": 300})


def test_a_shared_nonlinearity_is_learnt_and_removed_on_a_new_unit(quick_fitter):
    model, stats = fit_fleet_elm({f"u{k}": _unit_rows(CUBIC, k) for k in range(8)}, seed=0)
    assert model is not None and stats["enabled"] and stats["held_out_units"] == ["u0", "u4"]
    x, y = _unit_rows(CUBIC, 100)
    before, after = _rms(x - y), _rms(elm.elm_apply(model, x) - y)
    # the distortion is ~0.7 µT RMS; the ELM must leave at most a third of it (noise 0.05 µT included)
    assert before > 0.5 and after < before / 3


def test_units_with_their_own_nonlinearities_give_no_fleet_elm(quick_fitter):
    rng = np.random.default_rng(7)
    rows = {f"u{k}": _unit_rows(rng.normal(0.0, 1.0, (3, 3)), k) for k in range(8)}
    model, stats = fit_fleet_elm(rows, seed=0)
    assert model is None and not stats["enabled"] and "not a 10% gain" in stats["reason"]


def test_too_few_units_give_no_fleet_elm():
    model, stats = fit_fleet_elm({f"u{k}": _unit_rows(CUBIC, k) for k in range(MIN_UNITS - 1)}, seed=0)
    assert model is None and f"fewer than {MIN_UNITS} units" in stats["reason"]


def test_the_fleet_elm_reads_back_from_fleet_json(tmp_path, quick_fitter):
    model, stats = fit_fleet_elm({f"u{k}": _unit_rows(CUBIC, k, 400) for k in range(5)}, seed=0)
    path = tmp_path / "fleet.json"
    path.write_text(json.dumps({"elm": fleet_elm_json(model, stats)}))
    x, _ = _unit_rows(CUBIC, 9, 50)
    assert np.allclose(elm.elm_apply(load_fleet_elm(path), x), elm.elm_apply(model, x), rtol=0, atol=1e-12)
    path.write_text(json.dumps({"elm": fleet_elm_json(None, {"reason": "none"})}))
    assert load_fleet_elm(path) is None
    path.write_text(json.dumps({"elm": {"model": {"form": "field", "w": "x"}}}))
    with pytest.raises(ModelError, match="fleet.json: its fleet ELM cannot be read"):
        load_fleet_elm(path)


def test_a_unit_gets_the_fleet_elm_only_when_it_leaves_less_on_the_units_held_out_data(quick_fitter):
    from training.train import _fleet_elm_choice
    good, _ = fit_fleet_elm({f"u{k}": _unit_rows(CUBIC, k) for k in range(6)}, seed=0)
    bad, _ = fit_fleet_elm({f"u{k}": _unit_rows(-CUBIC, k) for k in range(6)}, seed=0)
    x, y = _unit_rows(CUBIC, 50)
    folds = [(x[:1000], y[:1000], x[1000:], y[1000:])]
    own = [((x[1000:] - y[1000:]) ** 2, (0.3 * (x[1000:] - y[1000:])) ** 2)]   # an own ELM leaving 30 %
    notes = []
    assert _fleet_elm_choice(good, folds, own, notes) and notes[-1].endswith("the unit gets the fleet")
    assert not _fleet_elm_choice(bad, folds, own, notes) and notes[-1].endswith("the unit gets its own")


def test_a_fleet_elm_is_not_used_without_a_reference_to_check_it_on():
    from training.models.thermal import ThermalModel
    from training.train import _elm_stage
    notes = []
    model, enabled, _ = _elm_stage([], {"mag": ThermalModel.identity()}, 0, notes, False, fleet_elm=object())
    assert model is None and not enabled and notes[-1].endswith("not used either (nothing to check it on)")
