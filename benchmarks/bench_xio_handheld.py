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
- the magnetic disturbance (samples whose calibrated field norm leaves ±10 % of its median): the
  heading change of each filter across it against the heading change of the gyro alone.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from training import layout  # noqa: E402
from training.bench import run_xio_fusion  # noqa: E402
from training.io import read_imu_csv  # noqa: E402
from training.thermal import apply_thermal  # noqa: E402

DATA = ROOT.parent / "shared" / "data" / "xio_handheld" / "xio_handheld.csv.gz"
#: A field whose calibrated norm leaves ±10 % of the recording's median is disturbed: the band the
#: quaternion filter's own rejection uses (ImuAttitude.c) and far above the calibrated spread.
DISTURBED_NORM = 0.10
_Q = [layout.OUTPUTS.index(n) for n in ("q_w", "q_x", "q_y", "q_z")]
_ACC = [layout.OUTPUTS.index(n) for n in ("accel_x", "accel_y", "accel_z")]
_FIELD = [layout.OUTPUTS.index(n) for n in ("field_x", "field_y", "field_z")]


def up_in_body(q: np.ndarray) -> np.ndarray:
    """(N, 3) unit 'up' of NED (0, 0, -1) expressed in the body for body -> NED quaternions q (N, 4)."""
    w, x, y, z = q.T
    # third row of R(q) (NED z in body coordinates), negated
    return -np.column_stack([2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z])


def heading(q: np.ndarray) -> np.ndarray:
    """(N,) yaw [rad] of body -> NED quaternions (ZYX)."""
    w, x, y, z = q.T
    return np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def angle_deg(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(N,) angle [°] between unit vectors u, v (N, 3)."""
    return np.degrees(np.arccos(np.clip(np.sum(u * v, axis=1), -1.0, 1.0)))


def wrap_deg(a: np.ndarray) -> np.ndarray:
    """Angles [°] wrapped to (-180, 180]."""
    return (a + 180.0) % 360.0 - 180.0


def _disturbed_span(field: np.ndarray, t: np.ndarray) -> tuple[int, int] | None:
    """[first, last] sample index of the longest run of disturbed field norm, or None."""
    norm = np.linalg.norm(field, axis=1)
    bad = np.abs(norm / np.nanmedian(norm) - 1.0) > DISTURBED_NORM
    edges = np.flatnonzero(np.diff(np.concatenate([[0], bad.astype(int), [0]])))
    runs = list(zip(edges[::2], edges[1::2]))
    if not runs:
        return None
    a, b = max(runs, key=lambda r: t[r[1] - 1] - t[r[0]])
    return int(a), int(b - 1)


def _gyro_heading_change(rate: np.ndarray, q: np.ndarray, t: np.ndarray, a: int, b: int) -> float:
    """Heading change [°] from a to b of the gyro alone: the yaw rate in NED (R(q)·ω, z) integrated."""
    w, x, y, z = q.T
    r3 = np.column_stack([2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z])
    yaw_rate = np.sum(r3 * rate, axis=1)
    return float(np.degrees(np.sum(yaw_rate[a:b] * np.diff(t[a:b + 1]))))


def main() -> None:
    from fmu.cosim import run_fmu
    from fmu.packer import build_fmu
    from training.artefact import coefficients_array, settings_dict
    from training.calibration_report import summary_text, write_calibration_report
    from training.pipeline import recording_parameters
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
    q_imu, q_xio = res[:, _Q], run_xio_fusion(data)
    acc_c = apply_thermal(artefact.thermal["acc"], data.acc, data.temp)
    rest = detect_rest(data).mask
    up_acc = -acc_c / np.linalg.norm(acc_c, axis=1, keepdims=True)
    settle = t > 5.0  # both filters start from their first sample; 5 s of convergence excluded
    incl_diff = angle_deg(up_in_body(q_imu), up_in_body(q_xio))
    head_diff = wrap_deg(np.degrees(heading(q_imu) - heading(q_xio)))
    head_diff -= np.median(head_diff[settle])  # the raw-field Fusion heading has its own offset
    rows = [("inclination difference ImuFusion vs x-io Fusion, RMS [°]", np.sqrt(np.mean(incl_diff[settle] ** 2))),
            ("heading difference (median offset removed), RMS [°]", np.sqrt(np.mean(head_diff[settle] ** 2))),
            ("median heading offset between the two [°]", float(np.median(wrap_deg(np.degrees(heading(q_imu) - heading(q_xio)))[settle]))),
            ("rest samples (after 5 s)", int(np.sum(rest & settle)))]
    for name, q in (("ImuFusion", q_imu), ("x-io Fusion", q_xio)):
        e = angle_deg(up_in_body(q), up_acc)[rest & settle]
        rows.append((f"{name}: inclination at rest vs calibrated accelerometer, RMS [°]", float(np.sqrt(np.mean(e ** 2)))))
    span = _disturbed_span(res[:, _FIELD], t)
    if span:
        a, b = span
        gyro = _gyro_heading_change(res[:, [0, 1, 2]], q_imu, t, a, b)
        rows.append((f"magnetic disturbance {t[a]:.1f}-{t[b]:.1f} s: gyro-only heading change [°]", gyro))
        for name, q in (("ImuFusion", q_imu), ("x-io Fusion", q_xio)):
            change = float(wrap_deg(np.degrees(heading(q[b:b + 1]) - heading(q[a:a + 1])))[0])
            rows.append((f"  {name} heading change across it [°] (difference to gyro)", f"{change:.2f} ({change - gyro:+.2f})"))
    print("| quantity | value |\n|---|---|")
    for name, v in rows:
        print(f"| {name} | {v if isinstance(v, str) else f'{v:.3f}'} |")
    fmu.unlink()


if __name__ == "__main__":
    main()
