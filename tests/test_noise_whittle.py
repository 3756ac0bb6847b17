"""The Whittle fit and its Cramér–Rao bound (training.noise.whittle): the limit on K that
benchmarks/noise_recovery.py --limit measures and docs/noise.md quotes."""
from __future__ import annotations

import numpy as np

from training.noise.whittle import cramer_rao, expected_basis, periodogram, whittle_fit
from training.simulator.sensors import flicker_bias

RATE_HZ = 100.0
#: white noise density, bias instability, random walk of the synthetic unit [u/√Hz, u, u/√s]
N, B, K = 5e-5, 3.5e-5, 3e-6


def _series(n: int, rng: np.random.Generator) -> np.ndarray:
    white = rng.standard_normal(n) * N * np.sqrt(RATE_HZ)
    walk = np.cumsum(rng.standard_normal(n) * K / np.sqrt(RATE_HZ))
    return white + walk + flicker_bias(n, RATE_HZ, B, rng, axes=1)[:, 0]


def test_expected_periodogram_is_the_mean_tapered_periodogram():
    # white noise and random walk only (each its own unit), 2000 samples, 2000 draws: 2.2 % 1σ per bin
    rng = np.random.default_rng(0)
    n, draws = 2001, 2000
    mean = np.zeros((2, (n - 2) // 2))
    for _ in range(draws):
        mean[0] += periodogram(rng.standard_normal(n) * np.sqrt(RATE_HZ)) / draws
        mean[1] += periodogram(np.cumsum(rng.standard_normal(n) / np.sqrt(RATE_HZ))) / draws
    expected = expected_basis(n - 1, RATE_HZ)[[0, 2]]
    low = slice(0, 10)  # where the white noise's leakage would show
    assert np.all(np.abs(mean[:, low] / expected[:, low] - 1.0) < 0.1), mean[:, low] / expected[:, low]
    assert abs(np.mean(mean / expected) - 1.0) < 0.01


def test_whittle_fit_reads_k_within_its_bound_on_one_hour():
    hours = 1.0
    n = int(hours * 3600 * RATE_HZ)
    bound = cramer_rao(n, RATE_HZ, N, B, K)
    errors = []
    for seed in range(4):
        x = _series(n, np.random.default_rng(seed))
        fit = whittle_fit([x - x.mean()], RATE_HZ, (1.2 * N, 0.8 * B, 1.5 * K))
        errors.append(np.log([fit.noise_density / N, fit.bias_instability / B, fit.random_walk / K]))
    errors = np.array(errors)
    # each figure within 3.5 of its bound's 1σ, and their RMS within 2 of it
    assert np.all(np.abs(errors) < 3.5 * bound), (errors, bound)
    assert np.all(np.sqrt(np.mean(errors ** 2, axis=0)) < 2.0 * bound), (errors, bound)


def test_cramer_rao_of_the_mems_grade_gyro_at_3_h():
    # benchmarks/noise_recovery.py's mems_grade gyro: no estimator reads its K within 10 % at 1σ from 3 h
    deg = np.pi / 180.0
    sigma = cramer_rao(int(3 * 3600 * RATE_HZ), RATE_HZ, 0.003 * deg, 0.002 * deg, 2e-4 * deg)
    assert 0.0005 < sigma[0] < 0.002
    assert 0.12 < sigma[2] < 0.17, sigma


def test_whittle_fit_without_a_long_enough_stretch_is_none():
    assert whittle_fit([np.zeros(5)], RATE_HZ, (N, B, K)) is None
