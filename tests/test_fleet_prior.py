"""The fleet prior (training.models.prior): the maximum a posteriori gain/bias fit.

Truth: a simulated triad with a known degree-1 model. Data at one temperature cannot show the
temperature slope; the prior supplies it, and a vague prior leaves the data's own fit.
"""
import json

import numpy as np
import pytest

from contract.errors import ModelError
from training.models.prior import MIN_PRIOR_UNITS, TriadPrior, build_prior, load_prior, parameter_count, theta
from training.models.thermal import GainBiasFitter, ThermalModel, apply_thermal

#: The true model: gains ~1 %, bias 0.5 + 0.2 Tn (Tn = (T − 20) / 15) in the triad's unit.
TRUE = ThermalModel(True, 20.0, 15.0, 1, np.eye(3) + np.diag([0.01, -0.01, 0.005]),
                    np.array([[0.002], [0.001], [-0.001]]), np.array([[0.5, 0.2], [-0.3, 0.1], [0.4, -0.2]]))
NOISE = 0.01


def _data(temp_c: float, rows: int = 3000, seed: int = 0):
    """(raw, reference, temperature) of TRUE at one temperature: references spread over directions."""
    rng = np.random.default_rng(seed)
    ref = rng.standard_normal((rows, 3)) * 2.0
    temp = np.full(rows, temp_c)
    # invert TRUE: raw = G⁻¹ ∘ (A⁻¹ ref) + B
    tn = (temp_c - TRUE.t0) / TRUE.ts
    gain = 1.0 + TRUE.g[:, 0] * tn
    bias = TRUE.b[:, 0] + TRUE.b[:, 1] * tn
    raw = (np.linalg.solve(TRUE.A, ref.T).T) / gain + bias + NOISE * rng.standard_normal((rows, 3))
    return raw, ref, temp


def _prior(scale: float) -> TriadPrior:
    """A prior centred on TRUE with σ = scale × |θ| + 1e-3."""
    mean = theta(TRUE, 1)
    return TriadPrior(TRUE.t0, TRUE.ts, 1, mean, scale * np.abs(mean) + 1e-3, NOISE, (5.0, 35.0), 20)


def test_the_prior_supplies_the_temperature_slope_a_one_temperature_recording_cannot_show():
    raw, ref, temp = _data(10.0)
    model = GainBiasFitter(prior=_prior(0.05)).fit(raw, ref, temp, 0, "u").model
    hot = np.full(1000, 30.0)
    x = np.random.default_rng(1).standard_normal((1000, 3))
    truth = apply_thermal(TRUE, x, hot)
    plain = GainBiasFitter().fit(raw, ref, temp, 0, "u").model  # degree 0: the bias at 10 °C
    err_prior = np.abs(apply_thermal(model, x, hot) - truth).max()
    err_plain = np.abs(apply_thermal(plain, x, hot) - truth).max()
    # the plain fit misses the slope: 0.2 × (30 − 10) / 15 ≈ 0.27 on the x axis
    assert err_plain > 0.2 and err_prior < 0.02, (err_plain, err_prior)


def test_a_vague_prior_leaves_the_data_fit():
    raw, ref, temp = _data(20.0)
    vague = GainBiasFitter(prior=_prior(1e6)).fit(raw, ref, temp, 0, "u").model
    data_only = GainBiasFitter(degree=0).fit(raw, ref, temp, 0, "u").model
    x = np.random.default_rng(2).standard_normal((500, 3))
    at = np.full(500, 20.0)
    assert np.abs(apply_thermal(vague, x, at) - apply_thermal(data_only, x, at)).max() < 1e-3


def test_build_prior_needs_enough_units_and_one_normalisation():
    models = [TRUE] * (MIN_PRIOR_UNITS - 1)
    assert build_prior(models, [NOISE] * len(models)) is None
    rng = np.random.default_rng(3)
    units = [ThermalModel(True, 20.0, 15.0, 1, TRUE.A, TRUE.g, TRUE.b + 0.01 * rng.standard_normal((3, 2)))
             for _ in range(MIN_PRIOR_UNITS)]
    odd = ThermalModel(True, 30.0, 5.0, 0, TRUE.A, np.zeros((3, 0)), TRUE.b[:, :1])  # another basis: left out
    prior = build_prior(units + [odd], [NOISE] * (len(units) + 1))
    assert prior.units == MIN_PRIOR_UNITS and prior.degree == 1 and prior.mean.shape == (parameter_count(1),)
    assert np.all(prior.sigma > 0)


def test_load_prior_names_the_file(tmp_path):
    with pytest.raises(ModelError, match="fleet prior not found"):
        load_prior(tmp_path / "nope.json")
    (tmp_path / "f.json").write_text(json.dumps({"prior": {}}))
    with pytest.raises(ModelError, match="has no prior"):
        load_prior(tmp_path / "f.json")
    (tmp_path / "g.json").write_text(json.dumps({"prior": {"gyr": {**_prior(0.1).to_json(), "mean": [1.0]}}}))
    with pytest.raises(ModelError, match=r"g.json: prior.gyr.mean: must be 15 finite numbers"):
        load_prior(tmp_path / "g.json")


_FLOAT_MAX = 1.7976931348623157e308


@pytest.mark.parametrize("what, edit, field", [
    ("degree 50", {"degree": 50}, "prior.gyr.degree: must be an integer in 0..3"),
    ("degree 1.7", {"degree": 1.7}, "prior.gyr.degree: must be an integer in 0..3"),
    ("degree true", {"degree": True}, "prior.gyr.degree"),
    ("a NaN mean", {"mean": [float("nan")] * 15}, "prior.gyr.mean: must be 15 finite numbers"),
    ("a 1e300 mean", {"mean": [1e300] * 15}, "prior.gyr.mean: must be 15 finite numbers of magnitude < 1e+06"),
    ("a string in sigma", {"sigma": ["x"] * 15}, "prior.gyr.sigma"),
    ("a zero sigma", {"sigma": [0.0] * 15}, "prior.gyr.sigma: must be 15 numbers in (0, 1e+06)"),
    ("a negative noise", {"noise": -1.0}, "prior.gyr.noise: must be a finite number ≥ 0"),
    ("an infinite noise", {"noise": _FLOAT_MAX * 10}, "prior.gyr.noise"),
    ("a 3-value t_range", {"t_range": [0, 10, 20]}, "prior.gyr.t_range: must be [low, high]"),
    ("t_range [50, -10]", {"t_range": [50, -10]}, "prior.gyr.t_range: must be [low, high] in °C, finite, low ≤ high"),
    ("ts 0", {"ts": 0}, "prior.gyr.ts: must be a finite number > 0"),
    ("t0 missing", {"t0": None}, "prior.gyr.t0"),
    ("units -3", {"units": -3}, "prior.gyr.units: must be an integer in 1..1000000000"),
])
def test_a_damaged_fleet_prior_is_one_error_naming_the_file_the_field_and_its_range(tmp_path, what, edit, field):
    """Issue 31 item 4: 11 of 40 damaged fleet.json files gave tracebacks, and degree 1.7, a negative
    noise, t_range [50, -10] were accepted without comment."""
    entry = {**_prior(0.1).to_json(), **edit}
    path = tmp_path / "fleet.json"
    path.write_text(json.dumps({"prior": {"gyr": entry}}))
    with pytest.raises(ModelError) as e:
        load_prior(path)
    assert str(e.value).startswith(f"{path}: {field}"), str(e.value)


@pytest.mark.parametrize("doc, problem", [({"prior": [1, 2]}, "'prior' must be an object of triads"),
                                          ([1, 2], "'prior' must be an object of triads"),
                                          ({"prior": {"gyro": {}}}, "prior.gyro: unknown triad (allowed: gyr, acc, mag)"),
                                          ({"prior": {"acc": [1]}}, "prior.acc: must be an object with t0")])
def test_a_fleet_json_of_the_wrong_shape_is_one_error(tmp_path, doc, problem):
    path = tmp_path / "fleet.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(ModelError, match=problem.replace("(", r"\(").replace(")", r"\)")):
        load_prior(path)


def test_the_posterior_is_tighter_than_the_prior_where_the_data_look():
    """At one temperature the data pin the bias there (b0 at Tn = −2/3 mixes b0 and b1) far below
    the prior's spread; the slope b1 alone stays near the prior's σ (the data cannot see it)."""
    raw, ref, temp = _data(20.0)  # Tn = 0: the data see b0 directly
    prior = _prior(0.5)
    fit = GainBiasFitter(prior=prior).fit(raw, ref, temp, 0, "u")
    post = fit.posterior_sigma
    assert post.shape == prior.sigma.shape and np.all(post <= prior.sigma * (1 + 1e-9))
    b = slice(6 + 3, None)
    b0, b1 = post[b].reshape(3, 2).T
    assert np.all(b0 < 0.01 * prior.sigma[b].reshape(3, 2)[:, 0])   # NOISE / √3000 ≈ 2e-4
    assert np.all(b1 > 0.9 * prior.sigma[b].reshape(3, 2)[:, 1])


def test_train_with_a_prior_widens_the_range_and_sets_the_filter_spreads(tmp_path):
    """`train(prior=..., fleet_elm=...)` on one minute at 10 °C: every referenced triad is fitted in the
    prior's basis (its degree, its calibrated range: the prior carries the temperature dependence
    there), the particle filter's prior spreads are the magnetometer fit's posterior σ (Laplace), and
    the fleet's ELM replaces the unit's own when it leaves less on the unit's held-out data."""
    from pathlib import Path

    from training.data.io import read_imu_csv
    from training.simulator import simulate_to_dir
    from training.models import elm
    from training.models.fleet_elm import FLEET_ELM_FITTER
    from training.train import elm_rows, train
    root = Path(__file__).resolve().parent.parent
    full = read_imu_csv(simulate_to_dir(root / "scenarios" / "fleet" / "calibration.toml", tmp_path, seed=4))
    minute = full.slice(slice(0, 6000))
    plain = train([minute], progress=False)
    priors = {t: TriadPrior(15.0, 20.0, 1, theta(plain.thermal[t], 1), np.full(parameter_count(1), 0.01),
                            0.01, (5.0, 40.0), 20) for t in ("gyr", "acc", "mag")}
    other = read_imu_csv(simulate_to_dir(root / "scenarios" / "fleet" / "calibration.toml", tmp_path / "other", seed=5))
    fleet_elm = elm.ElmFitter(**FLEET_ELM_FITTER).fit(*elm_rows([other], plain.thermal), 0)  # another recording
    fitted = train([minute], progress=False, prior=priors, fleet_elm=fleet_elm)
    for triad in ("gyr", "acc", "mag"):
        model = fitted.thermal[triad]
        assert model.degree == 1 and (model.t0, model.ts) == (15.0, 20.0)
        assert model.t_range[0] <= 5.0 and model.t_range[1] >= 40.0
        assert fitted.fit_stats[triad]["fleet_prior_units"] == 20
    sigma = np.asarray(fitted.fit_stats["mag"]["posterior_sigma"])
    assert fitted.settings["pf_prior_spread_hard"] == pytest.approx(sigma[9:].reshape(3, 2)[:, 0].max())
    assert fitted.settings["pf_prior_spread_soft"] == pytest.approx(sigma[:6].max())
    assert 0 < fitted.settings["pf_prior_spread_hard"] <= 0.01
    assert any("fleet prior of 20 units" in n for n in fitted.notes)
    # the fleet's ELM, learnt on another recording of the type, beats the minute's own on its held-out end
    stage = fitted.fit_stats["elm"]
    assert stage["source"] == "fleet prior" and stage["enabled"] and stage["rms_after"] < 0.8 * stage["rms_before"]
    assert fitted.elm is fleet_elm and any(n.endswith("the unit gets the fleet") for n in fitted.notes)


def test_a_prior_that_cannot_help_a_triad_says_so():
    from types import SimpleNamespace

    from training.train import _unused_prior_notes
    refs = {"gyr": SimpleNamespace(source="columns"), "acc": SimpleNamespace(source="none"),
            "mag": SimpleNamespace(source="columns")}
    notes = _unused_prior_notes(refs, {"gyr": _prior(0.1)})
    assert len(notes) == 2 and notes[0].startswith("acc: the fleet prior was not used")
    assert notes[1].startswith("mag: the fleet prior has no mag population")
    assert _unused_prior_notes(refs, {}) == []


def test_the_bias_uncertainty_grows_away_from_the_recordings_temperature():
    """One temperature (20 °C = t0) pins the bias there; at ± 15 °C (τ = ±1) the posterior σ is
    the prior's slope σ (0.2 × 0.2 + 1e-3 = 0.041), whatever the recording says."""
    from training.train import bias_uncertainty
    raw, ref, temp = _data(20.0)
    prior = _prior(0.2)
    fit = GainBiasFitter(degree=1, prior=prior).fit(raw, ref, temp, 0, "1")
    at_data, away, far = bias_uncertainty(fit.posterior_cov, prior, (20.0, 35.0, 5.0))
    assert at_data < 0.01 * away                      # NOISE / √3000 ≈ 2e-4 against the prior's 0.04
    assert away == pytest.approx(far, rel=0.05) and 0.9 * 0.041 < away < 1.05 * 0.041
