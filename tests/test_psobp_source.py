"""PSO-BP in the source's form (issue 4, issue 18 item 2): every switch does what it says, the
source's form differs from the product, and the defaults are the product's fit."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from test_psobp import DPS, synthetic_static
from training.bench.compare_thermal import FORM_ROWS, FULL, MODELS, SOURCE
from training.models.psobp import (ADDITIONS, MODE_FULL, MODE_RESIDUAL, SOURCE_FORM, PsoBpFitter, PsoBpModel,
                                   _batched_losses, backpropagate, bias_targets, cumulative_forms,
                                   evaluate_psobp, product_form, pso_minimise)

torch.set_num_threads(1)
#: A fit small enough for a unit test (about 0.1 s) that still runs every stage.
SMALL = dict(particles=8, pso_iterations=5, epochs=100)
#: A stopping rule that ends the SMALL fit of `series` early (after 48 of its 100 epochs).
EARLY = dict(patience=10, tolerance=0.05)


@pytest.fixture(scope="module")
def series():
    return synthetic_static(8, duration_s=1000.0)[:4]


def _fit(series, stop=None, **switches):
    fitter = PsoBpFitter(**SMALL, **(stop or {}), **{k: v for k, v in switches.items() if k != "clamp_inputs"})
    return fitter.fit(*series, seed=3)


def test_forms_go_from_the_source_to_the_product_one_switch_at_a_time():
    rows = cumulative_forms()
    assert {**rows[0][1], "clamp_inputs": rows[0][2]} == SOURCE_FORM
    assert {**rows[-1][1], "clamp_inputs": rows[-1][2]} == product_form()
    assert [s for s, _ in ADDITIONS] == list(SOURCE_FORM)  # every switch added once
    for (_, a, ca), (_, b, cb), (switch, _) in zip(rows, rows[1:], ADDITIONS):
        changed = {k for k in a if a[k] != b[k]} | ({"clamp_inputs"} if ca != cb else set())
        assert changed == {switch}
    assert product_form(window_s=5.0)["window_s"] == 5.0
    assert MODELS[MODELS.index(SOURCE):MODELS.index(SOURCE) + len(FORM_ROWS)] == FORM_ROWS
    assert FORM_ROWS[-1].startswith(FULL)


@pytest.mark.parametrize("mode", [MODE_FULL, MODE_RESIDUAL])
def test_product_values_passed_explicitly_give_the_default_fit_bit_for_bit(series, mode):
    default = PsoBpFitter(mode=mode, **SMALL).fit(*series, seed=3)
    explicit = PsoBpFitter(mode=mode, **SMALL, **{k: v for k, v in product_form().items()
                                                  if k != "clamp_inputs"}).fit(*series, seed=3)
    assert explicit.model.to_block() == default.model.to_block()
    assert (explicit.epochs, explicit.loss_end) == (default.epochs, default.loss_end)


@pytest.mark.parametrize("switch", [s for s, _ in ADDITIONS if s != "clamp_inputs"])
def test_each_fit_switch_in_its_source_form_changes_the_fit(series, switch):
    stop = EARLY if switch == "early_stop" else None
    default = _fit(series, stop).model.to_block()
    assert _fit(series, stop, **{switch: SOURCE_FORM[switch]}).model.to_block() != default


def test_the_source_form_differs_from_the_product_and_still_fits(series):
    t, gyr, ref, temp = series
    product, source = _fit(series), _fit(series, **SOURCE_FORM)
    assert source.model.to_block() != product.model.to_block()
    assert source.epochs == SMALL["epochs"]  # no patience stop
    assert source.windows == int(np.sum(np.all(np.isfinite(gyr), axis=1)))  # single samples
    # Plain gradient descent lowers the loss on every axis.
    assert all(end < start for start, end in zip(source.loss_start, source.loss_end))


def test_single_sample_targets_are_the_static_rows():
    t, gyr, ref, temp, _ = synthetic_static(2, duration_s=200.0)
    ref = ref.copy()
    ref[::4] = 1.0  # moving rows are not targets
    temp_s, rate_s, bias_s = bias_targets(t, gyr, ref, temp, 10.0, None, 1e-3)
    static = np.arange(t.shape[0]) % 4 != 0
    np.testing.assert_array_equal(bias_s, gyr[static] - ref[static])
    np.testing.assert_array_equal(temp_s, temp[static])
    assert rate_s.shape == temp_s.shape


def test_gradient_descent_step_is_theta_minus_lr_times_the_gradient():
    rng = np.random.default_rng(4)
    hidden, lr = 3, 0.05
    u, y = rng.uniform(-1, 1, (40, 2)), rng.uniform(-1, 1, (40, 3))
    theta0 = rng.uniform(-1, 1, (3, 4 * hidden + 1))

    def loss(theta):
        return float(_batched_losses(torch.from_numpy(theta), torch.from_numpy(u), torch.from_numpy(y),
                                     hidden).sum())

    step = 1e-6  # central differences: error O(step²) ~ 1e-12, round-off ~ 1e-16 / step ~ 1e-10
    grad = np.zeros_like(theta0)
    for idx in np.ndindex(theta0.shape):
        e = np.zeros_like(theta0)
        e[idx] = step
        grad[idx] = (loss(theta0 + e) - loss(theta0 - e)) / (2 * step)
    result = backpropagate(theta0, u, y, hidden, 1, lr, 50, 1e-3, rule="gd", early_stop=False)
    np.testing.assert_allclose(result.theta, theta0 - lr * grad, rtol=0, atol=1e-9)
    with pytest.raises(ValueError, match="BP rule"):
        PsoBpFitter(bp_rule="adam")


def test_without_early_stop_the_whole_budget_runs():
    rng = np.random.default_rng(5)
    u = rng.uniform(-1, 1, (30, 2))
    y = np.column_stack([np.sin(3 * u[:, 0])] * 3)
    theta0 = rng.uniform(-1, 1, (3, 9))
    stopped = backpropagate(theta0, u, y, 2, 500, 0.01, EARLY["patience"], EARLY["tolerance"])
    full = backpropagate(theta0, u, y, 2, 500, 0.01, EARLY["patience"], EARLY["tolerance"], early_stop=False)
    assert stopped.epochs < 500 and full.epochs == 500


def test_swarm_without_clamp_leaves_the_box():
    centre = np.array([2.0, -2.5])  # outside the box [-1, 1]² (the start range)

    def bowl(x):
        return np.sum((x - centre) ** 2, axis=1)

    boxed = pso_minimise(bowl, 2, np.random.default_rng(3), iterations=150, bound=1.0)
    free = pso_minimise(bowl, 2, np.random.default_rng(3), iterations=150, bound=1.0, clamp=False)
    np.testing.assert_allclose(boxed.best, [1.0, -1.0])  # the box corner nearest the centre
    # 150 iterations with w -> 0.4 contract the swarm far below this on a 2-D bowl.
    np.testing.assert_allclose(free.best, centre, atol=1e-3)


def test_unclamped_inputs_extrapolate_the_formula():
    w1, b1 = np.full((3, 1, 2), 0.5), np.zeros((3, 1))
    model = PsoBpModel(MODE_FULL, 1, 10.0, 0.0, 10.0, -1.0, 1.0, w1, b1, np.full((3, 1), DPS), np.zeros(3))
    temp, rate = np.array([20.0]), np.array([0.0])  # 20 °C: u0 = 3, outside [-1, 1]
    by_hand = DPS * np.tanh(0.5 * 3.0 + 0.5 * 0.0)
    np.testing.assert_allclose(evaluate_psobp(model, temp, rate, clamp_inputs=False), [[by_hand] * 3],
                               rtol=1e-15)
    np.testing.assert_allclose(evaluate_psobp(model, temp, rate), [[DPS * np.tanh(0.5)] * 3], rtol=1e-15)
