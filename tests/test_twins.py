"""Every numpy twin against the C runtime it mirrors, on one recording (VQF's habit: one test runs
every implementation on the same data). The twins are the Python reference implementations of the
C stages: the ELM's field form (training/models/elm.py), the PSO-BP bias network
(training/models/psobp.py) and the particle filter in both modes (training/models/magpf.py); the
modules' own tests probe each pair on inputs built to reach its corners."""
from __future__ import annotations

import numpy as np
import pytest

from training.main_job import SCENARIO_DIR
from training.models import elm, magpf
from training.models.psobp import (MODE_RESIDUAL, PsoBpModel, apply_psobp, correct_gyro_psobp,
                                   correct_gyro_psobp_c, predict_psobp_c)
from training.simulator import load_scenario, simulate

#: Relative bound of twin against C: both evaluate the same formulas in the same order; only the
#: C library's tanh/exp/sqrt may differ from numpy's by an ulp, which the stages amplify by far
#: less than 1e5 (network weights of order 1-100, particle filters over a few hundred updates:
#: the modules' own tests observe ~1e-14).
TWIN_RTOL = 1e-9
#: Samples of the recording the particle filters run on (the Python twin is slow) and their
#: filter settings: an update every 4th sample, 16 particles, the zero prior, both modes.
PF_SAMPLES = 600


@pytest.fixture(scope="module")
def recording():
    """The main job's hand-held evaluation scenario, seed 3: rates, temperature and field of a
    moving, warming sensor."""
    return simulate(load_scenario(SCENARIO_DIR / "eval_handheld.toml"), seed=3)


def _elm_model(field: np.ndarray) -> elm.ElmModel:
    """A field-form network with seeded weights whose box is the recording's field range."""
    rng = np.random.default_rng(11)
    lo, hi = np.nanmin(field, axis=0), np.nanmax(field, axis=0)
    return elm.ElmModel("tanh", rng.normal(size=(8, 3)), rng.normal(size=8), 0.3 * rng.normal(size=(8, 3)),
                        elm.MinMax(lo, hi), elm.MinMax(lo - 5.0, hi + 5.0), seed=11, loss=0.0, train_time_s=0.0)


def _psobp_model(temp: np.ndarray) -> PsoBpModel:
    """A residual bias network with seeded weights over the recording's temperature range."""
    rng = np.random.default_rng(12)
    return PsoBpModel(MODE_RESIDUAL, 4, 12.0, float(np.nanmin(temp)) - 1.0, float(np.nanmax(temp)) + 1.0, -0.05,
                      0.05, rng.normal(0, 1.5, (3, 4, 2)), rng.normal(0, 1, (3, 4)), rng.normal(0, 0.01, (3, 4)),
                      rng.normal(0, 0.01, 3))


def _elm(d):
    model = _elm_model(d.mag)
    return elm.field_apply(model, d.mag), elm.c_apply(elm.to_block(model), d.mag)


def _psobp_bias(d):
    model = _psobp_model(d.temp)
    return apply_psobp(model, d.t, d.temp), predict_psobp_c(model, d.t, d.temp)


def _psobp_correct(d):
    model = _psobp_model(d.temp)
    return correct_gyro_psobp(model, d.t, d.gyr, d.temp), correct_gyro_psobp_c(model, d.t, d.gyr, d.temp)


def _magpf(rao_blackwell: int):
    def run(d):
        norm = float(np.nanmedian(np.linalg.norm(d.mag, axis=1)))
        s = magpf.settings(norm, pf_particles=16, pf_seed=9, pf_decimation=4, pf_rao_blackwell=rao_blackwell,
                           **magpf.zero_prior(norm))
        py, c = magpf.run_python(d.mag[:PF_SAMPLES], s), magpf.run_c(d.mag[:PF_SAMPLES], s)
        return (np.hstack([py.compensated, py.hard_iron, py.soft_iron, py.neff[:, None]]),
                np.hstack([c.compensated, c.hard_iron, c.soft_iron, c.neff[:, None]]))
    return run


#: Implementation pair -> (twin output, C output) on the recording.
PAIRS = {"elm field form": _elm, "psobp bias": _psobp_bias, "psobp corrected gyro": _psobp_correct,
         "magpf mode 0 (the method's 9-state filter)": _magpf(0), "magpf mode 1 (Rao-Blackwellised)": _magpf(1)}


@pytest.mark.parametrize("pair", sorted(PAIRS))
def test_twin_equals_c_on_one_recording(recording, pair):
    twin, c = PAIRS[pair](recording)
    assert twin.shape == c.shape and np.all(np.isfinite(c))
    scale = np.max(np.abs(c))
    np.testing.assert_allclose(twin, c, rtol=TWIN_RTOL, atol=TWIN_RTOL * scale)
