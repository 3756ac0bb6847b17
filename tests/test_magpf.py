"""Magnetometer particle filter: PCG32, observation model, filter steps, C vs numpy, accuracy."""
from __future__ import annotations

from datetime import datetime

import numpy as np
import pytest

from contract import layout
from training import runtime
from training.models import magmoments as mm, magpf
from training.models.ellipsoid import apply_ellipsoid, fit_ellipsoid
from training.models.rng import Pcg32

# pcg32-demo (pcg-random.org, "Using the Full C Implementation"): seed 42, stream 54.
PCG32_REFERENCE = [0xA15C02B7, 0x7B47F409, 0xBA1D3330, 0x83D2F293, 0xBFA4784B, 0xCBED606E]
# C vs numpy: identical operations, but numpy's exp/log/tanh and its summation order may differ
# from the C library by an ulp; over 60 updates of 32 particles the states stay within 1e-9
# relative (observed ~1e-14). Weight thresholds could in principle flip on such a difference,
# which is why the comparison is over the first updates only.
TWIN_RTOL = 1e-9
# Identity: no hard/soft iron, prior spread 2 µT / 0.01: 20 s of tumbling determine the hard iron
# to ~0.05 µT (docs/magpf.md); 0.3 µT / 0.01 leave margin and stay well inside 1 % of |h_0|.
IDENTITY_HARD_BOUND_UT = 0.3
IDENTITY_SOFT_BOUND = 0.01
# Issue 3 acceptance, simulated, 20 seeds each (worst seed): hard-iron error <= 1 % of |h_0| =
# 0.6 µT per axis and RMS of |h_c| - |h_0| <= 0.5 % over the last 10 s, after 60 s from a zero
# prior and 30 s after a 20 µT hard-iron jump.
ACCEPTANCE_HARD_UT = 0.6
ACCEPTANCE_NORM_PERCENT = 0.5
ACCEPTANCE_SEEDS = 20
# Power sums: the binomial shift and the closed-form likelihood equal direct sums over the samples
# to rounding; relative 1e-9 on sums of ~1e9 µT^4.
MOMENTS_RTOL = 1e-9
# Batch ellipsoid fit on 60 s of tumbling with 0.25 µT noise: 6000 samples determine the 9
# parameters to ~0.01 µT; 0.05 µT / 0.001 leave margin.
ELLIPSOID_OFFSET_BOUND_UT = 0.05
ELLIPSOID_MATRIX_BOUND = 1e-3
# Held calibration: the jump test of the acceptance on 5 seeds (the 20-seed table is in docs/magpf.md).
HELD_SEEDS = 5
# The 9-state filter adapts from the start: on clean 30 s tumbling records from the trained prior it
# wanders by up to 0.39 µT (seeds 0–4), after the prior is taken back its re-drawn cloud
# re-converges within 0.7 µT; 1 µT still rejects an estimate kept from a disturbance (7–11 µT).
NINE_STATE_RETURN_UT = 1.0
# Ambient field growth that the change test must not take for a change of the carrier: 4 % of
# |h_0| makes the normalised residual ~(2·60·2.4/36)² ≈ 64, far above the threshold 25.
AMBIENT_GROWTH = 0.04


def test_pcg32_reference_values_python_and_c():
    rng = Pcg32(42, 54)
    assert [rng.next_u32() for _ in range(6)] == PCG32_REFERENCE
    assert magpf.rng_draw_c(42, 54, "u32", 6).astype(np.int64).tolist() == PCG32_REFERENCE


@pytest.mark.parametrize("kind", ["uniform", "normal"])
def test_generator_draws_identical_in_c_and_python(kind):
    rng = Pcg32(7, magpf.RNG_STREAM)
    py = rng.uniforms(1000) if kind == "uniform" else rng.normals(1000)
    np.testing.assert_array_equal(py, magpf.rng_draw_c(7, magpf.RNG_STREAM, kind, 1000))


def test_normal_draws_are_standard_normal():
    z = Pcg32(3, 54).normals(20000)
    # standard errors of mean and std over 20000 draws: 0.007 and 0.005; 5 sigma bounds.
    assert abs(z.mean()) < 0.035 and abs(z.std() - 1.0) < 0.025


def test_observation_equals_closed_form():
    rng = np.random.default_rng(0)
    x = np.column_stack([rng.normal(0, 20, (50, 3)), rng.normal(0, 0.05, (50, 6))])
    m = rng.normal(0, 40, (50, 3))
    b = magpf.soft_matrix(x[:, 3:])
    d = m - x[:, :3]
    quad = np.einsum("ni,nij,nj->n", d, b + np.swapaxes(b, 1, 2) + np.swapaxes(b, 1, 2) @ b, d)
    expanded = 2 * np.sum(x[:, :3] * m, axis=1) - np.sum(x[:, :3] ** 2, axis=1) - quad
    np.testing.assert_allclose(magpf.observation(x, m), expanded, rtol=0, atol=1e-9)


def test_observation_noise_moments_match_monte_carlo():
    sigma, norm = 0.5, 50.0
    rng = np.random.default_rng(1)
    h = norm * np.array([0.6, 0.0, 0.8])
    v = rng.normal(0, sigma, (400000, 3))
    y = np.sum((h + v) ** 2, axis=1) - norm ** 2
    mean, var = magpf.observation_noise_moments(sigma, norm)
    # standard error of the mean sqrt(var/4e5) = 0.08; of the variance ~0.3 %; 5 sigma bounds.
    assert abs(y.mean() - mean) < 0.4 and abs(y.var() / var - 1) < 0.015


def test_effective_sample_size_hill_number_and_split_plan():
    assert magpf.effective_sample_size(np.full(8, 1 / 8)) == pytest.approx(8.0)
    assert magpf.effective_sample_size([1, 0, 0, 0]) == pytest.approx(1.0)
    assert magpf.hill_number(np.zeros(10)) == pytest.approx(10.0)
    assert magpf.hill_number([0.0, -np.inf, -np.inf]) == pytest.approx(1.0)
    w = np.array([0.5, 0.3, 0.02, 0.02, 0.02, 0.02, 0.02, 0.05, 0.05])
    high, low, n = magpf.split_plan(w, 2.0 / 9, 0.5 / 9)    # high > 0.222, low < 0.0556
    assert high.tolist() == [0, 1] and low.tolist() == [2, 3, 4, 5, 6, 7, 8] and n == 3
    _, _, n = magpf.split_plan(np.full(9, 1 / 9), 2.0 / 9, 0.5 / 9)
    assert n == 0


def test_systematic_resampling_counts():
    w = np.array([0.1, 0.2, 0.3, 0.4])
    idx = magpf.systematic_indices(w, 0.5)           # offsets 0.125, 0.375, 0.625, 0.875
    assert idx.tolist() == [1, 2, 3, 3]
    counts = np.bincount(magpf.systematic_indices(np.full(5, 0.2), 0.999), minlength=5)
    assert counts.tolist() == [1, 1, 1, 1, 1]


@pytest.mark.parametrize("base, splitting, move, bins", [
    ("additions", 1, 1, 2), ("additions", 0, 1, 2), ("additions", 1, 0, 0), ("additions", 0, 0, 3),
    ("source", 1, 0, 0), ("source", 0, 0, 0), ("unclipped", 1, 1, 2)])
def test_c_equals_numpy_twin_first_updates(base, splitting, move, bins):
    # "source": the method with every addition off (no tempering, plain copies at resampling, no
    # buffer, no change test, inflation or clipping); "unclipped": the additions but glitch clipping
    method = {"additions": magpf.METHOD_WITH_ADDITIONS, "source": magpf.SOURCE_METHOD,
              "unclipped": {**magpf.METHOD_WITH_ADDITIONS, "glitch_clipping": 0}}[base]
    d = magpf.simulate_tumbling(0, duration_s=0.6)
    s = magpf.settings(60.0, pf_particles=32, pf_seed=5, **magpf.zero_prior(60.0),
                       **{**method, "enable_splitting": splitting, "enable_move": move,
                          "pf_sphere_bins": bins, "pf_decimation": 1})
    c, py = magpf.run_c(d.mag, s), magpf.run_python(d.mag, s)
    for a, b in ((c.hard_iron, py.hard_iron), (c.soft_iron, py.soft_iron), (c.neff, py.neff),
                 (c.compensated, py.compensated)):
        np.testing.assert_allclose(a, b, rtol=TWIN_RTOL, atol=TWIN_RTOL * 60.0)


@pytest.mark.parametrize("move, jump, prior, clipping", [(1, None, "zero", 1), (0, None, "zero", 1),
                                                         (1, 1.5, "zero", 1), (1, 1.5, "zero", 0),
                                                         (1, None, "held", 1)])
def test_c_equals_numpy_twin_rao_blackwell(move, jump, prior, clipping):
    # 16 particles, an update every 4th sample: ~75 updates with bridging, resampling, moves and
    # (jump) a declared change of environment; "held": the default prior (3 µT around zero) is
    # held until the data contradict it, then a change restarts the filter. The twin follows the
    # C code operation by operation.
    d = magpf.simulate_tumbling(6, duration_s=3.0, jump_at_s=jump)
    s = magpf.settings(60.0, pf_particles=16, pf_seed=9, pf_decimation=4, enable_move=move, glitch_clipping=clipping,
                       **(magpf.zero_prior(60.0) if prior == "zero" else {}))
    c, py = magpf.run_c(d.mag, s), magpf.run_python(d.mag, s)
    for a, b in ((c.hard_iron, py.hard_iron), (c.soft_iron, py.soft_iron), (c.neff, py.neff),
                 (c.compensated, py.compensated), (c.changes, py.changes)):
        np.testing.assert_allclose(a, b, rtol=TWIN_RTOL, atol=TWIN_RTOL * 60.0)


def _disturbed(d, start_s: float, duration_s: float, seed: int) -> np.ndarray:
    """d.mag with `duration_s` of independent wrong fields (random direction, norm 0.5–1.5 |h_0|)
    from `start_s`: long and varied enough to be declared a change of environment."""
    rng = np.random.default_rng(seed)
    mag = d.mag.copy()
    rows = slice(int(start_s * d.rate_hz), int((start_s + duration_s) * d.rate_hz))
    v = rng.normal(size=(rows.stop - rows.start, 3))
    mag[rows] = v / np.linalg.norm(v, axis=1)[:, None] * d.field_norm_ut * rng.uniform(0.5, 1.5, (len(v), 1))
    return mag


@pytest.mark.parametrize("rao_blackwell", [1, 0])
def test_c_equals_numpy_twin_through_a_declared_glitch_and_the_prior_taken_back(rao_blackwell):
    # 0.3 s of wrong fields at 0.5 s is declared a change (persistent evidence from many directions);
    # afterwards the prior calibration (the truth) explains the data and is taken back. Both steps
    # and the mode-0 buffer confirmation run identically in the twin.
    d = magpf.simulate_tumbling(8, duration_s=2.0)
    s = magpf.settings(60.0, pf_particles=16, pf_seed=3, pf_decimation=1, pf_rao_blackwell=rao_blackwell,
                       **magpf.trained_prior(d.hard_iron[0], d.soft_iron[0]))
    mag = _disturbed(d, 0.5, 0.3, 1)
    c, py = magpf.run_c(mag, s), magpf.run_python(mag, s)
    for a, b in ((c.hard_iron, py.hard_iron), (c.soft_iron, py.soft_iron), (c.neff, py.neff),
                 (c.compensated, py.compensated), (c.changes, py.changes)):
        np.testing.assert_allclose(a, b, rtol=TWIN_RTOL, atol=TWIN_RTOL * 60.0)
    assert c.changes[-1] >= 1
    if rao_blackwell:   # taken back: the held calibration again, bit for bit
        np.testing.assert_array_equal(c.hard_iron[-1], d.hard_iron[0])


@pytest.mark.parametrize("rao_blackwell", [1, 0])
def test_a_disturbance_declared_as_a_change_falls_back_to_the_trained_calibration(rao_blackwell):
    # 1 s of wrong fields (25 updates at decimation 4) is declared a change; 10 s later the trained
    # calibration (the truth ± 0.5 µT / 0.005) is back: held bit for bit (mode 1) or the 9-state
    # cloud re-drawn around it and adapting (mode 0, NINE_STATE_RETURN_UT). Before, both re-estimated
    # from the disturbance and kept what they found (7–11 µT off on these seeds).
    for seed in range(HELD_SEEDS):
        d = magpf.simulate_tumbling(seed, duration_s=30.0)
        s = magpf.settings(60.0, pf_seed=seed, pf_rao_blackwell=rao_blackwell, pf_decimation=4,
                           **magpf.trained_prior(d.hard_iron[0], d.soft_iron[0]))
        r = magpf.run_c(_disturbed(d, 10.0, 1.0, seed), s)
        after = int(21.0 * d.rate_hz)
        assert r.changes[-1] >= 1, seed
        error = np.abs(r.hard_iron[after:] - d.hard_iron[0]).max()
        assert error <= (0.0 if rao_blackwell else NINE_STATE_RETURN_UT), (seed, error)


def test_a_removed_magnet_returns_to_the_trained_calibration():
    # BROAD trial 32's defect: a magnet (20 µT hard iron) attached at 10 s and removed at 25 s; the
    # filter declares both changes and, after the removal, holds the trained calibration again
    # (exactly) instead of settling at a re-estimate of it.
    d = magpf.simulate_tumbling(1, duration_s=40.0)
    t = np.arange(len(d.mag)) / d.rate_hz
    mag = d.mag + np.where(((t >= 10.0) & (t < 25.0))[:, None], [20.0, 0.0, 0.0], 0.0)
    r = magpf.run_c(mag, magpf.settings(60.0, pf_seed=1, **magpf.trained_prior(d.hard_iron[0], d.soft_iron[0])))
    assert r.changes[-1] >= 2
    assert np.abs(r.hard_iron[int(20.0 * d.rate_hz)] - d.hard_iron[0] - [20.0, 0.0, 0.0]).max() <= ACCEPTANCE_HARD_UT
    np.testing.assert_array_equal(r.hard_iron[int(35.0 * d.rate_hz):], np.tile(d.hard_iron[0], (500, 1)))


def test_a_stuck_reading_is_not_a_change():
    # 1 s of one constant wrong reading (a stuck register) after convergence: a single direction is
    # no evidence of a carrier change (IMU_MAG_PF_CHANGE_DIRECTIONS), so nothing is declared and the
    # held calibration stays; before, four clipped updates declared a change.
    d = magpf.simulate_tumbling(4, duration_s=20.0)
    mag = d.mag.copy()
    mag[1000:1100] = [25.0, -30.0, 35.0]
    r = magpf.run_c(mag, magpf.settings(60.0, pf_seed=4, pf_decimation=2,
                                        **magpf.trained_prior(d.hard_iron[0], d.soft_iron[0])))
    assert r.changes[-1] == 0
    np.testing.assert_array_equal(r.hard_iron[-1], d.hard_iron[0])


def test_power_sums_shift_and_likelihood_equal_direct_sums():
    rng = np.random.default_rng(4)
    u = rng.normal(0.0, 40.0, (300, 3))
    p = np.array([3.0, -7.0, 11.0])
    shifted = mm.moments_shift(mm.power_sums(u), p)
    direct = mm.power_sums(u - p)
    np.testing.assert_allclose(shifted, direct, rtol=MOMENTS_RTOL, atol=MOMENTS_RTOL * max(map(abs, direct)))
    # the likelihood from the sums equals the Gaussian linear model evaluated on the samples
    sigma, norm = 0.4, 50.0
    prior = mm.MarginalPrior(np.zeros(3), 30.0, np.zeros(6), 0.1, norm ** 2 + 3 * sigma ** 2,
                             4 * norm ** 2 * sigma ** 2 + 6 * sigma ** 4, 0.01, 100.0)
    d = u - p
    phi = np.column_stack([d[:, 0] ** 2, 2 * d[:, 0] * d[:, 1], 2 * d[:, 0] * d[:, 2], d[:, 1] ** 2,
                           2 * d[:, 1] * d[:, 2], d[:, 2] ** 2])
    z = prior.offset - np.sum(d * d, axis=1)
    info = phi.T @ phi / prior.variance + np.eye(6) / prior.soft_spread ** 2
    eta = phi.T @ z / prior.variance
    m = np.linalg.solve(info, eta)
    expected = (-0.5 * (z @ z / prior.variance - eta @ m) - 0.5 * np.linalg.slogdet(info)[1]
                - 0.5 * np.sum((p / prior.hard_spread) ** 2))
    value, soft, ok = mm.marginal(mm.power_sums(u), p, prior)
    assert ok and value == pytest.approx(expected, rel=MOMENTS_RTOL)
    np.testing.assert_allclose(soft, m, rtol=1e-7, atol=1e-12)


def test_soft_iron_square_root_inverts_the_square():
    b = np.array([0.03, 0.05, -0.04, -0.02, 0.03, 0.04])
    np.testing.assert_allclose(mm.soft_from_quadratic(mm.quadratic_from_soft(b)), b, atol=1e-14)
    assert not mm.admissible(mm.quadratic_from_soft([0.5, 0, 0, 0, 0, 0]), 0.49, 1.69)


def _acceptance_figures(d, r) -> tuple[float, float]:
    """Hard-iron max-axis error at the end [µT] and norm RMS [%] of the noise-free distorted field
    over the last 10 s (the figures of docs/magpf.md)."""
    inv = np.linalg.inv(np.eye(3) + magpf.soft_matrix(d.soft_iron[0]))
    tail = slice(-int(10 * d.rate_hz), None)
    clean = (d.truth @ inv.T + d.hard_iron)[tail]
    est = np.column_stack([r.hard_iron, r.soft_iron])[tail]
    norm = np.linalg.norm(magpf.apply(est, clean), axis=1)
    rms = 100.0 * float(np.sqrt(np.mean((norm - d.field_norm_ut) ** 2))) / d.field_norm_ut
    return float(np.abs(r.hard_iron[-1] - d.hard_iron[-1]).max()), rms


@pytest.mark.parametrize("jump", [None, 30.0], ids=["zero-prior", "jump-20uT"])
def test_acceptance_over_20_seeds(jump):
    figures = []
    for seed in range(ACCEPTANCE_SEEDS):
        d = magpf.simulate_tumbling(seed, jump_at_s=jump)
        r = magpf.run_c(d.mag, magpf.settings(60.0, pf_seed=seed, **magpf.zero_prior(60.0)))
        figures.append(_acceptance_figures(d, r))
        if jump is not None:
            assert r.changes[-1] > r.changes[int(jump * d.rate_hz) - 1]   # the jump is declared
    worst = np.max(figures, axis=0)
    assert worst[0] <= ACCEPTANCE_HARD_UT and worst[1] <= ACCEPTANCE_NORM_PERCENT


def test_a_burst_of_glitches_neither_declares_a_change_nor_moves_the_estimate():
    # 16 corrupted readings (+25 µT on z, 0.16 s) after convergence: clipped in the change test and
    # kept out of the power sums, so the run ends where the clean run ends (within 0.05 µT, a
    # tenth of the acceptance bound) with the same number of declared changes.
    d = magpf.simulate_tumbling(2, duration_s=40.0)
    corrupted = d.mag.copy()
    corrupted[3000:3016, 2] += 25.0
    s = magpf.settings(60.0, pf_seed=2, **magpf.zero_prior(60.0))
    clean, glitched = magpf.run_c(d.mag, s), magpf.run_c(corrupted, s)
    assert glitched.changes[-1] == clean.changes[-1]
    assert np.abs(glitched.hard_iron[-1] - clean.hard_iron[-1]).max() < 0.05


def test_identity_estimate_stays_near_zero():
    d = magpf.simulate_tumbling(1, duration_s=20.0, hard_iron=(0, 0, 0), soft_iron=(0,) * 6)
    r = magpf.run_c(d.mag, magpf.settings(60.0, pf_prior_spread_hard=2.0, pf_prior_spread_soft=0.01, pf_hold_prior=0))
    assert np.abs(r.hard_iron[-500:]).max() < IDENTITY_HARD_BOUND_UT
    assert np.abs(r.soft_iron[-500:]).max() < IDENTITY_SOFT_BOUND


def test_held_calibration_is_exact_until_a_hard_iron_jump_then_reconverges():
    # A trained calibration (the truth, 0.5 µT / 0.005) is held bit for bit — no particle-mean
    # jitter — until a 20 µT hard-iron jump at 30 s is declared; 30 s later the bounds hold.
    for seed in range(HELD_SEEDS):
        d = magpf.simulate_tumbling(seed, jump_at_s=30.0)
        r = magpf.run_c(d.mag, magpf.settings(60.0, pf_seed=seed, **magpf.trained_prior(d.hard_iron[0], d.soft_iron[0])))
        before = slice(0, int(30.0 * d.rate_hz))
        assert np.all(r.hard_iron[before] == d.hard_iron[0]) and np.all(r.soft_iron[before] == d.soft_iron[0])
        assert r.changes[before.stop - 1] == 0 and r.changes[-1] >= 1
        hard, norm = _acceptance_figures(d, r)
        assert hard <= ACCEPTANCE_HARD_UT and norm <= ACCEPTANCE_NORM_PERCENT, (seed, hard, norm)


def test_a_held_calibration_the_data_contradict_from_the_start_is_a_change():
    # The default prior (3 µT around zero) on a sensor with a [30, 40, 20] µT hard iron: the held
    # calibration is the change test's baseline from the first update, so the mismatch is declared
    # at once and the filter converges to the bounds by the end of 60 s.
    d = magpf.simulate_tumbling(3)
    r = magpf.run_c(d.mag, magpf.settings(60.0, pf_seed=3))
    assert r.changes[int(5.0 * d.rate_hz)] >= 1
    hard, norm = _acceptance_figures(d, r)
    assert hard <= ACCEPTANCE_HARD_UT and norm <= ACCEPTANCE_NORM_PERCENT


def test_an_ambient_norm_drift_is_not_a_change_of_the_carrier():
    # The field around a calibrated sensor grows by 4 % over 40 s (walking into a stronger field):
    # the residual is then the same at every orientation, and its running mean (norm time constant
    # 300 updates = 12 s here) keeps it out of the change test; without that a change is declared.
    # A 3 µT hard-iron step (residual 2 h_p·h, orientation-dependent) is still declared.
    d = magpf.simulate_tumbling(0)
    inv = np.linalg.inv(np.eye(3) + magpf.soft_matrix(d.soft_iron[0]))
    noise = d.mag - (d.truth @ inv.T + d.hard_iron)
    t = np.arange(len(d.mag)) / d.rate_hz
    grow = 1.0 + AMBIENT_GROWTH * np.clip((t - 10.0) / 40.0, 0.0, 1.0)
    drifting = (d.truth * grow[:, None]) @ inv.T + d.hard_iron + noise
    stepped = d.mag + np.where(t[:, None] >= 30.0, [3.0, 0.0, 0.0], 0.0)
    s = magpf.settings(60.0, pf_seed=0, pf_decimation=4, **magpf.trained_prior(d.hard_iron[0], d.soft_iron[0]))
    assert magpf.run_c(drifting, s).changes[-1] == 0
    assert magpf.run_c(drifting, {**s, "norm_time_constant": 0.0}).changes[-1] >= 1
    assert magpf.run_c(stepped, s).changes[-1] >= 1


def test_deterministic_and_seed_dependent():
    d = magpf.simulate_tumbling(2, duration_s=5.0)
    a = magpf.run_c(d.mag, magpf.settings(60.0, pf_seed=11))
    b = magpf.run_c(d.mag, magpf.settings(60.0, pf_seed=11))
    c = magpf.run_c(d.mag, magpf.settings(60.0, pf_seed=12))
    np.testing.assert_array_equal(a.hard_iron, b.hard_iron)
    assert not np.array_equal(a.hard_iron, c.hard_iron)


def test_invalid_samples_are_skipped():
    d = magpf.simulate_tumbling(4, duration_s=1.0)
    bad = d.mag.copy()
    bad[10] = np.nan
    bad[20] = [1e6, 0, 0]
    bad[30] = 0.0
    s = magpf.settings(60.0)
    r = magpf.run_c(bad, s)
    assert np.all(np.isfinite(r.hard_iron)) and np.all(np.isfinite(r.neff))
    np.testing.assert_array_equal(r.hard_iron[10], r.hard_iron[9])
    np.testing.assert_array_equal(r.hard_iron[30], r.hard_iron[29])


@pytest.mark.parametrize("override, word", [
    ({"pf_particles": magpf.MAX_PARTICLES + 1}, "pf_particles"),
    ({"pf_measurement_noise": -1.0}, "pf_measurement_noise"),
    ({"pf_process_noise_hard": -0.1}, "pf_process_noise_hard"),
    ({"field_norm": 0.0}, "field_norm"),
    ({"pf_threshold_low": 1.5}, "pf_threshold_low"),
    ({"hidden_units": 9}, "hidden_units"),
    ({"hidden_units": 2.5}, "hidden_units"),
    ({"pf_sphere_bins": magpf.MAX_BIN_SIDE + 1}, "pf_sphere_bins"),
    ({"change_threshold": 1.0}, "change_threshold"),
    ({"enable_move": 2}, "enable_move"),
    ({"enable_tempering": 2}, "enable_tempering"),
    ({"resample_roughening": 0.5}, "resample_roughening"),
    ({"glitch_clipping": -1}, "glitch_clipping"),
    ({"pf_rao_blackwell": 2}, "pf_rao_blackwell"),
    ({"pf_hold_prior": 2}, "pf_hold_prior"),
    ({"pf_settle_spread": -1.0}, "pf_settle_spread"),
    ({"norm_time_constant": -1.0}, "norm_time_constant"),
    ({"pf_prior_spread_hard": 0.0}, "pf_prior_spread_hard"),
    ({"pf_min_rotation": 2.0}, "pf_min_rotation"),
])
def test_invalid_settings_rejected_with_message(override, word):
    s = {**magpf.settings(50.0), **override}
    assert word in magpf.check_settings_c(s)
    with pytest.raises(ValueError, match=word):
        magpf.run_c(np.zeros((2, 3)), s)
    if "pf_particles" in override:
        assert str(magpf.MAX_PARTICLES) in magpf.check_settings_c(s)


def test_ellipsoid_fit_recovers_hard_and_soft_iron():
    d = magpf.simulate_tumbling(0)
    fit = fit_ellipsoid(d.mag, 60.0)
    assert np.abs(fit.offset - d.hard_iron[0]).max() < ELLIPSOID_OFFSET_BOUND_UT
    truth = np.eye(3) + magpf.soft_matrix(d.soft_iron[0])
    assert np.abs(fit.matrix - truth).max() < ELLIPSOID_MATRIX_BOUND
    np.testing.assert_allclose(fit.matrix, fit.matrix.T)
    assert fit.residual < 0.5 and apply_ellipsoid(fit, d.mag).shape == d.mag.shape


def test_geomag_matches_published_igrf_value():
    pytest.importorskip("ppigrf")
    from training.data.geomag import earth_field
    # NOAA IGRF calculator, Berlin (52.5 N, 13.3 E), 2020-06-01: F ≈ 49.8 µT, I ≈ 67.9°,
    # D ≈ 4.3° E; 0.3 µT / 0.3° allow for altitude and model-revision differences.
    f = earth_field(52.5, 13.3, 0.05, datetime(2020, 6, 1))
    assert abs(f.norm_ut - 49.8) < 0.3 and abs(f.dip_deg - 67.9) < 0.3
    assert abs(f.declination_deg - 4.3) < 0.3


def test_settings_are_the_fmu_parameters_and_the_c_filters_internal_settings():
    """One vocabulary: field_norm and the pf_* parameters with the variable table's defaults, then
    the internal settings the C filter names (ImuMagPfInternal), none of them an FMU name."""
    internal = [name for name, _, _ in magpf.internal_settings()]
    fmu_defaults = layout.settings_defaults()
    assert all(internal) and len(set(internal)) == len(internal)
    assert not set(internal) & set(fmu_defaults)
    s = magpf.settings(50.0)
    assert list(s) == list(magpf.setting_names())
    assert {n: s[n] for n in magpf.FMU_SETTINGS if n != "field_norm"} == \
        {n: fmu_defaults[n] for n in magpf.FMU_SETTINGS if n != "field_norm"}


def test_batch_entry_and_fmu_chain_run_the_same_filter_from_the_same_settings():
    """ImuBatchMagPfRun builds its settings with the pipeline's own mapping (ImuPipelinePfSettings):
    on the raw field of an identity model the chain's hard-iron outputs equal the batch filter's
    bit for bit (pf_min_rotation in rad on both paths)."""
    d = magpf.simulate_tumbling(3, duration_s=4.0)
    n = len(d.mag)
    t = np.arange(n) / d.rate_hz
    inputs = np.column_stack([np.zeros((n, 3)), np.tile([0.0, 0.0, -9.81], (n, 1)), d.mag, np.full(n, 25.0),
                              np.zeros((n, len(layout.AUX_INPUTS)))])
    pf = {"pf_particles": 32.0, "pf_decimation": 2.0, "pf_min_rotation": 0.01, **magpf.zero_prior(d.field_norm_ut)}
    out = runtime.run_batch(layout.identity_coefficients(),
                            layout.settings_array({"enable_pf": 1.0, "field_norm": d.field_norm_ut, **pf}), t, inputs)
    chain = out[:, [layout.OUTPUTS.index(f"hard_iron_{a}") for a in "xyz"]]
    np.testing.assert_array_equal(chain, magpf.run_c(d.mag, magpf.settings(d.field_norm_ut, **pf)).hard_iron)
