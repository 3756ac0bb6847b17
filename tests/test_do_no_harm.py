"""A calibration never does harm silently (issue 15, item 3): a triad whose fit is worse than the
raw sensor on held-out data is not exported; the identity is kept and the summary says so."""
from __future__ import annotations

from training.data.io import read_imu_csv
from training.reports.calibration_report import triad_summary
from training.train import train

def test_a_fit_worse_than_raw_on_held_out_data_is_not_exported(xio_log):
    """x-io's example log (a sensor calibrated inside, no reference): the gyro bias fitted on the
    first 75 % of its rests leaves a larger mean rate on the last 25 % than the raw gyro (0.0100 vs
    0.0088 °/s), so the gyro stays the identity, loudly; the accelerometer's bias fit helps on held-out
    rests (gravity norm 0.063 → 0.0017 m/s²) and is kept."""
    art = train([read_imu_csv(xio_log)], seed=0, progress=False)
    held = art.fit_stats["gyr"]["held_out"]
    assert held["after"] > held["before"]
    assert not art.thermal["gyr"].enabled
    assert any(n.startswith("gyr: NOT EXPORTED") for n in art.notes)
    assert "worse than the raw sensor on held-out data" in "\n".join(triad_summary(art, "gyr"))
    acc = art.fit_stats["acc"]["held_out"]
    assert acc["after"] < acc["before"] and art.thermal["acc"].enabled
