"""The mounting acceptance figure of issue 16: x-io's example log (its board's z axis points up, no
reference) trained with `imufmu train` at the defaults, built with `imufmu build-fmu`, run through
the FMU with fmpy, and compared with x-io Fusion (package imufusion, its README settings:
training.bench.bench.run_xio_fusion) on the same log. x-io Fusion's attitude is in the sensor's axes; it
is compared in two ways: the tilt from level of each (x-io Fusion's by its own convention, z up
= level), and BROAD's inclination error of q_FMU ⊗ q_Fusion⁻¹ with Fusion's attitude turned into the
FMU's body axes (training.mounting.body_attitude). The second row runs the same FMU with the
mounting reset to the identity (mount_y = 2, mount_z = 3): the board then reads upside down.
The assertion lives in tests/test_mounting.py; this prints the table in docs/fmu.md (Mounting).

Usage: OMP_NUM_THREADS=1 .venv/bin/python benchmarks/xio_mounting.py
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT)]

from contract.layout import OUTPUTS  # noqa: E402
from contract.mounting import IDENTITY, MOUNT_SETTINGS, Z_UP  # noqa: E402
from fmu.cosim import run_fmu  # noqa: E402
from training.artefact import load_artefact, settings_dict  # noqa: E402
from training.bench.bench import run_xio_fusion  # noqa: E402
from training.cli import main  # noqa: E402
from training.data.io import read_imu_csv  # noqa: E402
from training.evaluate import tilt_from_level, tilt_heading_between  # noqa: E402
from training.mounting import body_attitude  # noqa: E402

XIO = ROOT.parent / "shared" / "data" / "xio_handheld" / "xio_handheld.csv.gz"
_Q = [OUTPUTS.index(name) for name in ("q_w", "q_x", "q_y", "q_z")]


def _row(label: str, out: np.ndarray, q_fusion: np.ndarray, codes) -> str:
    """One table row: median roll; |tilt from level − x-io Fusion's| (Fusion's own convention for this
    board, z up = level: its attitude in the body axes of Z_UP); the inclination error of
    q_FMU ⊗ q_Fusion⁻¹ with Fusion's attitude in the FMU's body axes (`codes`). Medians and p90 [°]."""
    q = out[:, _Q]
    tilt = np.rad2deg(np.abs(tilt_from_level(q) - tilt_from_level(body_attitude(q_fusion, Z_UP))))
    error = np.rad2deg(tilt_heading_between(q, body_attitude(q_fusion, codes))[:, 0])
    roll = np.rad2deg(out[:, OUTPUTS.index("roll")])
    cells = [f"{np.percentile(x, 50):.2f} / {np.percentile(x, 90):.2f}" for x in (tilt, error)]
    return f"| {label} | {', '.join(map(str, codes))} | {np.median(roll):+.1f} | {cells[0]} | {cells[1]} |"


def main_table() -> None:
    data = read_imu_csv(XIO)
    q_fusion = run_xio_fusion(data)
    with tempfile.TemporaryDirectory(prefix="imufusion-xio-") as tmp:
        # the log leaves its gyro and magnetometer uncalibrated (train exits 3 without --allow-partial)
        if main(["train", str(XIO), "--out", tmp, "--allow-partial"]) != 0 or main(
                ["build-fmu", "--model", f"{tmp}/model.json", "--out", f"{tmp}/ImuFusion.fmu"]) != 0:
            raise SystemExit("training or building the FMU failed")
        settings = settings_dict(load_artefact(f"{tmp}/model.json"))
        codes = tuple(int(settings[name]) for name in MOUNT_SETTINGS)
        mounted = run_fmu(f"{tmp}/ImuFusion.fmu", data.t, data.inputs())
        unmounted = run_fmu(f"{tmp}/ImuFusion.fmu", data.t, data.inputs(),
                            parameters=dict(zip(MOUNT_SETTINGS, map(float, IDENTITY))))
    print()
    print("| FMU run | mount_x, mount_y, mount_z | median roll [°] | tilt from level − x-io Fusion's, "
          "median / p90 [°] | inclination error against x-io Fusion, median / p90 [°] |")
    print("|---|---|---|---|---|")
    print(_row("trained by `imufmu train` (mounting set by train)", mounted, q_fusion, codes))
    print(_row("same FMU, mounting reset to the identity", unmounted, q_fusion, IDENTITY))


if __name__ == "__main__":
    main_table()
