"""The virtual sensor (sources/ImuSensor.c, the ImuSensor FMU): the trained chain run backwards returns the
truth through the correction chain, its lags delay, its noise has the figures asked for, it is seeded and its
FMU state restores, and its FMU validates."""
from __future__ import annotations

import numpy as np
import pytest

from contract import layout
from contract.errors import ModelError
from fmu.cosim import initialised_fmu, run_named, Stepper
from fmu.sensor_fmu import pack_sensor_fmu
from fmu.validator import validate_fmu
from fmu_cases import trained_coefficients
from test_elm import small_fitter, synthetic
from test_psobp import random_model
from training.models import elm
from training.runtime import run_batch
from training.sensor.build import anticausal_terms, leading_triads, noise_plan

#: The chain's inverses: the gain/bias(T) model exactly (three probes, a 3 x 3 solve), the ELM and the terms to
#: IMU_SENSOR_TOLERANCE = 1e-13 relative; then the forward chain's rounding. 1e-9 of a unit is far below any noise.
ROUND_TRIP_TOLERANCE = 1e-9
RAW = tuple(f"{s}_{a}" for s in ("gyr", "acc", "mag") for a in "xyz")
RATE = 100.0
#: Terms of every kind the diagnosis writes: a cross-axis gain, a product of two triads, a temperature
#: slope, a lag (the corrector subtracts -0.015 s x the time derivative: it advances a gyro that lags by
#: 0.015 s, longer than the 0.01 s sample interval, which a fixed point would not invert), an auxiliary input.
TERMS = [("gyr_x", "acc_x", None, 2e-3), ("mag_y", "gyr_z", "gyr_z", 0.5), ("acc_z", "temp", None, 1e-3),
         ("gyr_y", "d_gyr_y", None, -0.015), ("mag_x", "aux_1", None, 0.3)]
CHAIN = {"enable_thermal": 1.0, "enable_elm": 1.0, "enable_psobp": 1.0, "enable_pf": 0.0, "bias_learning": 0.0,
         "mount_x": 1.0, "mount_y": -2.0, "mount_z": -3.0}


def rich_coefficients() -> np.ndarray:
    """Thermal models on every triad (tests/fmu_cases.py), the TERMS, a PSO-BP network and a fitted ELM."""
    base = trained_coefficients()
    thermal = [list(base[layout.OFFSET_THERMAL + k * layout.TRIAD_BLOCK:
                         layout.OFFSET_THERMAL + (k + 1) * layout.TRIAD_BLOCK]) for k in range(3)]
    terms = layout.terms_block([(*term, -1e300, 1e300) for term in TERMS])
    field, truth, _, _ = synthetic(800, 3)
    model = small_fitter(max_hidden=8).fit(field, truth, seed=0)
    psobp = random_model(np.random.default_rng(5)).to_block()
    return np.array(layout.pack_coefficients(thermal, terms, elm=list(elm.to_block(model)), psobp=psobp))


def truth(n: int = 800) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Times and a true motion: turning and tilting, field of a turning body, a temperature ramp (-5..40 °C
    across the thermal models' and the network's ranges) and a sine on aux_1."""
    t = np.arange(n) / RATE
    s = t / t[-1]
    rate = np.column_stack([0.6 * np.sin(2.1 * t), 0.4 * np.cos(1.3 * t), 0.8 * np.sin(0.7 * t)])
    accel = np.column_stack([1.5 * np.sin(t), -2.0 * np.cos(0.5 * t), -9.80665 + 0.5 * np.sin(3 * t)])
    field = np.column_stack([25.0 * np.cos(0.4 * t), -20.0 * np.sin(0.4 * t), 40.0 + 2 * np.sin(t)])
    inputs = {f"true_{name}_{a}": v[:, i] for name, v in (("rate", rate), ("accel", accel), ("field", field))
              for i, a in enumerate("xyz")}
    inputs["true_temp"] = -5.0 + 45.0 * s
    inputs["aux_1"] = np.sin(0.9 * t)
    return t, inputs


@pytest.fixture(scope="module")
def rich(tmp_path_factory):
    """The rich chain's coefficients and its sensor FMUs (FMI 2, 3) with the noise parameters of a MEMS unit."""
    coefficients = rich_coefficients()
    folder = tmp_path_factory.mktemp("sensor")
    noise = {"gyr_noise_density_x": 1e-3, "gyr_random_walk_y": 1e-4, "gyr_bias_instability_z": 2e-3,
             "acc_noise_density_z": 2e-3, "mag_noise_density_x": 0.1, "gyr_lsb": 1e-5}
    fmus = {v: pack_sensor_fmu(coefficients, CHAIN, noise, folder / f"s{v}.fmu", v) for v in (2, 3)}
    return coefficients, fmus


def corrected(coefficients: np.ndarray, settings: dict, t: np.ndarray, raw: np.ndarray, inputs: dict) -> np.ndarray:
    """The batch runtime's corrected rate, specific force and field (body axes) of the raw sensor outputs."""
    aux = np.column_stack([inputs.get(name, np.zeros(t.size)) for name in layout.AUX_INPUTS])
    out = run_batch(coefficients, layout.settings_array(settings), t, np.column_stack([raw, inputs["true_temp"], aux]))
    first = layout.OUTPUTS.index("rate_x")
    return out[:, first:first + 9]


def stacked(inputs: dict) -> np.ndarray:
    return np.column_stack([inputs[f"true_{name}_{a}"] for name in ("rate", "accel", "field") for a in "xyz"])


@pytest.mark.parametrize("version", [2, 3])
def test_noise_free_sensor_through_the_correction_chain_returns_the_truth(rich, version):
    coefficients, fmus = rich
    t, inputs = truth()
    raw = run_named(fmus[version], t, inputs, RAW, {"noise": False, "field_from_attitude": False})
    back = corrected(coefficients, CHAIN, t, raw, inputs)
    assert np.max(np.abs(back - stacked(inputs))) < ROUND_TRIP_TOLERANCE
    # the chain is not the identity: the raw outputs are far from the truth
    assert np.max(np.abs(raw - stacked(inputs))) > 0.05


def test_fmi2_and_fmi3_give_the_same_noisy_recording_and_the_seed_decides_it(rich):
    _, fmus = rich
    t, inputs = truth(300)
    a2 = run_named(fmus[2], t, inputs, RAW, {"seed": 11})
    assert np.array_equal(a2, run_named(fmus[3], t, inputs, RAW, {"seed": 11}))
    assert np.array_equal(a2, run_named(fmus[2], t, inputs, RAW, {"seed": 11}))
    assert not np.array_equal(a2, run_named(fmus[2], t, inputs, RAW, {"seed": 12}))


@pytest.fixture(scope="module")
def lagged(tmp_path_factory):
    """A sensor FMU of the identity chain whose gyro lags true time by 0.023 s (lag_gyr)."""
    return pack_sensor_fmu(np.array(layout.identity_coefficients()), {"lag_gyr": 0.023}, {},
                           tmp_path_factory.mktemp("lagged") / "lag.fmu", 2)


def test_a_lag_delays_the_triad_by_the_lag(lagged):
    """lag_gyr = 0.023 s (the input lags true time): the sensor's gyro is the truth 0.023 s earlier, linearly
    interpolated between samples, once the delay line reaches that far."""
    t, inputs = truth(400)
    raw = run_named(lagged, t, inputs, RAW, {"noise": False, "field_from_attitude": False})
    expected = np.interp(t - 0.023, t, inputs["true_rate_x"])
    assert np.max(np.abs(raw[5:, 0] - expected[5:])) < 1e-12
    assert np.max(np.abs(raw[:, 3:] - stacked(inputs)[:, 3:])) < 1e-12   # the other triads are not delayed


def test_the_field_from_the_attitude_is_the_earth_field_in_body_axes(lagged):
    """A body yawed 90° (east) and level: the field's north component lies along body -y."""
    fmu = lagged
    t = np.arange(3) / RATE
    half = np.full(3, np.pi / 4)   # half the 90° yaw
    inputs = {"true_q_w": np.cos(half), "true_q_z": np.sin(half), "true_temp": np.full(3, 25.0)}
    raw = run_named(fmu, t, inputs, RAW, {"noise": False, "field_norm": 50.0, "field_dip": np.radians(60.0),
                                          "declination": 0.0})
    np.testing.assert_allclose(raw[0, 6:], [0.0, -25.0, 50.0 * np.sin(np.radians(60.0))], atol=1e-12)


def test_white_noise_and_random_walk_have_the_figures_asked_for(rich):
    """gyr x: density 1e-3 rad/s/√Hz -> σ = 1e-2 rad/s per 0.01 s sample; 20000 samples estimate σ to 0.5 %
    (1/√(2n)): bound 3 %. gyr y, random walk only (1e-4 rad/s/√s): its sample-to-sample increments have
    σ = K √h = 1e-5 rad/s, estimated to the same 0.5 %; the 1e-5 rad/s LSB adds a rounding error of σ 1e-5/√6
    to each difference (+8 % in variance, +4 % in σ): bound 5 % above, 3 % below. Every gyro output is a
    multiple of the LSB; a triad axis without figures has no noise."""
    _, fmus = rich
    n = 20000
    t = np.arange(n) / RATE
    inputs = {"true_temp": np.full(n, 25.0), "true_accel_z": np.full(n, -9.80665), "true_q_w": np.ones(n)}
    raw = run_named(fmus[2], t, inputs, RAW, {"seed": 3})
    noise_free = run_named(fmus[2], t, inputs, RAW, {"noise": False})
    e = raw - noise_free
    assert abs(np.std(e[:, 0]) / (1e-3 * np.sqrt(RATE)) - 1.0) < 0.03
    ratio = np.std(np.diff(e[:, 1])) / (1e-4 / np.sqrt(RATE))
    assert 0.97 < ratio < 1.05 + 0.04
    lsb = raw[:, :3] / 1e-5
    assert np.max(np.abs(lsb - np.round(lsb))) < 1e-6
    assert np.allclose(e[:, 4], 0.0) and np.std(e[:, 5]) > 0   # acc z has noise, acc y none


def test_the_fmu_state_restores_the_noise_and_the_delay_line(rich):
    _, fmus = rich
    t, inputs = truth(200)
    names = list(inputs)
    values = np.column_stack([inputs[k] for k in names])
    for version in (2, 3):
        with initialised_fmu(fmus[version], parameters={"seed": 4}, instance_name="ImuSensor") as fmu:
            stepper = Stepper(fmu, names, RAW)
            fmi3 = version == 3
            for k in range(100):
                stepper.set_inputs(values[k])
                stepper.do_step(t[k], 0.01)
            state = fmu.getFMUState() if fmi3 else fmu.getFMUstate()
            first = []
            for k in range(100, 200):
                stepper.set_inputs(values[k])
                stepper.do_step(t[k], 0.01)
                first.append(stepper.get_outputs())
            (fmu.setFMUState if fmi3 else fmu.setFMUstate)(state)
            again = []
            for k in range(100, 200):
                stepper.set_inputs(values[k])
                stepper.do_step(t[k], 0.01)
                again.append(stepper.get_outputs())
            assert np.array_equal(np.array(first), np.array(again))


def test_the_sensor_fmus_validate(rich):
    for fmu in rich[1].values():
        assert validate_fmu(fmu) == []


def test_a_noise_figure_outside_its_range_is_refused_in_one_line(tmp_path):
    with pytest.raises(ModelError, match="gyr_noise_density_x = -1 is outside"):
        pack_sensor_fmu(np.array(layout.identity_coefficients()), {}, {"gyr_noise_density_x": -1.0},
                        tmp_path / "bad.fmu", 2)


def test_the_noise_plan_takes_supported_figures_and_names_the_others():
    supported = {"value": 2e-4, "ci": [1.9e-4, 2.1e-4], "unit": "rad/s/√Hz", "supported": True, "why": ""}
    unsupported = {"value": 0.0, "ci": [0.0, 0.0], "unit": "rad/s", "supported": False,
                   "why": "needs 300 s of still data; the longest still stretch is 1.5 s"}
    axis = {"noise_density": supported, "bias_instability": unsupported, "random_walk": unsupported}
    block = {"format": "imufusion-noise/1", "source": "rests", "triads": {"gyr": {"unit": "rad/s", "lsb": 1e-5,
                                                                                "axes": [axis, axis, axis]}}}
    plan = noise_plan(block)
    assert plan.parameters == {"gyr_noise_density_x": 2e-4, "gyr_noise_density_y": 2e-4,
                               "gyr_noise_density_z": 2e-4, "gyr_lsb": 1e-5}
    assert "gyr bias_instability x: needs 300 s of still data; the longest still stretch is 1.5 s" in plan.unsupported
    assert any(line.startswith("acc:") for line in plan.unsupported)
    assert noise_plan(None).parameters == {} and "no noise characterisation" in noise_plan(None).unsupported[0]


def test_a_term_that_delays_a_triad_longer_than_half_a_sample_is_named():
    """The corrector's c · dx/dt with c > 0 delays the triad; its inverse (pole (c/h)/(1 - c/h) at interval h)
    diverges from c = h/2 on: at 100 Hz 0.015 s is named, 0.004 s and any advance (c < 0) are not."""
    terms = [{"target": "gyr_y", "a": "d_gyr_y", "b": None, "coefficient": c} for c in (0.015, 0.004, -0.015)]
    lines = anticausal_terms(terms, 100.0)
    assert len(lines) == 1 and "0.015 s delays the triad" in lines[0]


def test_the_plan_takes_the_quantisation_out_of_the_white_noise_it_adds_back():
    """Measured white noise holds the LSB's rounding (σ² = lsb²/12 per sample); the sensor rounds itself, so its
    density parameter is √(N² − lsb²/(12 fs)): 2e-4 rad/s/√Hz with a 1e-3 rad/s LSB at 100 Hz -> 1.979e-4."""
    figure = {"value": 2e-4, "ci": [0.0, 0.0], "unit": "rad/s/√Hz", "supported": True, "why": ""}
    axis = {"noise_density": figure}
    block = {"rate_hz": 100.0, "triads": {"gyr": {"lsb": 1e-3, "axes": [axis, axis, axis]}}}
    assert noise_plan(block).parameters["gyr_noise_density_y"] == pytest.approx(np.sqrt(4e-8 - 1e-6 / 1200.0), rel=1e-12)


def test_the_flicker_bias_matches_the_simulators_and_its_floor(lagged):
    """B = 1e-3 rad/s alone, 2 h at 10 Hz, seeds 0-3: the C sensor's overlapping Allan deviation at τ = 10, 31.6,
    100 s (mean over the seeds) and the simulator's flicker_bias (training/simulator/sensors.py, the same
    construction, numpy's generator) both lie on the floor √(2 ln2/π)·B and agree. One seed's deviation at
    100 s has ~50 degrees of freedom (±10 %); four seeds ±5 %, the ratio of the two ±7 %: bound 15 % (2σ)."""
    import allantools
    from training.simulator.sensors import flicker_bias
    rate, n, b = 10.0, 72000, 1e-3
    t = np.arange(n) / rate
    taus = np.array([10.0, 31.6, 100.0])
    c_dev, py_dev = [], []
    for seed in range(4):
        raw = run_named(lagged, t, {"true_temp": np.full(n, 25.0)}, ["gyr_x"],
                        {"seed": seed, "gyr_bias_instability_x": b})[:, 0]
        c_dev.append(allantools.oadev(raw, rate=rate, data_type="freq", taus=taus)[1])
        py = flicker_bias(n, rate, b, np.random.default_rng(seed), axes=1)[:, 0]
        py_dev.append(allantools.oadev(py, rate=rate, data_type="freq", taus=taus)[1])
    floor = np.sqrt(2.0 * np.log(2.0) / np.pi) * b
    c_mean, py_mean = np.mean(c_dev, axis=0), np.mean(py_dev, axis=0)
    assert np.all(np.abs(c_mean / floor - 1.0) < 0.15) and np.all(np.abs(py_mean / floor - 1.0) < 0.15)
    assert np.all(np.abs(c_mean / py_mean - 1.0) < 0.15)


def test_a_leading_triad_is_named_and_the_outputs_before_the_first_sample_are_nan(lagged):
    assert leading_triads({"lag_gyr": -0.015, "lag_acc": 0.0, "lag_mag": 0.02}) == [
        "lag_gyr = -0.015 s: the gyr leads true time; the sensor extrapolates the truth that far (exact only where it "
        "changes linearly)"]
    with initialised_fmu(lagged, instance_name="ImuSensor") as fmu:
        assert all(np.isnan(v) for v in Stepper(fmu, [], RAW).get_outputs())
