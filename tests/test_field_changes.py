"""train decides the online hard/soft-iron filter (enable_pf) by running it over the calibration
recordings (training.attitude.field_changes): a recording whose hard iron steps — a magnet attached to
the sensor halfway through — switches it on, the same recording without the step leaves it off, and the
note says which. The magnetometer is a calibrated one (the simulator's true body field plus 0.3 µT
noise), and the filter's change test is set from the clean recording as `train` sets it
(training.models.pf_settings), so the decision rests on the filter alone. The simulated main job, with
no change, writes enable_pf = 0 (tests/test_pipeline.py checks the note)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from contract import layout
from training.attitude.field_changes import pf_switch
from training.main_job import SCENARIO_DIR
from training.models.pf_settings import pf_settings_from_calibration
from training.simulator import load_scenario, simulate

#: The attached magnet: a body-fixed field step [µT] (BROAD's attached magnets: 3-14 µT at 4-1 cm).
STEP_UT = np.array([6.0, -4.0, 3.0])


@pytest.fixture(scope="module")
def recordings():
    data = simulate(load_scenario(SCENARIO_DIR / "eval_handheld.toml"), seed=5)
    data = data.slice(data.t - data.t[0] < 120.0)
    rng = np.random.default_rng(11)
    clean = replace(data, mag=data.ref_mag + 0.3 * rng.standard_normal(data.ref_mag.shape), name="clean")
    step = replace(clean, mag=clean.mag + np.where((clean.t - clean.t[0] >= 60.0)[:, None], STEP_UT, 0.0),
                   name="magnet")
    norm = float(np.median(np.linalg.norm(clean.mag, axis=1)))
    rate = 1.0 / float(np.median(np.diff(clean.t)))
    settings = {**layout.settings_defaults(), "field_norm": norm,
                **pf_settings_from_calibration(clean.mag, clean.t, norm, rate)}
    return clean, step, settings


@pytest.mark.parametrize("which, expected", [("magnet", 1.0), ("clean", 0.0)])
def test_the_filter_is_on_where_the_recordings_show_a_hard_iron_change(recordings, which, expected):
    clean, step, settings = recordings
    data = step if which == "magnet" else clean
    notes: list[str] = []
    decided = pf_switch(layout.identity_coefficients(), settings, [data], notes)
    assert decided == {"enable_pf": expected}
    assert notes[-1].startswith(f"enable_pf = {expected:g}: the online hard/soft-iron filter")
    assert (which in notes[-1]) == (expected == 1.0)
