"""Noise characterisation by Allan deviation (issue 34 item 1, training.noise): recovery of N, B and
K on simulated static logs against the simulator's truth, the support flags on short data, the
imufusion-noise/1 block's shape, the quantisation step and Kalibr's imu.yaml."""
from __future__ import annotations

import numpy as np
import pytest
import yaml

from training.data.dataset import ImuData
from training.noise.characterise import FORMAT, characterise, quantisation_lsb
from training.noise.kalibr import imu_yaml_text
from training.simulator.sensors import flicker_bias

RATE_HZ = 100.0
#: 30 min at 100 Hz of white noise N and random walk K (K's line meets the white one at
#: τc = √3 N/K ≈ 8.7 s, so the longest τ, 200 s, is 23 τc).
N_TRUE, K_TRUE = 5e-4, 1e-4
#: N is pinned by the short τ (edf ~ 10⁵): over 20 seeds × 3 axes its worst error was 0.5 %; 2 % leaves 4x.
N_BOUND = 0.02
#: K rests on the few long τ (edf ≈ 8 at 200 s): over 20 seeds × 3 axes its errors spread with σ = 9 %,
#: worst −28 % / +20 %; 30 % is the worst case of that sample, not a typical one.
K_BOUND = 0.30
#: 30 min of white noise plus a flicker floor of B: the floor dominates from τ ≈ 2 s (where it meets the
#: white line) to the longest τ, 200 s; the generator's floor is flat within ±4 % from 10 s on
#: (test_noise_flicker), so B within 15 % (IEEE 952 reading, 0.664 B) leaves room for the scatter of
#: the few long τ.
B_TRUE = 5e-4
B_BOUND = 0.15


def _static(x: dict[str, np.ndarray], rate_hz: float = RATE_HZ, name: str = "static") -> ImuData:
    """A static recording (sidecar reference 'static') of the given triads (N, 3); others all-NaN."""
    n = len(next(iter(x.values())))
    nan3 = np.full((n, 3), np.nan)
    return ImuData(t=np.arange(n) / rate_hz, gyr=x.get("gyr", nan3), acc=x.get("acc", nan3.copy()),
                   mag=x.get("mag", nan3.copy()), temp=np.full(n, 25.0),
                   meta={"rate_hz": rate_hz, "reference": "static"}, name=name)


def _noise(seconds: float, n_density: float, k_walk: float = 0.0, b: float = 0.0, seed: int = 0) -> np.ndarray:
    """(n, 3) white noise of density n_density [u/√Hz] + random walk k_walk [u/√s] + flicker B [u]."""
    rng = np.random.default_rng(seed)
    n = int(seconds * RATE_HZ)
    x = rng.standard_normal((n, 3)) * n_density * np.sqrt(RATE_HZ)
    x += np.cumsum(rng.standard_normal((n, 3)) * k_walk / np.sqrt(RATE_HZ), axis=0)
    if b > 0:
        x += flicker_bias(n, RATE_HZ, b, rng)
    return x


@pytest.fixture(scope="module")
def half_hour():
    """The block of a 30 min static gyro with N_TRUE and K_TRUE (seed 0)."""
    return characterise([_static({"gyr": _noise(1800.0, N_TRUE, K_TRUE)})]).block


def test_noise_density_and_random_walk_are_recovered_from_half_an_hour(half_hour):
    for axis in half_hour["triads"]["gyr"]["axes"]:
        n, k = axis["noise_density"], axis["random_walk"]
        assert n["supported"] and k["supported"], (n["why"], k["why"])
        assert abs(n["value"] / N_TRUE - 1.0) < N_BOUND
        assert abs(k["value"] / K_TRUE - 1.0) < K_BOUND
        assert n["ci"][0] < n["value"] < n["ci"][1] and k["ci"][0] < k["value"] < k["ci"][1]
        # white noise and a random walk only: no floor to read
        assert not axis["bias_instability"]["supported"]


def test_bias_instability_is_recovered_where_the_floor_shows():
    block = characterise([_static({"gyr": _noise(1800.0, N_TRUE, b=B_TRUE, seed=1)})]).block
    for axis in block["triads"]["gyr"]["axes"]:
        b = axis["bias_instability"]
        assert b["supported"], b["why"]
        assert abs(b["value"] / B_TRUE - 1.0) < B_BOUND


def test_block_has_the_contract_shape(half_hour):
    assert set(half_hour) == {"format", "source", "rate_hz", "still_seconds", "longest_still_seconds", "triads"}
    assert half_hour["format"] == FORMAT and half_hour["rate_hz"] == RATE_HZ
    assert half_hour["still_seconds"] == pytest.approx(1800.0) and half_hour["longest_still_seconds"] == pytest.approx(1800.0)
    assert set(half_hour["triads"]) == {"gyr"}  # acc and mag are all-NaN: left out
    gyr = half_hour["triads"]["gyr"]
    assert set(gyr) == {"unit", "lsb", "axes"} and gyr["unit"] == "rad/s" and len(gyr["axes"]) == 3
    units = {"noise_density": "rad/s/√Hz", "bias_instability": "rad/s", "random_walk": "rad/s/√s"}
    for axis in gyr["axes"]:
        assert set(axis) == set(units)
        for name, f in axis.items():
            assert set(f) == {"value", "ci", "unit", "supported", "why"} and f["unit"] == units[name]
            assert np.isfinite(f["value"]) and len(f["ci"]) == 2 and all(np.isfinite(f["ci"]))
            assert (f["why"] == "") == f["supported"]


def test_short_data_flags_bias_instability_and_random_walk():
    # 20 s: τ reaches 2.2 s, far below where a floor or a random walk of these sizes could show
    block = characterise([_static({"gyr": _noise(20.0, N_TRUE, K_TRUE, b=B_TRUE, seed=2)})]).block
    for axis in block["triads"]["gyr"]["axes"]:
        assert axis["noise_density"]["supported"]
        assert abs(axis["noise_density"]["value"] / N_TRUE - 1.0) < 0.1
        for name in ("bias_instability", "random_walk"):
            assert not axis[name]["supported"], name
            assert "longest still stretch" in axis[name]["why"] and "20 s" in axis[name]["why"], axis[name]["why"]


def test_no_still_data_flags_everything_with_finite_values():
    # a recording in constant fast motion has no rest: nothing can be said, and it is said
    n = 3000
    t = np.arange(n) / RATE_HZ
    rng = np.random.default_rng(3)
    gyr = np.column_stack([np.sin(2 * t), np.cos(3 * t), np.sin(5 * t)]) + rng.normal(0, 1e-3, (n, 3))
    acc = np.column_stack([np.sin(t), np.cos(t), -9.81 + 0 * t]) * 3 + rng.normal(0, 1e-2, (n, 3))
    data = ImuData(t=t, gyr=gyr, acc=acc, mag=np.full((n, 3), np.nan), temp=np.full(n, 25.0),
                   meta={"rate_hz": RATE_HZ}, name="moving")
    block = characterise([data]).block
    assert block["still_seconds"] == 0.0
    for triad in ("gyr", "acc"):
        for axis in block["triads"][triad]["axes"]:
            for f in axis.values():
                assert not f["supported"] and f["why"] and f["value"] == 0.0


def test_quantisation_step_is_found_when_the_values_show_one():
    x = _noise(60.0, 1e-3)
    lsb = 2.0 ** -12
    assert quantisation_lsb([_static({"gyr": lsb * np.round(x / lsb)})], "gyr") == pytest.approx(lsb, rel=1e-9)
    assert quantisation_lsb([_static({"gyr": x})], "gyr") is None


def test_imu_yaml_has_kalibr_keys_with_the_worst_supported_axis(half_hour):
    block = dict(half_hour)
    block["triads"] = dict(half_hour["triads"])
    text = imu_yaml_text(block)
    doc = yaml.safe_load(text)
    assert set(doc) == {"gyroscope_noise_density", "gyroscope_random_walk", "rostopic", "update_rate"}
    axes = half_hour["triads"]["gyr"]["axes"]
    assert doc["gyroscope_noise_density"] == pytest.approx(max(a["noise_density"]["value"] for a in axes), rel=1e-5)
    assert doc["gyroscope_random_walk"] == pytest.approx(max(a["random_walk"]["value"] for a in axes), rel=1e-5)
    assert doc["update_rate"] == RATE_HZ and doc["rostopic"] == "/imu0"
    # one comment line per axis figure, its CI in it
    for i in range(3):
        assert f"gyr {'xyz'[i]} noise_density = " in text
    # an unsupported figure is left out, with a comment saying why
    short = characterise([_static({"gyr": _noise(20.0, N_TRUE, K_TRUE, seed=4),
                                   "acc": _noise(20.0, 1e-3, seed=5)})]).block
    doc = yaml.safe_load(imu_yaml_text(short))
    assert "gyroscope_random_walk" not in doc and "accelerometer_random_walk" not in doc
    assert "accelerometer_noise_density" in doc and "gyroscope_noise_density" in doc
    assert "# gyroscope_random_walk omitted: no axis supports it (" in imu_yaml_text(short)


def test_a_gauss_markov_bump_is_named_and_white_noise_is_not():
    # a first-order Gauss–Markov process (τc = 2 s, σ = 1e-3) on white noise: its Allan bump peaks near
    # 1.9 τc at 0.62 σ, 2.5x the white line there; the three-term model bends its floor and walk around
    # it and then misses the data by > 20 % from τ ≈ 25 s on, which the note names
    from scipy.signal import lfilter
    n, tau_c, sigma = int(1800 * RATE_HZ), 2.0, 1e-3
    a = np.exp(-1.0 / (RATE_HZ * tau_c))
    bump = lfilter([sigma * np.sqrt(1 - a * a)], [1.0, -a], np.random.default_rng(9).standard_normal((n, 3)), axis=0)
    white = _noise(1800.0, N_TRUE, seed=8)
    notes = characterise([_static({"gyr": white + bump})]).notes
    assert len(notes) == 3 and all("correlated component" in note for note in notes), notes
    assert characterise([_static({"gyr": white})]).notes == []


def test_ten_minutes_of_a_floor_and_the_start_of_a_walk_do_not_support_k():
    # benchmarks/noise_recovery.py's mems_grade gyro, seed 1, first 10 min: the x axis bottoms out at
    # τ ≈ 20 s and rises to its longest τ, 67 s; the fit, seeing the floor and the walk's start over less
    # than a decade, drops the floor and reads K 2.6x the truth. The curve's rise after its bottom spans
    # a factor ~3 < RANDOM_WALK_FROM_BOTTOM: K is flagged, not reported
    from training.main_job import SCENARIO_DIR
    from training.simulator.scenario import read_toml, sensor_from_raw
    from training.simulator.sensors import flicker_stream
    from dataclasses import replace
    mems = sensor_from_raw(read_toml(SCENARIO_DIR / "sensors" / "mems_grade.toml"), SCENARIO_DIR / "s.toml").gyr
    zero = {f: np.zeros(3) for f in ("bias", "bias_t1", "bias_t2", "scale", "scale_t1", "scale_t2", "temp_rate")}
    gyro = replace(mems, **zero, misalignment=np.zeros((3, 3)), bias_instability=np.deg2rad(0.002))
    n = int(3 * 3600 * RATE_HZ)  # the benchmark draws 3 h (the white noise follows the walk's n draws)
    root = np.random.SeedSequence([1, 0])
    x = gyro.apply(np.zeros((n, 3)), np.full(n, 25.0), np.zeros(n), RATE_HZ, np.random.default_rng(root.spawn(2)[0]),
                   flicker_rng=flicker_stream(root, 0))[:int(600 * RATE_HZ)]
    block = characterise([_static({"gyr": x})]).block
    k = block["triads"]["gyr"]["axes"][0]["random_walk"]
    assert not k["supported"] and "bottom" in k["why"], k
    assert all(not a["random_walk"]["supported"] for a in block["triads"]["gyr"]["axes"])
