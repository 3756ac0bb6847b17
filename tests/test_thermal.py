"""Gain/bias temperature model: formula, block layout and the Rprop fit against truth."""
import numpy as np
import pytest

from contract.layout import MAX_DEGREE, TRIAD_BLOCK, identity_block
from training.models.thermal import GainBiasFitter, ThermalModel, apply_thermal

#: Horner (apply_thermal) vs explicit power sums (direct_evaluation) differ only by rounding:
#: a few ulp of values O(1..100), so 1e-13 relative is ~500 ulp of headroom.
APPLY_RTOL = 1e-13
#: Noise-free recovery: the fit stops when every Rprop step is below 1e-12 (normalised), and
#: the measured coefficient errors are ~1e-11; 1e-8 (A, g dimensionless; b relative to the
#: bias scale) still proves exact recovery, 1e6 below the ~1e-2 effects being fitted.
RECOVERY_TOL = 1e-8
#: With output noise σ the residual RMS estimates σ from 3N = 18000 values: relative std
#: 1/sqrt(2*18000) = 0.5 %, and the 21 fitted coefficients remove ~0.1 %; 2 % is ~4 std.
NOISE_RATIO_TOL = 0.02
#: Optimiser comparison at one iteration budget (150), measured on the mag data below:
#: Rprop reaches a max coefficient error of 7e-11; plain SGD at lr 1.0 reaches 6e-5
#: (lr 0.5: 3e-3; lr 1.3, tuned to the edge: 5e-6; lr 1.6 diverges).
BUDGET = 150
SGD_LR = 1.0
RPROP_BUDGET_TOL = 1e-8
SGD_MIN_RATIO = 1e3

N_ROWS = 6000
T_LOW, T_HIGH = -20.0, 60.0   # °C; t0 = 20, ts = 40 exactly when both ends are sampled
#: triad -> (unit, reference scale, bias scale): rate table rad/s, specific force m/s², µT.
TRIADS = {"gyr": ("rad/s", 1.0, 0.01), "acc": ("m/s²", 9.81, 0.2), "mag": ("µT", 50.0, 5.0)}


def true_model(bias_scale: float) -> ThermalModel:
    """A symmetric with ~0.01 off-diagonals, G ~1 % over the range, B offset+slope+curvature."""
    a = np.array([[1.02, 0.01, -0.008], [0.01, 0.985, 0.012], [-0.008, 0.012, 1.01]])
    g = np.array([[0.006, -0.003], [-0.005, 0.004], [0.004, 0.002]])
    b = bias_scale * np.array([[1.0, 0.3, -0.1], [-0.8, 0.2, 0.15], [0.5, -0.4, 0.1]])
    return ThermalModel(True, 0.5 * (T_LOW + T_HIGH), 0.5 * (T_HIGH - T_LOW), 2, a, g, b)


def gains_biases(model: ThermalModel, temp: np.ndarray):
    """G, B (N, 3) by explicit powers Tn**k (independent of the Horner code)."""
    tn = np.nan_to_num((temp - model.t0) / model.ts, nan=0.0)
    gain = 1.0 + sum(model.g[:, k - 1][None, :] * tn[:, None] ** k
                     for k in range(1, model.degree + 1))
    bias = sum(model.b[:, k][None, :] * tn[:, None] ** k for k in range(model.degree + 1))
    return gain * np.ones((len(temp), 3)), bias


def direct_evaluation(model: ThermalModel, x: np.ndarray, temp: np.ndarray) -> np.ndarray:
    """x_c = A (G ⊙ (x − B)) by matrix product and power sums."""
    gain, bias = gains_biases(model, temp)
    return (model.A @ (gain * (x - bias)).T).T


def invert(model: ThermalModel, x_c: np.ndarray, temp: np.ndarray) -> np.ndarray:
    """Raw triad producing x_c: x = B + (A⁻¹ x_c) / G."""
    gain, bias = gains_biases(model, temp)
    return bias + np.linalg.solve(model.A, x_c.T).T / gain


def synthetic(model, scale, seed, noise=0.0):
    """(raw, ref, temp): random references of RMS `scale`, temperatures spanning
    [T_LOW, T_HIGH], raw from the model inverse applied to ref + N(0, noise²)."""
    rng = np.random.default_rng(seed)
    ref = scale * rng.standard_normal((N_ROWS, 3))
    temp = np.linspace(T_LOW, T_HIGH, N_ROWS)
    raw = invert(model, ref + noise * rng.standard_normal(ref.shape), temp)
    return raw, ref, temp


def coefficient_errors(fitted: ThermalModel, truth: ThermalModel, bias_scale: float):
    """Max abs errors of A, g and (b / bias_scale)."""
    return (np.abs(fitted.A - truth.A).max(), np.abs(fitted.g - truth.g).max(initial=0.0),
            np.abs(fitted.b - truth.b).max() / bias_scale)


def random_model(degree: int, seed: int, enabled: bool = True) -> ThermalModel:
    """A random model of the given degree (A symmetrised)."""
    rng = np.random.default_rng(seed)
    a = np.eye(3) + 0.02 * rng.standard_normal((3, 3))
    return ThermalModel(enabled, 23.0, 17.0, degree, 0.5 * (a + a.T),
                        0.01 * rng.standard_normal((3, degree)),
                        rng.standard_normal((3, degree + 1)))


def test_identity_changes_nothing():
    rng = np.random.default_rng(1)
    x = 30.0 * rng.standard_normal((500, 3))
    temp = rng.uniform(-40.0, 85.0, 500)
    temp[::7] = np.nan
    assert np.array_equal(apply_thermal(ThermalModel.identity(), x, temp), x)
    assert ThermalModel.identity().to_block() == identity_block()


def test_disabled_model_passes_through():
    x = np.random.default_rng(2).standard_normal((50, 3))
    assert np.array_equal(apply_thermal(random_model(3, 3, enabled=False), x, np.zeros(50)), x)


@pytest.mark.parametrize("degree", range(MAX_DEGREE + 1))
def test_apply_matches_direct_evaluation(degree):
    rng = np.random.default_rng(10 + degree)
    model = random_model(degree, degree)
    x = 40.0 * rng.standard_normal((1000, 3))
    temp = rng.uniform(-40.0, 85.0, 1000)
    temp[::11] = np.nan
    np.testing.assert_allclose(apply_thermal(model, x, temp), direct_evaluation(model, x, temp),
                               rtol=APPLY_RTOL, atol=0)


def test_nan_temperature_means_t0():
    model = random_model(3, 4)
    x = np.random.default_rng(5).standard_normal((20, 3))
    at_nan = apply_thermal(model, x, np.full(20, np.nan))
    assert np.array_equal(at_nan, apply_thermal(model, x, np.full(20, model.t0)))


@pytest.mark.parametrize("degree", range(MAX_DEGREE + 1))
def test_block_round_trip(degree):
    model = random_model(degree, 20 + degree)
    block = model.to_block()
    assert len(block) == TRIAD_BLOCK
    back = ThermalModel.from_block(block)
    assert back.to_block() == block
    for name in ("A", "g", "b"):
        assert np.array_equal(getattr(back, name), getattr(model, name))


@pytest.mark.parametrize("edit, problem", [
    (lambda b: b[:-1], "shape"),
    (lambda b: [b[0], b[1], b[2], 4.0] + b[4:], "degree"),
    (lambda b: [0.5] + b[1:], "enabled"),
    (lambda b: b[:-4] + [1.0] + b[-3:], "above degree"),  # the last b entry, before the range
])
def test_from_block_rejects_malformed(edit, problem):
    with pytest.raises(ValueError, match=problem):
        ThermalModel.from_block(edit(random_model(2, 6).to_block()))


@pytest.mark.parametrize("triad", TRIADS)
def test_recovers_known_coefficients(triad):
    unit, scale, bias_scale = TRIADS[triad]
    truth = true_model(bias_scale)
    raw, ref, temp = synthetic(truth, scale, seed=7)
    fit = GainBiasFitter(degree=2).fit(raw, ref, temp, seed=0, unit=unit)
    assert fit.converged and fit.unit == unit and fit.rows_dropped == 0
    assert (fit.model.t0, fit.model.ts) == (truth.t0, truth.ts)
    assert np.array_equal(fit.model.A, fit.model.A.T)
    assert max(coefficient_errors(fit.model, truth, bias_scale)) < RECOVERY_TOL
    assert fit.rms_after < RECOVERY_TOL * fit.rms_before


@pytest.mark.parametrize("triad", TRIADS)
def test_noisy_residual_is_noise(triad):
    unit, scale, bias_scale = TRIADS[triad]
    sigma = 0.01 * scale
    raw, ref, temp = synthetic(true_model(bias_scale), scale, seed=8, noise=sigma)
    fit = GainBiasFitter(degree=2).fit(raw, ref, temp, seed=0, unit=unit)
    assert abs(fit.rms_after / sigma - 1.0) < NOISE_RATIO_TOL


def test_drops_nonfinite_rows_and_keeps_nan_temperature():
    unit, scale, bias_scale = TRIADS["acc"]
    truth = true_model(bias_scale)
    raw, ref, temp = synthetic(truth, scale, seed=9)
    temp[5::50] = np.nan                    # the model at Tn = 0 holds for these rows
    raw[5::50] = invert(truth, ref[5::50], temp[5::50])
    raw[3::100, 1] = np.nan
    ref[4::100, 2] = np.inf
    fit = GainBiasFitter(degree=2).fit(raw, ref, temp, seed=0, unit=unit)
    assert fit.rows_dropped == 2 * N_ROWS // 100
    assert fit.rows_used == N_ROWS - fit.rows_dropped
    assert max(coefficient_errors(fit.model, truth, bias_scale)) < RECOVERY_TOL


def test_all_nan_temperature_fits_degree_zero():
    unit, scale, _ = TRIADS["mag"]
    a = np.array([[1.03, 0.02, 0.0], [0.02, 0.97, -0.01], [0.0, -0.01, 1.0]])
    truth = ThermalModel(True, 25.0, 1.0, 0, a, np.zeros((3, 0)), [[3.0], [-2.0], [7.0]])
    rng = np.random.default_rng(11)
    ref = scale * rng.standard_normal((N_ROWS, 3))
    temp = np.full(N_ROWS, np.nan)
    fit = GainBiasFitter(degree=3).fit(invert(truth, ref, temp), ref, temp, seed=0, unit=unit)
    assert (fit.model.degree, fit.model.t0, fit.model.ts) == (0, 25.0, 1.0)
    assert max(coefficient_errors(fit.model, truth, 1.0)) < RECOVERY_TOL


def test_rprop_beats_plain_sgd_at_equal_budget():
    unit, scale, bias_scale = TRIADS["mag"]
    truth = true_model(bias_scale)
    raw, ref, temp = synthetic(truth, scale, seed=12)
    rprop = GainBiasFitter(iterations=BUDGET, tolerance=0.0).fit(raw, ref, temp, 0, unit)
    sgd = GainBiasFitter(iterations=BUDGET, lr=SGD_LR, optimizer="sgd").fit(raw, ref, temp, 0, unit)
    assert rprop.iterations == sgd.iterations == BUDGET
    rprop_error = max(coefficient_errors(rprop.model, truth, bias_scale))
    sgd_error = max(coefficient_errors(sgd.model, truth, bias_scale))
    assert rprop_error < RPROP_BUDGET_TOL
    assert sgd_error > SGD_MIN_RATIO * rprop_error
    assert sgd.loss_history[-1] > SGD_MIN_RATIO * rprop.loss_history[-1]


def test_divergent_descent_is_reported():
    unit, scale, bias_scale = TRIADS["mag"]
    raw, ref, temp = synthetic(true_model(bias_scale), scale, seed=12)
    with pytest.raises(ValueError, match="diverged"):
        GainBiasFitter(iterations=BUDGET, lr=10.0, optimizer="sgd").fit(raw, ref, temp, 0, unit)


def test_fitter_rejects_bad_hyperparameters_and_empty_data():
    with pytest.raises(ValueError, match="degree"):
        GainBiasFitter(degree=MAX_DEGREE + 1)
    with pytest.raises(ValueError, match="optimizer"):
        GainBiasFitter(optimizer="adam")
    nan = np.full((4, 3), np.nan)
    with pytest.raises(ValueError, match="no row"):
        GainBiasFitter().fit(nan, nan, np.zeros(4), seed=0, unit="µT")
