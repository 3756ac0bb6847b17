"""Issue 15 item 2: outside the calibrated range.

A model trained on two static soaks at 15 and 35 °C (scenarios/variants/two_soaks.toml with its
soak temperatures moved, the mems_grade sensor) records that temperature range; the runtime
evaluates the gain/bias polynomials with the temperature clamped to it, so at -20 and 70 °C the
corrected outputs are those of the range edge, not of an extrapolated polynomial. The output
`calibration_valid` is 0 exactly while a model input is outside its range, and the FMU (through
fmpy) logs one Warning per excursion episode. The PSO-BP network, the ELM and the correction terms
clamp their inputs the same way and report their excursions through the same output.
"""
from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from fmu.cosim import run_fmu
from training.fmu_build import build_fmu
from test_psobp import random_model
from test_thermal_degree import static_recording
from contract.layout import (OUTPUTS, TRIAD_BLOCK, TRIAD_ORDER, identity_block, identity_coefficients,
                             pack_coefficients, settings_array, terms_block)
from training.artefact import coefficients_array, load_artefact, settings_dict
from training.main_job import SCENARIO_DIR
from training.models import elm
from training.models.thermal import CONTINUATION_SPANS, apply_thermal
from training.models.psobp import MODE_RESIDUAL, evaluate_psobp_c
from training.runtime import run_batch
from training.simulator import load_scenario, simulate
from training.train import train

TWO_SOAKS = SCENARIO_DIR / "variants" / "two_soaks.toml"
#: The soak temperatures of the calibration [°C] and the evaluation temperatures far outside them.
SOAKS_C = (15.0, 35.0)
OUTSIDE_C = (-20.0, 70.0)
#: The recorded range is the span of the simulated sensor temperature, which sits on the soaks.
RANGE_TOLERANCE_C = 0.5
CALIBRATION_VALID = OUTPUTS.index("calibration_valid")
RATE_HZ = 50.0


def two_soak_scenario(directory: Path):
    """two_soaks.toml with its soaks at SOAKS_C instead of 13 and 48 °C."""
    sensor = (TWO_SOAKS.parent / "../sensors/mems_grade.toml").resolve()
    text = TWO_SOAKS.read_text(encoding="utf-8")
    edits = {"temp_c = 13.0": f"temp_c = {SOAKS_C[0]}", "temp_end_c = 48.0": f"temp_end_c = {SOAKS_C[1]}",
             '"../sensors/mems_grade.toml"': json.dumps(str(sensor))}
    for old, new in edits.items():
        assert text.count(old) == 1, old
        text = text.replace(old, new)
    path = directory / "two_soaks_15_35.toml"
    path.write_text(text, encoding="utf-8")
    return load_scenario(path)


@pytest.fixture(scope="module")
def scenario(tmp_path_factory):
    return two_soak_scenario(tmp_path_factory.mktemp("scenario"))


@pytest.fixture(scope="module")
def artefact(scenario):
    return train([simulate(scenario)], seed=0, progress=False)


def calibrated_range(art) -> tuple[float, float]:
    """The temperatures [°C] inside every gain/bias model's range (the ranges coincide here)."""
    ranges = [m.t_range for m in art.thermal.values() if m.enabled and m.degree > 0]
    return max(lo for lo, _ in ranges), min(hi for _, hi in ranges)


def batch(art, t, inputs) -> np.ndarray:
    return run_batch(coefficients_array(art), np.asarray(settings_array(settings_dict(art))), t, inputs)


def test_the_artefact_records_the_range_and_train_says_it(artefact, tmp_path):
    for triad in TRIAD_ORDER:
        model = artefact.thermal[triad]
        assert model.enabled and model.degree == 1, triad
        np.testing.assert_allclose(model.t_range, SOAKS_C, atol=RANGE_TOLERANCE_C)
    loaded = load_artefact(artefact.save(tmp_path / "model.json"))
    assert all(loaded.thermal[k].t_range == artefact.thermal[k].t_range for k in TRIAD_ORDER)
    lo, hi = artefact.thermal["gyr"].t_range
    assert (f"calibrated range: gyroscope gain/bias model: temperature {lo:.1f} … {hi:.1f} °C; outside it the FMU "
            "continues the model along its tangent at the range edge (at most one span) and sets calibration_valid = 0") \
        in artefact.notes


def batch_with(art, t, inputs, **settings) -> np.ndarray:
    """The batch runtime with the artefact's settings and `settings` changed."""
    values = settings_dict(art)
    values.update(settings)
    return run_batch(coefficients_array(art), np.asarray(settings_array(values)), t, inputs)


@pytest.mark.parametrize("temp_c", OUTSIDE_C)
def test_with_continuation_off_the_models_hold_their_edge_value(scenario, artefact, temp_c):
    # The bound on the corrected biases at T relative to the value at the range edge is zero: the
    # temperature is clamped before any arithmetic, so the same raw samples compensated at T and at
    # the edge temperature give bit-identical outputs (the polynomial extrapolated to T does not).
    lo, hi = calibrated_range(artefact)
    edge = lo if temp_c < lo else hi
    data = static_recording(scenario, temp_c, seed=int(temp_c) + 200)
    at_edge = data.inputs()
    at_edge[:, 9] = edge
    out = batch_with(artefact, data.t, data.inputs(), thermal_continuation=0.0)
    out_edge = batch_with(artefact, data.t, at_edge, thermal_continuation=0.0)
    np.testing.assert_array_equal(out[:, :6], out_edge[:, :6])
    unclamped = replace(artefact, thermal={k: replace(m, t_range=None) for k, m in artefact.thermal.items()})
    assert np.max(np.abs(batch(unclamped, data.t, data.inputs())[:, :6] - out_edge[:, :6])) > 1e-3


#: C and numpy evaluate the tangent in a different order of operations only through A's rows: a
#: relative 1e-12 of the triad's values (|x| ≲ 10 m/s²) is far below any sensor's resolution.
TWIN_TOLERANCE = 1e-12


@pytest.mark.parametrize("temp_c", OUTSIDE_C)
def test_by_default_the_models_continue_along_their_tangent_for_one_span(scenario, artefact, temp_c):
    # The models here are of degree 1, so their tangent is the polynomial itself: within one span beyond
    # the edge the runtime equals the unclamped polynomial, beyond it the polynomial one span out. Both
    # OUTSIDE_C temperatures lie more than one span (20 °C) beyond the soaks, so both cases are seen.
    lo, hi = calibrated_range(artefact)
    span = CONTINUATION_SPANS * (hi - lo)
    edge = lo if temp_c < lo else hi
    data = static_recording(scenario, temp_c, seed=int(temp_c) + 200)
    unclamped = replace(artefact, thermal={k: replace(m, t_range=None) for k, m in artefact.thermal.items()})
    for target, expected_c in ((edge + 0.5 * (temp_c - edge), None), (temp_c, edge + np.sign(temp_c - edge) * span)):
        inputs = data.inputs()
        inputs[:, 9] = target
        at_expected = inputs.copy()
        at_expected[:, 9] = target if expected_c is None else expected_c
        # the gain/bias model alone: the bias learning at these rests (tests/test_bias_learning.py) is off
        out = batch_with(artefact, data.t, inputs, bias_learning=0.0)
        np.testing.assert_allclose(out[:, :6], batch_with(unclamped, data.t, at_expected, bias_learning=0.0)[:, :6],
                                   rtol=0, atol=TWIN_TOLERANCE)
        for k, triad in enumerate(("gyr", "acc")):
            twin = apply_thermal(artefact.thermal[triad], getattr(data, triad), inputs[:, 9])
            np.testing.assert_allclose(out[:, 3 * k:3 * k + 3], twin, rtol=0, atol=TWIN_TOLERANCE)
        assert np.all(out[:, CALIBRATION_VALID] == 0.0)


def excursion_recording(lo: float, hi: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, inputs, outside): a sensor at rest whose temperature visits the range edges, just
    beyond them, -20 °C and 70 °C; two excursion episodes below and above the range."""
    levels = [0.5 * (lo + hi), lo, lo - 0.1, OUTSIDE_C[0], lo, 0.5 * (lo + hi), hi, hi + 0.1, OUTSIDE_C[1],
              hi, 0.5 * (lo + hi)]
    temp = np.repeat(levels, 25)
    n = temp.size
    inputs = np.zeros((n, 14))
    inputs[:, 5], inputs[:, 6], inputs[:, 8], inputs[:, 9] = -9.80665, 25.0, 43.3, temp
    return np.arange(n) / RATE_HZ, inputs, (temp < lo) | (temp > hi)


def test_calibration_valid_is_zero_exactly_outside_the_range(artefact):
    t, inputs, outside = excursion_recording(*calibrated_range(artefact))
    np.testing.assert_array_equal(batch(artefact, t, inputs)[:, CALIBRATION_VALID], np.where(outside, 0.0, 1.0))


def test_the_fmu_warns_once_per_excursion_episode(artefact, tmp_path):
    t, inputs, outside = excursion_recording(*calibrated_range(artefact))
    fmu = build_fmu(coefficients_array(artefact), settings_dict(artefact), tmp_path / "ImuFusion.fmu")
    log: list[str] = []
    out = run_fmu(fmu, t, inputs, log=log)
    np.testing.assert_array_equal(out[:, CALIBRATION_VALID], np.where(outside, 0.0, 1.0))
    warnings = [m for m in log if m.startswith("[WARNING]") and "outside the calibrated range" in m]
    assert len(warnings) == 2, log
    lo, hi = calibrated_range(artefact)
    assert f"temperature {lo - 0.1:g} degC: outside the calibrated range of the gyroscope gain/bias model " \
           f"(temperature [{lo:g}, {hi:g}] degC)" in warnings[0], warnings[0]
    assert f"temperature {hi + 0.1:g} degC" in warnings[1], warnings[1]


def test_an_artefact_without_ranges_loads_unclamped_and_says_so(artefact, tmp_path):
    doc = artefact.to_json_dict()
    for triad in TRIAD_ORDER:
        del doc["thermal"][triad]["t_range"]
    path = tmp_path / "old.json"
    path.write_text(json.dumps(doc), encoding="utf-8")
    old = load_artefact(path)
    assert all(old.thermal[k].t_range is None for k in TRIAD_ORDER)
    assert sum("no calibrated temperature range (an artefact from before layout version 4)" in n
               for n in old.notes) == 3
    t, inputs, _ = excursion_recording(*calibrated_range(artefact))
    assert np.all(batch(old, t, inputs)[:, CALIBRATION_VALID] == 1.0)  # nothing known, nothing flagged


# ------------------------------------------------------------- the other models of the chain

def flags(coefficients, t, inputs, **settings) -> np.ndarray:
    return run_batch(np.asarray(coefficients), np.asarray(settings_array(settings)), t, inputs)[:, CALIBRATION_VALID]


def test_psobp_network_clamps_temperature_and_rate():
    model = random_model(np.random.default_rng(4), mode=MODE_RESIDUAL)  # trained on -10..45 °C, -0.02..0.08 °C/s
    temp, rate = np.array([-40.0, 90.0, 20.0, 20.0]), np.array([0.0, 0.0, -1.0, 1.0])
    np.testing.assert_array_equal(evaluate_psobp_c(model, temp, rate),
                                  evaluate_psobp_c(model, np.clip(temp, -10.0, 45.0), np.clip(rate, -0.02, 0.08)))
    t = np.arange(6.0)
    inputs = np.zeros((6, 14))
    inputs[:, 5], inputs[:, 6], inputs[:, 8] = -9.80665, 25.0, 43.3
    inputs[:, 9] = [20.0, 20.0, 20.0, 60.0, 60.0, 60.0]  # a 40 °C jump: rate and temperature leave the range
    coefficients = pack_coefficients([identity_block()] * 3, psobp=model.to_block())
    valid = flags(coefficients, t, inputs, enable_psobp=1.0)
    assert valid[0] == 1.0 and np.all(valid[3:] == 0.0)


def test_elm_corrects_a_field_outside_its_box_as_at_the_box_edge():
    rng = np.random.default_rng(2)
    field = rng.uniform(-30.0, 30.0, (400, 3))
    model = elm.ElmFitter(max_hidden=6, tune_steps=0).fit(field, 1.02 * field + 0.5, seed=0)
    block = elm.to_block(model)
    x = np.array([[80.0, 0.0, -5.0], [10.0, -70.0, 3.0], [1.0, 2.0, 3.0]])
    xc = np.clip(x, model.x_norm.lo, model.x_norm.hi)
    np.testing.assert_allclose(elm.c_apply(block, x), elm.c_apply(block, xc) + (x - xc), rtol=0, atol=1e-12)
    t = np.arange(3.0)
    inputs = np.zeros((3, 14))
    inputs[:, 5], inputs[:, 6:9], inputs[:, 9] = -9.80665, x, 25.0
    valid = flags(pack_coefficients([identity_block()] * 3, elm=block), t, inputs, enable_elm=1.0)
    np.testing.assert_array_equal(valid, [0.0, 0.0, 1.0])


def test_a_term_regressor_beyond_its_bounds_is_flagged():
    terms = terms_block([("gyr_z", "temp", None, 1e-4, 15.0, 35.0)])
    t = np.arange(3.0)
    inputs = np.zeros((3, 14))
    inputs[:, 5], inputs[:, 6], inputs[:, 8], inputs[:, 9] = -9.80665, 25.0, 43.3, [25.0, 40.0, 35.0]
    out = run_batch(np.asarray(pack_coefficients([identity_block()] * 3, terms)), np.asarray(settings_array()),
                    t, inputs)
    np.testing.assert_array_equal(out[:, CALIBRATION_VALID], [1.0, 0.0, 1.0])
    np.testing.assert_allclose(out[:, 2], [-25e-4, -35e-4, -35e-4], rtol=0, atol=1e-15)  # clamped at hi


def test_identity_model_is_always_valid():
    assert len(identity_block()) == TRIAD_BLOCK and identity_block()[-3:] == [0.0, 0.0, 0.0]
    t, inputs, _ = excursion_recording(15.0, 35.0)
    assert np.all(flags(identity_coefficients(), t, inputs) == 1.0)


def test_imufmu_run_counts_the_samples_outside_the_calibrated_range():
    from contract.layout import OUTPUTS
    from training.reports.run_summary import range_note
    out = np.zeros((200, len(OUTPUTS)))
    out[:, OUTPUTS.index("calibration_valid")] = 1.0
    assert range_note(out) is None
    out[150:, OUTPUTS.index("calibration_valid")] = 0.0
    assert range_note(out).startswith("calibration_valid = 0 in 50 of 200 samples (25 %)")
