"""The BROAD benchmark harness (frames, metric, files) and the quaternion attitude mode.

Accuracy on the real BROAD trials is measured by `imufmu bench broad` (docs/BENCHMARKS.md), not
here: these tests use short synthetic recordings with a known attitude.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from contract import layout
from training.bench import bench
from training.data.dataset import ImuData
from training.data.io import write_imu_csv
from training.runtime import run_batch

FS = 100.0                        # Hz
G = 9.80665                       # m/s²
FIELD_NORM, DIP = 43.6, np.radians(69.2)
M_NED = FIELD_NORM * np.array([np.cos(DIP), 0.0, np.sin(DIP)])
#: A static attitude with every angle non-zero (roll 170° like BROAD's z-up IMU).
Q_TRUE = Rotation.from_euler("ZYX", [35.0, -20.0, 170.0], degrees=True)
#: Every filter converges on noise-free static data within the first half; 1° leaves room for
#: Madgwick's slow gradient-descent convergence, far below any frame mistake (≥ 90°).
STATIC_BOUND_DEG = 1.0


def wxyz(r: Rotation) -> np.ndarray:
    """(N, 4) or (4,) [w, x, y, z] of a scipy rotation (body -> NED)."""
    q = r.as_quat()
    return q[..., [3, 0, 1, 2]]


def static_trial(name: str = "01_static", seconds: float = 20.0) -> ImuData:
    """Noise-free static recording at Q_TRUE with reference; eval_mask on the second half."""
    n = int(seconds * FS)
    t = np.arange(n) / FS
    acc = np.tile(Q_TRUE.inv().apply([0.0, 0.0, -G]), (n, 1))
    mag = np.tile(Q_TRUE.inv().apply(M_NED), (n, 1))
    meta = {"rate_hz": FS, "reference": "simulated",
            "earth_field": {"norm_ut": FIELD_NORM, "dip_deg": float(np.degrees(DIP)), "declination_deg": 0.0}}
    return ImuData(t=t, gyr=np.zeros((n, 3)), acc=acc, mag=mag, temp=np.full(n, np.nan),
                   ref_q=np.tile(wxyz(Q_TRUE), (n, 1)), eval_mask=t >= seconds / 2, meta=meta, name=name)


def test_broad_metric_closed_form():
    data = static_trial()
    q_ref = wxyz(Q_TRUE)
    turned = wxyz(Rotation.from_euler("z", 10.0, degrees=True) * Q_TRUE)
    tilted = wxyz(Rotation.from_euler("x", 5.0, degrees=True) * Q_TRUE)
    n = len(data)
    assert bench.broad_errors(np.tile(q_ref, (n, 1)), data) == pytest.approx(
        {"total": 0.0, "heading": 0.0, "inclination": 0.0}, abs=1e-6)
    assert bench.broad_errors(np.tile(-turned, (n, 1)), data) == pytest.approx(
        {"total": 10.0, "heading": 10.0, "inclination": 0.0}, abs=1e-6)
    assert bench.broad_errors(np.tile(tilted, (n, 1)), data) == pytest.approx(
        {"total": 5.0, "heading": 0.0, "inclination": 5.0}, abs=1e-6)


@pytest.mark.parametrize("name", list(bench.FILTERS))
def test_every_filter_returns_body_to_ned(name):
    data = static_trial()
    errors = bench.broad_errors(bench.FILTERS[name](data), data)
    assert errors["total"] < STATIC_BOUND_DEG, errors


def quaternion_run(data: ImuData, **overrides) -> np.ndarray:
    """ImuFusion runtime outputs in quaternion mode with the trial's field."""
    return run_batch(layout.identity_coefficients(), bench.imufusion_settings(data, overrides),
                     data.t, data.inputs())


def test_rest_bias_stops_gyro_only_heading_drift():
    data = static_trial(seconds=60.0)
    data.gyr[:] = np.radians([0.3, -0.2, 0.5])  # °/s bias, at rest
    data.mag[1:] = np.nan                      # heading from the gyro after the first fix
    yaw = {th: bench.broad_errors(quaternion_run(data, rest_gyro_threshold=th)[:, bench._Q_COLS], data)["heading"]
           for th in (0.0, 0.035)}
    # without the estimate the heading drifts 0.5 °/s: RMSE over 30..60 s about 22°; with it the
    # drift stops after the rest detector's 1.5 s plus the bias time constant (2 s), leaving the
    # heading offset gathered until then, about 0.5 °/s x 3.5 s = 1.75°.
    assert yaw[0.0] > 10.0 and yaw[0.035] < 2.5, yaw


def test_disturbed_field_is_rejected_and_a_lasting_one_accepted():
    data = static_trial(seconds=60.0)
    disturbed = (data.t >= 20.0) & (data.t < 40.0)
    data.mag[disturbed] += [25.0, 0.0, 0.0]    # a magnet: norm and dip both off
    q = {rt: quaternion_run(data, mag_reject_time=rt)[:, bench._Q_COLS] for rt in (0.0, 60.0, 5.0)}
    heading = {rt: bench.broad_errors(q[rt], data)["heading"] for rt in q}
    assert heading[60.0] < 0.01 < 5.0 < heading[0.0], heading
    assert heading[5.0] > 5.0, heading  # accepted after 5 s of rejection (recovery)


def test_quaternion_mode_static_closed_form():
    data = static_trial(seconds=2.0)
    out = quaternion_run(data)
    q = out[:, bench._Q_COLS]
    np.testing.assert_allclose(np.abs(q @ wxyz(Q_TRUE)), 1.0, atol=1e-9)
    assert np.all(q[:, 0] >= 0.0)


def test_bench_broad_writes_tables_and_fmu_equals_batch(tmp_path):
    folder = tmp_path / "broad"
    for name in ("01_static_a", "28_static_b"):
        write_imu_csv(static_trial(name, seconds=5.0), folder / f"{name}.csv.gz")
    result = bench.bench_broad(None, tmp_path / "out", data_dir=folder)
    assert set(result["groups"]) == set(bench.FILTERS)
    assert result["groups"]["ImuFusion"]["all"]["n_trials"] == 2
    assert result["groups"]["ImuFusion"]["disturbed"]["n_trials"] == 1
    assert all(v["max_abs_q_difference"] == 0.0 for v in result["fmu"].values())
    for path in result["files"]:
        assert (tmp_path / "out" / path.split("/")[-1]).stat().st_size > 0
    assert "doi:10.3390/data6070072" in (tmp_path / "out" / "broad.md").read_text()


def test_speed_rows_switch_one_stage_each():
    # Every enable_* setting gets a row; its "on" and "off" runs differ in that stage's switch
    # only (the rest is train's settings), so the difference is the stage's cost, not noise.
    runs = bench._stage_runs()
    switches = [n for n, _ in layout.SETTINGS if n.startswith("enable_")]
    assert switches == list(runs)[:len(switches)]
    for name, (on, off) in runs.items():
        switch = name.split(",")[0]
        assert on[switch] == 1.0 and off[switch] == 0.0
        assert {k: v for k, v in on.items() if k != switch} == {k: v for k, v in off.items() if k != switch}


def test_speed_refuses_a_model_without_stage_coefficients(tmp_path):
    # A model without PSO-BP coefficients (no gyro reference): timing that stage on would time nothing.
    from contract.errors import ModelError
    from training.train import train
    data = static_trial()
    rng = np.random.default_rng(0)
    data.gyr, data.acc, data.mag = (x + s * rng.standard_normal(x.shape)
                                    for x, s in ((data.gyr, 1e-3), (data.acc, 1e-2), (data.mag, 0.3)))
    artefact = train([data], seed=0, progress=False, allow_identity=True)
    path = artefact.save(tmp_path / "model.json")
    with pytest.raises(ModelError, match="the model has no .*psobp coefficients"):
        bench.bench_speed(tmp_path, model=path, samples=100)
