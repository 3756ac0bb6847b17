"""Which reference calibrates each triad (training.data.reference_source) and what train does with it."""
from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from training.cli import main
from training.completeness import EXIT_INCOMPLETE
from training.data.dataset import ImuData
from training.data.io import write_imu_csv
from training.data.reference_source import choose_reference
from training.frames import quat_from_euler
from training.recommend import gyro_rest_settings
from training.train import gate_outliers

RATE_HZ = 100.0
EARTH = {"norm_ut": 50.0, "dip_deg": 60.0, "declination_deg": 0.0}


def _recording(n: int = 600, name: str = "rec", **extra) -> ImuData:
    """A recording turning slowly about z, with finite raw triads and no reference."""
    rng = np.random.default_rng(0)
    t = np.arange(n) / RATE_HZ
    gyr = np.column_stack([np.zeros(n), np.zeros(n), np.full(n, 0.3)]) + 1e-3 * rng.standard_normal((n, 3))
    acc = np.tile([0.0, 0.0, -9.81], (n, 1))
    mag = np.tile([25.0, 0.0, 43.3], (n, 1))
    return ImuData(t=t, gyr=gyr, acc=acc, mag=mag, temp=np.full(n, 20.0), name=name,
                   meta={"format": "imu-csv/1", "rate_hz": RATE_HZ, "earth_field": EARTH}, **extra)


def _attitude(n: int) -> np.ndarray:
    """ref_q (n, 4) of a turn about z at 0.3 rad/s, body -> NED."""
    yaw = 0.3 * np.arange(n) / RATE_HZ
    return quat_from_euler(np.column_stack([yaw, np.zeros(n), np.zeros(n)]))


def test_columns_win_over_an_attitude_reference():
    data = _recording()
    data = replace(data, ref_gyr=np.tile([0.0, 0.0, 0.3], (len(data), 1)), ref_q=_attitude(len(data)))
    ref = choose_reference([data], "gyr")
    assert ref.source == "columns" and ref.datasets[0] is data


def test_attitude_reference_derives_rate_and_field_like_diagnose():
    data = replace(_recording(), ref_q=_attitude(600))
    gyr, mag, acc = (choose_reference([data], t) for t in ("gyr", "mag", "acc"))
    assert gyr.source == "attitude" and mag.source == "attitude"
    # derived rate of a 0.3 rad/s turn about z: the Savitzky-Golay derivative is exact for it
    inner = gyr.datasets[0].ref_gyr[20:-20]
    assert np.allclose(inner, [0.0, 0.0, 0.3], atol=1e-9)
    # body field = R(q)^T m_ned; its norm is the sidecar's
    assert np.allclose(np.linalg.norm(mag.datasets[0].ref_mag, axis=1), EARTH["norm_ut"])
    assert acc.source == "none"  # no aux_pos_*: no specific-force reference
    assert any("ref_gyr derived" in n for n in gyr.notes)


def test_static_log_gives_zero_rate_and_acc_mag_only_when_all_static():
    still = replace(_recording(name="still"), meta={**_recording().meta, "reference": "static"})
    moving = _recording(name="moving")
    gyr = choose_reference([still, moving], "gyr")
    assert gyr.source == "static" and [d.name for d in gyr.datasets] == ["still"]
    assert np.array_equal(gyr.datasets[0].ref_gyr, np.zeros((len(still), 3)))
    # with a moving recording beside it, acc/mag are self-calibrated, not "static"
    assert choose_reference([still, moving], "acc").source == "none"
    only = choose_reference([still], "mag")
    assert only.source == "static"
    assert np.allclose(only.datasets[0].ref_mag, still.mag.mean(axis=0))


def test_no_reference_keeps_every_recording():
    a, b = _recording(name="a"), _recording(name="b")
    ref = choose_reference([a, b], "mag")
    assert ref.source == "none" and ref.datasets == (a, b)


def test_gate_outliers_drops_glitches_only():
    rng = np.random.default_rng(1)
    target = rng.standard_normal((1000, 3))
    raw = target + 0.01 * rng.standard_normal((1000, 3)) + 0.2  # a bias is no outlier
    raw[[10, 500]] += 5.0                                         # two glitches
    gated, dropped = gate_outliers(raw, target)
    assert dropped == 2 and np.isnan(gated[[10, 500]]).all() and np.isfinite(np.delete(gated, [10, 500], 0)).all()


def test_rest_threshold_covers_noise_and_the_residual_bias():
    sigma, bias = 2e-3, 4e-3
    runs = [(np.array([bias, 0.0, 0.0]), np.full(3, sigma ** 2), 100.0, 300),
            (np.array([-bias, 0.0, 0.0]), np.full(3, sigma ** 2), 100.0, 300)]
    s = gyro_rest_settings(runs)
    assert s["rest_gyro_threshold"] == pytest.approx(max(5 * sigma, 2 * bias))
    assert s["gyro_noise"] == pytest.approx(sigma / np.sqrt(100.0))


def test_train_cli_refuses_a_still_log_without_reference(tmp_path, capsys):
    rng = np.random.default_rng(2)
    n = 2000
    still = ImuData(t=np.arange(n) / RATE_HZ, gyr=0.01 + 1e-3 * rng.standard_normal((n, 3)),
                    acc=[0, 0, -9.81] + 0.01 * rng.standard_normal((n, 3)),
                    mag=[20, 0, 40] + 0.1 * rng.standard_normal((n, 3)), temp=np.full(n, np.nan),
                    meta={"format": "imu-csv/1", "rate_hz": RATE_HZ, "reference": "none"}, name="still")
    path = write_imu_csv(still, tmp_path / "still.csv")
    assert main(["train", str(path), "--out", str(tmp_path / "m")]) == 1
    err = [line for line in capsys.readouterr().err.splitlines() if line.startswith("imufmu train:")]
    assert len(err) == 1 and "no reference and no motion in still" in err[0] and "--allow-identity" in err[0]
    # declared static, the same log calibrates the gyro bias and says so
    sidecar = tmp_path / "still.json"
    sidecar.write_text(json.dumps({**json.loads(sidecar.read_text()), "reference": "static"}))
    assert main(["train", str(path), "--out", str(tmp_path / "m")]) == EXIT_INCOMPLETE  # acc, mag: nothing
    assert main(["train", str(path), "--out", str(tmp_path / "m"), "--allow-partial", "--force"]) == 0
    out = capsys.readouterr().out
    assert "gyroscope: reference: static log" in out and (tmp_path / "m" / "calibration.md").is_file()


def test_sidecar_site_gives_the_field_through_igrf():
    from datetime import datetime

    from contract.errors import ModelError
    from training.data.geomag import earth_field
    from training.recommend import sidecar_values
    site = {"latitude_deg": 47.8, "longitude_deg": 9.2, "altitude_km": 0.4, "date": "2020-06-01"}
    data = replace(_recording(), meta={"format": "imu-csv/1", "rate_hz": RATE_HZ, "site": site})
    igrf = earth_field(47.8, 9.2, 0.4, datetime(2020, 6, 1))
    assert sidecar_values([data], "norm_ut") == [igrf.norm_ut]
    assert sidecar_values([data], "dip_deg") == [igrf.dip_deg]
    # an explicit earth_field wins over the site
    both = replace(data, meta={**data.meta, "earth_field": EARTH})
    assert sidecar_values([both], "norm_ut") == [EARTH["norm_ut"]]
    bad = replace(data, meta={**data.meta, "site": {"latitude_deg": "north"}})
    with pytest.raises(ModelError, match="rec: sidecar site"):
        sidecar_values([bad], "norm_ut")


BROAD_09 = "09_undisturbed_fast_rotation_with_breaks_B.csv.gz"
#: A self-calibration of a log without reference may only help: 0.05° of BROAD total error is
#: what the gyro bias alone moves on this trial (measured +0.01°); the magnetometer fit that cost
#: 0.2-0.9° on such trials (a non-uniform lab field read as hard iron) must be refused.
NO_HARM_DEG = 0.05


def test_self_calibration_of_a_real_log_does_no_harm(broad_trial):
    from contract import layout
    from training.artefact import coefficients_array, settings_dict
    from training.bench import bench
    from training.data.io import read_imu_csv
    from training.main_job import recording_parameters, settings_with
    from training.runtime import run_batch
    from training.train import train
    data = read_imu_csv(broad_trial(BROAD_09))
    user = replace(data, ref_q=None, ref_gyr=None, ref_acc=None, ref_mag=None, eval_mask=None,
                   meta={**data.meta, "reference": "none"})
    artefact = train([user], seed=0, progress=False)  # it moves: no refusal
    assert not artefact.thermal["mag"].enabled
    assert "clearly more constant" in artefact.fit_stats["mag"]["why_not_more"]
    settings = settings_with(np.array(layout.settings_array(settings_dict(artefact))), recording_parameters(data))
    q = [layout.OUTPUTS.index(n) for n in ("q_w", "q_x", "q_y", "q_z")]
    errors = [bench.broad_errors(run_batch(c, settings, data.t - data.t[0], data.inputs())[:, q], data)["total"]
              for c in (coefficients_array(artefact), np.array(layout.identity_coefficients()))]
    assert errors[0] <= errors[1] + NO_HARM_DEG, errors


def test_a_reference_slice_outside_the_eval_mask_trains_without_an_elm(broad_trial):
    """BROAD trial 09's first 7 s carry the optical reference but no eval_mask sample: the ELM has no
    compass row to learn from — the stage is off and says so, where it used to end in a traceback."""
    from training.data.io import read_imu_csv
    from training.train import train
    data = read_imu_csv(broad_trial("09_undisturbed_fast_rotation_with_breaks_B.csv.gz"))
    part = data.slice(slice(0, int(np.searchsorted(data.t, 7.0))))
    artefact = train([part], seed=0, progress=False, allow_identity=True)
    assert not artefact.settings["enable_elm"] and any(n.startswith("elm: fewer than") for n in artefact.notes)


def test_a_setting_the_data_push_outside_the_fmu_range_is_held_at_its_bound_with_a_warning():
    # a gyro bias at rest that the calibration does not explain asked for a rest threshold of 7 rad/s;
    # the runtime refuses anything above 1 rad/s, and train stopped with its refusal
    from training.recommend import held_in_range
    notes: list[str] = []
    held = held_in_range({"rest_gyro_threshold": 7.0, "gyro_noise": 1e-4}, notes)
    assert held == {"rest_gyro_threshold": 1.0, "gyro_noise": 1e-4}
    assert len(notes) == 1 and notes[0].startswith("warning: rest_gyro_threshold = 7 from the calibration data is outside the range the FMU accepts, [0, 1] rad/s; held at 1"), notes
