"""The source methods as a user selects them (issue 33): `imufmu train --method NAME=FORM` records the forms in
model.json and the FMU parameters, the FMU run through fmpy gives the batch runtime's outputs, and each runtime
switch runs the pure form its Python/batch twin describes: the Euler fusion without additions
(euler_additions = 0, tests/test_euler_additions.py), the particle filter as its source describes it
(pf_additions = 0: the C filter's internal settings at magpf.SOURCE_METHOD's values) and the PSO-BP network
evaluated outside its training ranges (psobp_clamp = 0: psobp.apply_psobp(clamp_inputs=False))."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from contract import layout
from contract.ranges import EULER_ALL_ADDITIONS
from fmu.cosim import run_fmu
from training import runtime
from training.artefact import coefficients_array, load_artefact, settings_dict
from training.cli import main
from training.data.io import write_imu_csv
from training.fmu_build import build_fmu_from_model
from training.main_job import SCENARIO_DIR
from training.models import magpf, psobp
from training.models.methods import METHODS
from training.simulator import load_scenario, simulate

#: The source form of every method but the PSO-BP network's, whose source fit runs its whole gradient budget
#: (60 s on this session: a benchmark's cost); it has its own test below on the session decimated (16 s).
SOURCE = {method: next(iter(forms)) if method != "psobp" else "product" for method, forms in METHODS.items()}
#: PSO-BP network output against the C runtime's: the same operations in another order (tanh, sums) differ
#: by rounding, ~1e-16 rad/s; 1e-12 rad/s (2e-11 °/s) is far under any gyro's noise and far over rounding.
PSOBP_TWIN_RAD_S = 1e-12
#: The PSO-BP source-form test trains on every DECIMATION-th sample: its fit's cost is proportional to the samples.
DECIMATION = 5


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """(folder of `imufmu train --method` with every source form, the session)."""
    tmp = tmp_path_factory.mktemp("methods")
    data = simulate(load_scenario(SCENARIO_DIR / "variants" / "diag_calibration_clean.toml"))
    path = write_imu_csv(data, tmp / "session.csv.gz")
    argv = ["train", str(path), "--out", str(tmp / "unit"), "--allow-partial"]
    for method, form in SOURCE.items():
        argv += ["--method", f"{method}={form}"]
    assert main(argv) == 0
    return tmp, data


def test_the_selected_forms_are_recorded_and_reach_the_fmu(trained, capsys):
    tmp, data = trained
    artefact = load_artefact(tmp / "unit" / "model.json")
    assert artefact.methods == SOURCE
    settings = settings_dict(artefact)
    for method, form in SOURCE.items():
        assert {k: settings[k] for k in METHODS[method][form].settings} == METHODS[method][form].settings
        assert any(n.startswith(f"method: {method} = {form}") for n in artefact.notes)
    assert artefact.elm is not None and artefact.psobp is not None
    fmu = build_fmu_from_model(tmp / "unit" / "model.json", tmp / "unit.fmu")
    part = data.slice(np.arange(0, 600))
    t, inputs = part.t, part.inputs()
    np.testing.assert_array_equal(run_fmu(fmu, t, inputs),
                                  runtime.run_batch(coefficients_array(artefact), layout.settings_array(settings), t,
                                                    inputs))


def test_an_unknown_method_or_form_is_one_line(capsys):
    with pytest.raises(SystemExit):
        main(["train", "x.csv", "--out", "y", "--method", "pf=foo"])
    assert "pf has the forms source, stabilised, rb" in capsys.readouterr().err


def test_the_euler_additions_range_is_the_runtimes():
    """The parameter's declared maximum (its default) is every addition bit of the C fusion; the bits themselves
    and the source form's lock-up: tests/test_euler_additions.py."""
    assert EULER_ALL_ADDITIONS == runtime.euler_all_additions()


def test_pf_additions_off_is_the_filter_as_its_source_describes_it():
    """The chain with pf_additions = 0 equals the batch filter run with magpf.SOURCE_METHOD (the source row of
    the ablation): the C table's source values and Python's ADDITIONS agree."""
    internal = {name: source for name, _, default, source in runtime.magpf_internal_rows() if source != default}
    assert internal == {k: v for k, v in magpf.SOURCE_METHOD.items() if k not in dict(layout.SETTINGS)}
    d = magpf.simulate_tumbling(3, duration_s=4.0)
    n = len(d.mag)
    t = np.arange(n) / d.rate_hz
    inputs = np.column_stack([np.zeros((n, 3)), np.tile([0.0, 0.0, -9.81], (n, 1)), d.mag, np.full(n, 25.0),
                              np.zeros((n, len(layout.AUX_INPUTS)))])
    pf = {"pf_particles": 32.0, "pf_decimation": 1.0, **magpf.zero_prior(d.field_norm_ut)}
    fmu_names = {k: v for k, v in magpf.SOURCE_METHOD.items() if k in dict(layout.SETTINGS)}
    chain = {}
    for additions in (0.0, 1.0):
        out = runtime.run_batch(layout.identity_coefficients(), layout.settings_array(
            {"enable_pf": 1.0, "field_norm": d.field_norm_ut, "pf_additions": additions, **pf, **fmu_names}), t, inputs)
        chain[additions] = out[:, [layout.OUTPUTS.index(f"hard_iron_{a}") for a in "xyz"]]
    source = magpf.run_c(d.mag, magpf.settings(d.field_norm_ut, **pf, **magpf.SOURCE_METHOD)).hard_iron
    np.testing.assert_array_equal(chain[0.0], source)
    assert not np.array_equal(chain[1.0], source)


def test_psobp_clamp_off_evaluates_the_network_outside_its_ranges(trained):
    tmp, data = trained
    artefact = load_artefact(tmp / "unit" / "model.json")
    model = artefact.psobp
    n = 3000
    t = np.arange(n) * 0.01
    temp = np.linspace(model.t_min - 15.0, model.t_max + 15.0, n)  # beyond the training range on both sides
    inputs = np.column_stack([np.zeros((n, 3)), np.tile([0.0, 0.0, -9.81], (n, 1)), np.tile([20.0, 0.0, 40.0], (n, 1)),
                              temp, np.zeros((n, len(layout.AUX_INPUTS)))])
    coefficients = coefficients_array(artefact)
    rates = [layout.OUTPUTS.index(f"rate_{a}") for a in "xyz"]

    def rate(**settings):
        values = {**settings_dict(artefact), "rest_gyro_threshold": 0.0, "motion_bias": 0.0, **settings}
        return runtime.run_batch(coefficients, layout.settings_array(values), t, inputs)[:, rates]

    without = rate(enable_psobp=0.0)
    for clamp in (False, True):
        correction = without - rate(enable_psobp=1.0, psobp_clamp=float(clamp))
        np.testing.assert_allclose(correction, psobp.apply_psobp(model, t, temp, clamp_inputs=clamp),
                                   rtol=0, atol=PSOBP_TWIN_RAD_S, err_msg=f"clamp {clamp}")


def test_the_psobp_source_fit_reaches_the_fmu_as_its_pure_form(tmp_path):
    """`train --method psobp=source` (the source's fit: single-sample targets, plain swarm, plain gradient descent
    over the whole 3000-epoch budget, no input clamp; on the session decimated to 10 Hz so that the budget costs
    seconds, not a minute) records the form, its FMU through fmpy equals the batch runtime bit for bit, and the
    network the FMU applies is psobp.apply_psobp(clamp_inputs=False) of the fitted model within PSOBP_TWIN_RAD_S."""
    data = simulate(load_scenario(SCENARIO_DIR / "variants" / "diag_calibration_clean.toml"))
    every = data.slice(np.arange(0, len(data), DECIMATION))
    every = replace(every, meta={**every.meta, "rate_hz": every.meta["rate_hz"] / DECIMATION})
    path = write_imu_csv(every, tmp_path / "session.csv.gz")
    assert main(["train", str(path), "--out", str(tmp_path / "unit"), "--allow-partial", "--method", "psobp=source"]) == 0
    artefact = load_artefact(tmp_path / "unit" / "model.json")
    settings = settings_dict(artefact)
    assert artefact.methods == {"psobp": "source"} and settings["psobp_clamp"] == 0.0 and artefact.psobp is not None
    fmu = build_fmu_from_model(tmp_path / "unit" / "model.json", tmp_path / "unit.fmu")
    n = 600
    t = np.arange(n) * 0.05
    temp = np.linspace(artefact.psobp.t_min - 10.0, artefact.psobp.t_max + 10.0, n)  # beyond its range too
    inputs = np.column_stack([np.zeros((n, 3)), np.tile([0.0, 0.0, -9.81], (n, 1)), np.tile([20.0, 0.0, 40.0], (n, 1)),
                              temp, np.zeros((n, len(layout.AUX_INPUTS)))])
    values = {**settings, "rest_gyro_threshold": 0.0, "motion_bias": 0.0}
    out = run_fmu(fmu, t, inputs, parameters={"rest_gyro_threshold": 0.0, "motion_bias": 0.0})
    np.testing.assert_array_equal(out, runtime.run_batch(coefficients_array(artefact), layout.settings_array(values),
                                                         t, inputs))
    rates = [layout.OUTPUTS.index(f"rate_{a}") for a in "xyz"]
    without = runtime.run_batch(coefficients_array(artefact), layout.settings_array({**values, "enable_psobp": 0.0}),
                                t, inputs)[:, rates]
    np.testing.assert_allclose(without - out[:, rates], psobp.apply_psobp(artefact.psobp, t, temp, clamp_inputs=False),
                               rtol=0, atol=PSOBP_TWIN_RAD_S)
