"""Mounting (issue 16 item 5): the sensor's axes turned into the body axes by a signed axis
permutation (sources/ImuMount.h, training/mounting.py), set by `train` when the data tell."""
from __future__ import annotations

import argparse
import json
import re
import itertools
from dataclasses import replace

import numpy as np
import pytest

from contract import layout
from contract.errors import DataError, ModelError
from contract.mounting import IDENTITY, MOUNT_SETTINGS, Z_UP, frame_text, mount_matrix, mounting_problem
from training.bench.bench import run_xio_fusion
from training.cli import _param
from training.data.io import read_imu_csv
from training.evaluate import compute_metrics, tilt_from_level, tilt_heading_between
from training.main_job import SCENARIO_DIR
from training.mounting import body_attitude, body_references, recommended_mounting, sensor_attitude
from training.runtime import run_batch
from training.simulator import load_scenario, simulate
from training.train import train

SCENARIO = SCENARIO_DIR / "eval_handheld.toml"
#: The acceptance bound of issue 16: with the mounting set, the inclination agrees with x-io
#: Fusion's (its README settings, training.bench.bench.run_xio_fusion) within 1° median on its own log.
XIO_INCLINATION_MEDIAN_DEG = 1.0
_Q = slice(layout.OUTPUTS.index("q_w"), layout.OUTPUTS.index("q_w") + 4)
_Q_SENSOR = slice(layout.OUTPUTS.index("q_sensor_w"), layout.OUTPUTS.index("q_sensor_w") + 4)
_ROLL = layout.OUTPUTS.index("roll")
CODES = (-3, -2, -1, 1, 2, 3)


def _mounted(codes) -> dict[str, float]:
    return dict(zip(MOUNT_SETTINGS, map(float, codes)))


def _run(data, codes=IDENTITY, coefficients=None, settings=None) -> np.ndarray:
    s = layout.settings_array({**(settings or {}), **_mounted(codes)})
    coefficients = layout.identity_coefficients() if coefficients is None else coefficients
    return run_batch(coefficients, s, data.t - data.t[0], data.inputs())


def _turned_sensor(data, codes):
    """The recording as a sensor mounted by `codes` would give it: sensor = Mᵀ · body for every
    triad and reference, and the sensor-frame attitude reference q ⊗ q(M)."""
    mt = mount_matrix(codes).T
    inverse = [0, 0, 0]
    for row in range(3):
        column = int(np.flatnonzero(mt[row])[0])
        inverse[row] = int(mt[row, column]) * (column + 1)
    turned = body_references(data, inverse)  # references turned by Mᵀ
    return replace(turned, gyr=data.gyr @ mt.T, acc=data.acc @ mt.T, mag=data.mag @ mt.T)


@pytest.fixture(scope="module")
def handheld():
    return simulate(load_scenario(SCENARIO), seed=3)


def test_exactly_the_24_rotations_are_accepted_in_c_and_python():
    short = simulate(load_scenario(SCENARIO), seed=1).slice(slice(0, 20))
    accepted = []
    for codes in itertools.product(range(-3, 4), repeat=3):
        try:
            _run(short, codes)
            c_ok = True
        except Exception as e:  # the C check names a mounting setting
            assert re.search(r"mount_[xyz]", str(e))
            c_ok = False
        assert c_ok == (mounting_problem(codes) is None), codes
        accepted += [codes] if c_ok else []
    assert len(accepted) == 24
    assert all(np.linalg.det(mount_matrix(c)) == pytest.approx(1.0) for c in accepted)


@pytest.mark.parametrize("codes", [c for c in itertools.product(CODES, repeat=3) if mounting_problem(c) is None])
def test_a_mounted_sensor_gives_what_the_body_sensor_gives(handheld, codes):
    """Every output of a sensor mounted by `codes` and told so equals the output of a sensor on the
    body axes, bit for bit: the runtime turns the triads by M, then everything runs in body axes. All but
    q_sensor_*, the attitude of the sensor axes, which differ by the mounting's turn (next test)."""
    part = handheld.slice(slice(0, 2000))
    body = [k for k, name in enumerate(layout.OUTPUTS) if not name.startswith("q_sensor_")]
    np.testing.assert_array_equal(_run(_turned_sensor(part, codes), codes)[:, body], _run(part)[:, body])


def test_q_sensor_is_the_attitude_of_the_sensor_axes(handheld):
    """Issue 35 item 3: q_sensor_* = q_* ⊗ q(sensor -> body) (training.mounting.sensor_attitude): equal to q_*
    bit for bit at the identity; for each of the 24 mountings, the sensor turned and told so gives as q_sensor_*
    the body run's attitude turned into its sensor axes (1e-15: the C and numpy products round differently),
    which is what its sensor-axes reference ref_q is compared with."""
    part = handheld.slice(slice(0, 2000))
    body = _run(part)
    np.testing.assert_array_equal(body[:, _Q_SENSOR], body[:, _Q])
    for codes in (c for c in itertools.product(CODES, repeat=3) if mounting_problem(c) is None):
        out = _run(_turned_sensor(part, codes), codes)
        expected = sensor_attitude(body[:, _Q], codes)
        assert np.max(1.0 - np.abs(np.sum(out[:, _Q_SENSOR] * expected, axis=1))) < 1e-15, codes
        np.testing.assert_allclose(np.linalg.norm(out[:, _Q_SENSOR], axis=1), 1.0, atol=1e-15)


def test_mounted_references_give_the_metrics_of_the_body_sensor(handheld):
    """training.mounting.body_references turns a sensor-axes reference into body axes: the metrics
    of a sensor turned 180° about x (z up) with the mounting set equal the metrics on the body axes."""
    turned = _turned_sensor(handheld, Z_UP)
    before = compute_metrics(_run(handheld), handheld).as_dict()
    after = compute_metrics(_run(turned, Z_UP), body_references(turned, Z_UP)).as_dict()
    assert after == pytest.approx(before, rel=1e-9, abs=1e-12)


def test_train_mounts_a_z_up_board_without_reference_and_says_so(handheld):
    blind = replace(_turned_sensor(handheld, Z_UP), ref_q=None, ref_gyr=None, ref_acc=None, ref_mag=None)
    notes: list[str] = []
    assert recommended_mounting([blind], notes) == _mounted(Z_UP)
    assert len(notes) == 1 and "+z" in notes[0] and "1, -2, -3" in notes[0]


def test_a_reference_does_not_change_the_rule(handheld):
    """Issue 35 item 1: one rule with or without an attitude reference. The z-up board with its reference
    kept gets the mounting it gets without (it had the identity: the same sensor, two output frames)."""
    turned = _turned_sensor(handheld, Z_UP)
    with_ref, blind = [], []
    assert recommended_mounting([turned], with_ref) == _mounted(Z_UP)
    assert recommended_mounting([replace(turned, ref_q=None, ref_gyr=None, ref_acc=None, ref_mag=None)],
                                blind) == _mounted(Z_UP)
    assert with_ref == blind


def test_a_declared_mounting_wins_over_the_data(handheld):
    """Issue 35 item 1: the sidecar's "mounting" or train --mounting decide; the argument over the sidecar;
    sidecars that disagree, or codes that are no rotation, are refused with what declared them."""
    turned = _turned_sensor(handheld, Z_UP)
    declared = replace(turned, meta={**turned.meta, "mounting": [2, 1, -3]})
    notes: list[str] = []
    assert recommended_mounting([declared], notes) == _mounted((2, 1, -3))
    assert len(notes) == 1 and "declared by the sidecar 'mounting' of" in notes[0] and "2, 1, -3" in notes[0]
    assert recommended_mounting([declared], [], declared=(1, -2, -3)) == _mounted(Z_UP)
    assert recommended_mounting([handheld], [], declared=(2, -1, 3)) == _mounted((2, -1, 3))
    other = replace(handheld, meta={**handheld.meta, "mounting": [1, 2, 3]}, name="other")
    with pytest.raises(ModelError, match="sidecars declare different mountings"):
        recommended_mounting([declared, other], [])
    with pytest.raises(ModelError, match="train --mounting: .*left-handed"):
        recommended_mounting([handheld], [], declared=(1, 2, -3))


def test_a_sidecar_mounting_is_checked_when_read(handheld, tmp_path):
    from training.data.io import write_imu_csv
    path = tmp_path / "board.csv"
    write_imu_csv(replace(handheld.slice(slice(0, 50)), meta={**handheld.meta, "mounting": [1, -2, -3]}), path)
    assert read_imu_csv(path).meta["mounting"] == [1, -2, -3]
    side = path.with_suffix(".json")
    side.write_text(json.dumps({**json.loads(side.read_text()), "mounting": [1, 1, 3]}))
    with pytest.raises(DataError, match="sidecar 'mounting' .* name a sensor axis twice"):
        read_imu_csv(path)


def test_the_frame_is_named_in_one_line():
    assert frame_text(IDENTITY) == "body axes = sensor axes (mount_x..z = 1, 2, 3)"
    assert frame_text(Z_UP).startswith("body axes = sensor axes turned by mount_x..z = 1, -2, -3 (")
    assert "180° about sensor [1, 0, 0]" in frame_text(Z_UP) and "90° about sensor [0, 0, 1]" in frame_text((2, -1, 3))


def test_train_keeps_a_z_down_board_silently_and_reports_any_other_direction(handheld):
    blind = replace(handheld, ref_q=None)
    notes: list[str] = []
    assert recommended_mounting([blind], notes) == {} and notes == []
    x_up = replace(_turned_sensor(handheld, (3, 2, -1)), ref_q=None)  # body z = -sensor x: x points up
    assert recommended_mounting([x_up], notes) == {}
    assert len(notes) == 1 and "+x" in notes[0] and "kept" in notes[0]


def test_cli_refuses_a_code_that_is_no_axis():
    with pytest.raises(argparse.ArgumentTypeError, match="mount_x is 0, expected a whole number in -3..3 other than 0"):
        _param("mount_x=0")


def test_xio_log_trained_at_the_defaults_agrees_with_xio_fusion(xio_log):
    """The acceptance figure of issue 16 item 5: train sets the mounting of x-io's z-up board, and
    the trained runtime's inclination agrees with x-io Fusion's within 1° median (benchmarks/
    xio_mounting.py prints the table; FMU = batch runtime bit for bit, tests/test_fmu.py)."""
    from training.artefact import coefficients_array, settings_dict
    data = read_imu_csv(xio_log)
    artefact = train([data], seed=0, progress=False)
    settings = settings_dict(artefact)
    codes = tuple(int(settings[name]) for name in MOUNT_SETTINGS)
    assert codes == Z_UP
    out = run_batch(coefficients_array(artefact), layout.settings_array(settings), data.t - data.t[0], data.inputs())
    q, q_fusion = out[:, _Q], run_xio_fusion(data)
    error = np.rad2deg(tilt_heading_between(q, body_attitude(q_fusion, codes))[:, 0])
    tilt = np.rad2deg(np.abs(tilt_from_level(q) - tilt_from_level(body_attitude(q_fusion, Z_UP))))
    assert np.median(error) < XIO_INCLINATION_MEDIAN_DEG and np.median(tilt) < XIO_INCLINATION_MEDIAN_DEG
    assert abs(np.median(np.rad2deg(out[:, _ROLL]))) < 10.0  # level-ish, not upside down (was ~180°)


def test_an_fmu_with_a_mounting_validates_and_runs_as_the_batch_runtime(handheld, tmp_path):
    """A mounting that swaps axes (body x = sensor y): every validate check passes (the binary's
    triad check follows the declared mounting) and the FMU gives the batch runtime's outputs."""
    from fmu.cosim import run_fmu
    from fmu.validator import validate_fmu
    from training.fmu_build import build_fmu
    codes = (2, 1, -3)
    path = build_fmu(np.asarray(layout.identity_coefficients()), _mounted(codes), tmp_path / "ImuFusion.fmu")
    assert validate_fmu(path) == []
    part = handheld.slice(slice(0, 500))
    np.testing.assert_array_equal(run_fmu(path, part.t - part.t[0], part.inputs()), _run(part, codes))


def test_the_calibration_summary_opens_with_the_frame(handheld):
    """Issue 35 item 2: the summary `train` prints says first which body frame the FMU reports in and what
    decided it (a declaration or the data)."""
    from contract.layout import TRIAD_ORDER, settings_defaults
    from training.artefact import ModelArtefact
    from training.models.thermal import ThermalModel
    from training.reports.calibration_report import summary_text
    part = handheld.slice(slice(0, 3000))
    cases = ((_turned_sensor(part, Z_UP), None, "decided from the data: at rest gravity reads along sensor +z"),
             (part, (2, 1, -3), "declared by train --mounting"),
             (part, None, "decided from the data: at rest gravity reads along sensor -z"))
    for data, declared, source in cases:
        notes: list[str] = []
        settings = {**settings_defaults(), **recommended_mounting([data], notes, declared)}
        artefact = ModelArtefact(seed=0, thermal={k: ThermalModel.identity(enabled=False) for k in TRIAD_ORDER},
                                 settings=settings, notes=notes)
        head = summary_text(artefact, []).splitlines()
        codes = tuple(int(settings[name]) for name in MOUNT_SETTINGS)
        assert head[1].startswith(f"frame: {frame_text(codes)} (") and source in head[1], head[1]
        assert "q_sensor_*" in head[2]


def test_a_multi_position_calibration_sets_no_mounting_whatever_its_median():
    """Held still z up (20 %), z down (15 %), and tilted 45° about y either way and about x (20 % + 20 % + 15 %,
    each with z up), 10 % tumbling: the median rest direction is sensor +z within a few degrees, but only the z-up
    pose lies within 30° of it — no axis holds MIN_AXIS_SHARE of the rests, the board rests many ways up, and the
    data say nothing about its mounting (the two-soak calibration's median landed 10° from +z)."""
    from training.data.dataset import ImuData
    from training.mounting import AXIS_TOLERANCE_DEG, MIN_AXIS_SHARE, gravity_axis
    s = np.sqrt(0.5)
    poses = [((0, 0, 1), 200), ((0, 0, -1), 150), ((s, 0, s), 200), ((-s, 0, s), 200), ((0, s, s), 150)]
    blocks = [np.tile(np.array(d, dtype=float), (k, 1)) for d, k in poses]
    blocks.append(np.random.default_rng(3).normal(size=(100, 3)))
    up = np.vstack(blocks)
    up = up / np.linalg.norm(up, axis=1)[:, None]
    n = len(up)
    data = ImuData(t=np.arange(n) / 100.0, gyr=np.zeros((n, 3)), acc=9.80665 * up, mag=np.tile([20.0, 0.0, 40.0], (n, 1)),
                   temp=np.full(n, 25.0), name="many_poses")
    axis, angle, share = gravity_axis(data)
    assert axis == "+z" and angle < AXIS_TOLERANCE_DEG and share < MIN_AXIS_SHARE
    notes: list[str] = []
    assert recommended_mounting([data], notes) == {} and not any(n.startswith("mounting:") for n in notes)
