"""The magnetometer trusted only as far as it deserves (issue 29, training.attitude.magnetic_trust): on
the simulated main job `train` keeps the magnetometer (tests/test_pipeline.py); in a non-uniform field (a robot cell:
a perturbation fixed in the room that changes as the sensor moves, 25 % of the earth field) it writes
mag_heading = 0 with a warning, and the FMU at those settings is no worse than with the magnetometer
forced on — against the simulator's truth, heading-aligned (a 6D heading starts at 0)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from contract import layout
from training.artefact import coefficients_array, settings_dict
from training.data.reference import reference_quaternion_magnetic
from training.frames import quat_multiply
from training.main_job import SCENARIO_DIR, recording_parameters
from training.mounting import body_references
from training.runtime import run_batch
from training.simulator import load_scenario, simulate
from training.train import train

SCENARIO = SCENARIO_DIR / "eval_handheld.toml"
#: Perturbation of the field in the room, per axis, relative to the earth field's norm: 25 %, a
#: robot cell or a desk with a computer (the robot-arm data set of issue 29 sees 10-30 %).
PERTURBATION = 0.25
_Q = [layout.OUTPUTS.index(n) for n in ("q_w", "q_x", "q_y", "q_z")]


def _rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(N, 3) vectors v turned by the (N, 4) quaternions q."""
    u, w = q[:, 1:], q[:, :1]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def _non_uniform(data, seed: int):
    """The recording in a room whose field is perturbed by a smooth random field (sums of sines of
    5-40 s periods, PERTURBATION · |B| per axis) as the sensor moves through it: the perturbation is
    fixed in the room, so it enters the body readings through the true attitude. The reference
    columns keep the simulator's uniform earth field: the model of the field the room does not follow."""
    rng = np.random.default_rng(seed)
    t = data.t - data.t[0]
    norm = float(np.median(np.linalg.norm(data.mag, axis=1)))
    periods = rng.uniform(5.0, 40.0, (3, 4))
    phases = rng.uniform(0.0, 2.0 * np.pi, (3, 4))
    nav = np.stack([np.sum(np.sin(2.0 * np.pi * t[:, None] / periods[i] + phases[i]), axis=1) / 2.0
                    for i in range(3)], axis=1) * PERTURBATION * norm
    conj = data.ref_q * np.array([1.0, -1.0, -1.0, -1.0])
    return replace(data, mag=data.mag + _rotate(conj, nav))


def _aligned_heading_rmse(out: np.ndarray, data) -> float:
    """Heading error RMSE [°] after removing its mean (heading-aligned: a 6D heading starts at 0)."""
    q_ref = reference_quaternion_magnetic(data)
    err = quat_multiply(out[:, _Q], q_ref * np.array([1.0, -1.0, -1.0, -1.0]))
    heading = 2.0 * np.arctan2(err[:, 3], err[:, 0])
    heading = np.angle(np.exp(1j * (heading - np.angle(np.mean(np.exp(1j * heading))))))
    return float(np.rad2deg(np.sqrt(np.mean(heading ** 2))))


#: Seconds of the simulated handheld recording used (its start: still, then hand-held motion).
SECONDS = 90.0


def _handheld(seed: int):
    data = simulate(load_scenario(SCENARIO), seed=seed)
    return data.slice(data.t - data.t[0] < SECONDS)


@pytest.fixture(scope="module")
def handheld():
    return _handheld(seed=3)


def test_a_non_uniform_field_falls_back_to_6d_and_does_no_harm(handheld):
    artefact = train([_non_uniform(handheld, seed=1)], seed=0, progress=False)
    assert artefact.settings["mag_heading"] == 0.0
    assert any("mag: warning: mag_heading = 0" in n for n in artefact.notes)
    trial = _non_uniform(_handheld(seed=4), seed=2)
    errors = {}
    for label, heading in (("trained", artefact.settings["mag_heading"]), ("9D", 1.0)):
        s = layout.settings_array({**settings_dict(artefact), **recording_parameters(trial), "mag_heading": heading})
        out = run_batch(coefficients_array(artefact), s, trial.t - trial.t[0], trial.inputs([]))
        errors[label] = _aligned_heading_rmse(out, body_references(trial, (1, 2, 3)))
    assert errors["trained"] <= errors["9D"], errors
