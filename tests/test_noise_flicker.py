"""The simulator's bias instability (issue 34): a flicker-like bias made of FLICKER_TERMS first-order
Gauss–Markov processes (τ_k = 10^(k/2) s, σ_k = 0.6125 B) whose Allan deviation is the IEEE 952 floor
0.664 B, flat within ±4 % from 10 s to 1000 s; drawn from its own stream, so a sensor without it
(bias_instability = 0, the default) simulates bit for bit as before."""
from __future__ import annotations

import allantools
import numpy as np

from training.simulator.sensors import FLICKER_TERMS, SensorModel, TriadErrors, flicker_bias, flicker_stream

#: The floor's flatness the construction promises (the C virtual sensor relies on it).
FLOOR_TOLERANCE = 0.04
#: 40 independent 28 h series at 1 Hz: the Allan variance at 1000 s then has ≈ 40 × 2 × 100 / 3 ≈ 2700
#: equivalent degrees of freedom, a 1σ error of 1.4 % on the deviation — below the ±4 % promised.
SERIES, SAMPLES, RATE_HZ = 40, 100_000, 1.0
TAUS = np.array([10.0, 31.6, 100.0, 316.0, 1000.0])


def test_flicker_floor_is_flat_at_0664_b_from_10_to_1000_s():
    b = 2.0e-4
    x = flicker_bias(SAMPLES, RATE_HZ, b, np.random.default_rng(0), axes=SERIES)
    avar = np.mean([allantools.oadev(x[:, i], rate=RATE_HZ, data_type="freq", taus=TAUS)[1] ** 2
                    for i in range(SERIES)], axis=0)
    floor = np.sqrt(2.0 * np.log(2.0) / np.pi) * b
    assert np.all(np.abs(np.sqrt(avar) / floor - 1.0) < FLOOR_TOLERANCE), np.sqrt(avar) / floor


def test_flicker_starts_at_zero_and_draws_n_minus_1_times_terms_normals_per_axis():
    rng = np.random.default_rng(1)
    x = flicker_bias(50, 100.0, 1.0, rng, axes=2)
    assert np.all(x[0] == 0.0)
    twin = np.random.default_rng(1)
    twin.standard_normal((49, 2, FLICKER_TERMS))
    assert rng.bit_generator.state == twin.bit_generator.state


def _triad(bias_instability: float) -> TriadErrors:
    z = np.zeros(3)
    return TriadErrors(bias=z, bias_t1=z, bias_t2=z, scale=z, scale_t1=z, scale_t2=z, misalignment=np.zeros((3, 3)),
                       temp_rate=z, noise_density=1e-3, bias_walk=1e-4, lsb=1e-12, full_scale=1e3,
                       bias_instability=bias_instability)


def test_zero_bias_instability_draws_nothing_and_other_noise_stays_bit_identical():
    from training.simulator.sensors import MagDistortion
    n = 2000
    truth, temp = np.zeros((n, 3)), np.full(n, 25.0)
    mag = MagDistortion(np.zeros(3), np.eye(3), np.zeros((3, 3)), 50.0)
    plain = SensorModel("plain", _triad(0.0), _triad(0.0), _triad(0.0), mag)
    flicker = SensorModel("flicker", _triad(3e-4), _triad(0.0), _triad(0.0), mag)
    seed = 7
    a = plain.measure(truth, truth, truth, temp, np.zeros(n), 100.0, np.random.SeedSequence(seed))
    b = flicker.measure(truth, truth, truth, temp, np.zeros(n), 100.0, np.random.SeedSequence(seed))
    # acc and mag untouched, gyro = the same white noise and walk + the flicker of its own stream
    assert np.array_equal(a[1], b[1]) and np.array_equal(a[2], b[2])
    expected = flicker_bias(n, 100.0, 3e-4, flicker_stream(np.random.SeedSequence(seed), 0))
    assert np.allclose(b[0] - a[0], expected, atol=1e-11)
    # B = 0 leaves a flicker stream handed over untouched
    stream = np.random.default_rng(5)
    state = stream.bit_generator.state
    _triad(0.0).apply(truth, temp, np.zeros(n), 100.0, np.random.default_rng(0), flicker_rng=stream)
    assert stream.bit_generator.state == state


def test_scenario_key_sets_bias_instability_in_si(tmp_path):
    from training.simulator.scenario import read_toml, sensor_from_raw
    from training.main_job import SCENARIO_DIR
    raw = read_toml(SCENARIO_DIR / "sensors" / "mems_grade.toml")
    raw["gyr"]["bias_instability_dps"] = 0.002
    raw["acc"]["bias_instability_ms2"] = 5e-4
    sensor = sensor_from_raw(raw, tmp_path / "s.toml")
    assert sensor.gyr.bias_instability == np.deg2rad(0.002) and sensor.acc.bias_instability == 5e-4
    assert sensor.mag.bias_instability == 0.0
