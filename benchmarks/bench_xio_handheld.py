"""xio_handheld: a real handheld log with no reference at all — calibrate it, run the FMU, compare.

    python benchmarks/bench_xio_handheld.py [--data ../shared/data/xio_handheld/xio_handheld.csv.gz] [--out bench/xio]

There is no truth, so the table reports what can be checked without one:

- the calibration summary of `imufmu train` (self-calibration, no reference) and the field-norm
  spread before → after;
- agreement of the ImuFusion FMU (at the settings `train` wrote, through fmpy) with x-io Fusion
  (the log's own library, `imufusion`, its README settings, on the raw log as x-io's example runs
  it): RMS of the inclination and heading differences;
- inclination at rest against the calibrated accelerometer (at rest the specific force is
  gravity, so it gives the inclination to within its calibration), for both filters;
- the magnetic disturbance (rest samples whose calibrated field norm leaves ±10 % or whose dip
  leaves ±10° of its median at rest): the heading change of each filter across it against that of
  the gyro alone.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from contract import layout  # noqa: E402
from contract.mounting import mount_matrix, settings_codes  # noqa: E402
from training.bench.bench import run_xio_fusion  # noqa: E402
from training.data.io import read_imu_csv  # noqa: E402
from training.frames import euler_from_quat, quat_multiply  # noqa: E402
from training.models.thermal import apply_thermal  # noqa: E402
from training.mounting import body_attitude  # noqa: E402

DATA = ROOT.parent / "shared" / "data" / "xio_handheld" / "xio_handheld.csv.gz"
#: A field whose calibrated norm leaves ±10 % of its median at rest is disturbed: the band the
#: quaternion filter's own rejection uses (ImuAttitude.c) and far above the calibrated spread.
DISTURBED_NORM = 0.10
#: ... or whose dip leaves ±10° of its median at rest (the same rejection band, for the dip).
DISTURBED_DIP_DEG = 10.0
#: Disturbed rest samples less than this apart [s] are one disturbance (a hand moving the board
#: within a disturbed zone leaves rest for a few seconds).
MERGE_S = 5.0
#: Time after a disturbance [s] left out of the agreement figure: x-io Fusion's heading returns
#: within ~10 s (its recovery trigger period, 5 s at its settings, plus convergence).
RECOVERY_S = 10.0
_Q = [layout.OUTPUTS.index(n) for n in ("q_w", "q_x", "q_y", "q_z")]
_ACC = [layout.OUTPUTS.index(n) for n in ("accel_x", "accel_y", "accel_z")]


def up_in_body(q: np.ndarray) -> np.ndarray:
    """(N, 3) unit 'up' of NED (0, 0, -1) expressed in the body for body -> NED quaternions q (N, 4)."""
    w, x, y, z = q.T
    # third row of R(q) (NED z in body coordinates), negated
    return -np.column_stack([2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z])


def heading(q: np.ndarray) -> np.ndarray:
    """(N,) yaw [rad] of body -> NED quaternions (ZYX)."""
    return euler_from_quat(q)[:, 0]


def heading_difference_deg(qa: np.ndarray, qb: np.ndarray) -> np.ndarray:
    """(N,) signed heading difference [°] of two body -> NED attitudes, defined at every attitude:
    the rotation about the vertical of q_err = qa ⊗ qb⁻¹ (BROAD's split), 2·atan2(z, w)."""
    err = quat_multiply(qa, qb * np.array([1.0, -1.0, -1.0, -1.0]))
    return wrap_deg(np.degrees(2.0 * np.arctan2(err[:, 3], err[:, 0])))


def angle_deg(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(N,) angle [°] between unit vectors u, v (N, 3)."""
    return np.degrees(np.arccos(np.clip(np.sum(u * v, axis=1), -1.0, 1.0)))


def wrap_deg(a: np.ndarray) -> np.ndarray:
    """Angles [°] wrapped to (-180, 180]."""
    return (a + 180.0) % 360.0 - 180.0


def dip_deg(acc: np.ndarray, field: np.ndarray) -> np.ndarray:
    """(N,) dip [°] of the field below the horizontal, from the specific force (up at rest) and the field."""
    cos_up = np.sum(acc * field, axis=1) / np.linalg.norm(acc, axis=1) / np.linalg.norm(field, axis=1)
    return np.degrees(np.arcsin(np.clip(-cos_up, -1.0, 1.0)))


def _disturbed_span(field: np.ndarray, acc: np.ndarray, rest: np.ndarray, t: np.ndarray) -> tuple[int, int] | None:
    """[first, last] sample index of the longest disturbance seen at rest (where the accelerometer gives
    gravity): field norm off its rest median by more than DISTURBED_NORM, or dip off by more than
    DISTURBED_DIP_DEG; disturbed rest samples less than MERGE_S apart belong to one disturbance."""
    norm, dip = np.linalg.norm(field, axis=1), dip_deg(acc, field)
    bad = rest & ((np.abs(norm / np.median(norm[rest]) - 1.0) > DISTURBED_NORM)
                  | (np.abs(dip - np.median(dip[rest])) > DISTURBED_DIP_DEG))
    idx = np.flatnonzero(bad)
    if idx.size == 0:
        return None
    groups = np.split(idx, np.flatnonzero(np.diff(t[idx]) > MERGE_S) + 1)
    longest = max(groups, key=lambda g: t[g[-1]] - t[g[0]])
    return int(longest[0]), int(longest[-1])


def _gyro_heading_change(rate: np.ndarray, q: np.ndarray, t: np.ndarray, a: int, b: int) -> float:
    """Heading change [°] from a to b of the gyro alone: the yaw rate in NED (R(q)·ω, z) integrated."""
    w, x, y, z = q.T
    r3 = np.column_stack([2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z])
    yaw_rate = np.sum(r3 * rate, axis=1)
    return float(np.degrees(np.sum(yaw_rate[a:b] * np.diff(t[a:b + 1]))))


def main() -> None:
    from fmu.cosim import run_fmu
    from training.artefact import coefficients_array, settings_dict
    from training.fmu_build import build_fmu
    from training.main_job import recording_parameters
    from training.reports.calibration_report import summary_text, write_calibration_report
    from training.selfcal.rest import detect_rest
    from training.train import train
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", default=str(DATA))
    p.add_argument("--out", default="bench/xio")
    args = p.parse_args()
    out = Path(args.out)
    data = read_imu_csv(args.data)
    artefact = train([data], seed=0, progress=False)
    write_calibration_report(artefact, [data], out)
    print(summary_text(artefact, [data]), "\n")
    fmu = build_fmu(coefficients_array(artefact), settings_dict(artefact), out / "ImuFusion.fmu")
    t = data.t - data.t[0]
    res = run_fmu(fmu, t, data.inputs(), parameters=recording_parameters(data))
    # The FMU reports in the body axes of the mounting train set; x-io Fusion and the calibrated
    # accelerometer are in the sensor's: both are turned into the body axes before any comparison.
    codes = settings_codes(settings_dict(artefact))
    q_imu, q_xio = res[:, _Q], body_attitude(run_xio_fusion(data), codes)
    acc_c = apply_thermal(artefact.thermal["acc"], data.acc, data.temp) @ mount_matrix(codes).T
    rest = detect_rest(data).mask
    up_acc = acc_c / np.linalg.norm(acc_c, axis=1, keepdims=True)  # at rest f = −g points up
    settle = t > 5.0  # both filters start from their first sample; 5 s of convergence excluded
    incl_diff = angle_deg(up_in_body(q_imu), up_in_body(q_xio))
    head_diff = heading_difference_deg(q_imu, q_xio)
    offset = float(np.median(head_diff[settle]))  # Fusion uses the raw field: its own heading offset
    rows = [("inclination difference ImuFusion vs x-io Fusion, RMS [°]", np.sqrt(np.mean(incl_diff[settle] ** 2))),
            ("heading difference, median [°]", offset),
            ("heading difference about its median, RMS [°]", np.sqrt(np.mean(wrap_deg(head_diff - offset)[settle] ** 2))),
            ("rest samples (after 5 s)", f"{int(np.sum(rest & settle))}")]
    for name, q in (("ImuFusion", q_imu), ("x-io Fusion", q_xio)):
        e = angle_deg(up_in_body(q), up_acc)[rest & settle]
        rows.append((f"{name}: inclination at rest vs calibrated accelerometer, RMS [°]", float(np.sqrt(np.mean(e ** 2)))))
    # The disturbance as the calibrated magnetometer saw it (not the FMU's field output, which the
    # particle filter, when train switches it on, adapts to the disturbance).
    mag_c = apply_thermal(artefact.thermal["mag"], data.mag, data.temp) @ mount_matrix(codes).T
    span = _disturbed_span(mag_c, acc_c, rest, t)
    if span:
        a, b = span
        gyro = _gyro_heading_change(res[:, [0, 1, 2]], q_imu, t, a, b)
        rows.append((f"magnetic disturbance {t[a]:.1f}-{t[b]:.1f} s: gyro-only heading change [°]", gyro))
        calm = settle & ((t < t[a]) | (t > t[b] + RECOVERY_S))
        rows.insert(3, (f"heading difference about its median outside {t[a]:.0f}-{t[b] + RECOVERY_S:.0f} s "
                        "(the disturbance and Fusion's recovery), RMS [°]",
                        np.sqrt(np.mean(wrap_deg(head_diff - offset)[calm] ** 2))))
        for name, q in (("ImuFusion", q_imu), ("x-io Fusion", q_xio)):
            change = float(heading_difference_deg(q[b:b + 1], q[a:a + 1])[0])
            rows.append((f"  {name} heading change across it [°] (difference to gyro)", f"{change:.2f} ({change - gyro:+.2f})"))
    print("| quantity | value |\n|---|---|")
    for name, v in rows:
        print(f"| {name} | {v if isinstance(v, str) else f'{v:.3f}'} |")
    fmu.unlink()


if __name__ == "__main__":
    main()
