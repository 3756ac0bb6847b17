"""Can a field norm tell an outside current from the calibration it bent? The x-io case of
benchmarks/diagnose_real_injected.py probed with the exact model (issue 30's evidence).

    python benchmarks/norm_identifiability.py [--data ../shared/data] [--out DIR]

The x-io handheld log has no reference: the diagnosis sees the field norm only. The current of
diagnose_real_injected's "field of a motor current (no reference)" (c = 1.5, −1, 2 µT/A, 0–10 A) is in the
calibration part (`train` on the first 60 %) and the diagnosed part alike. On the diagnosed part's training
blocks, the exact norm model |A·(x − b − c·I)| = n (x the trained model's field, A = I + a symmetric change,
b an offset, n the field norm) is fitted by scipy's least squares in four ways, and each is scored on the
held-out blocks the diagnosis uses: the current with the calibration refitted (what issue 30 asks), the
current held at its injected value, the calibration held at train's, and the calibration held first then
freed. Prints a Markdown table.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))

from diagnose_real_injected import CASES, _xio  # noqa: E402

from training.artefact import load_artefact  # noqa: E402
from training.diagnosis.diagnose import load_recordings, residuals, targets_of  # noqa: E402
from training.train import train  # noqa: E402

CASE = "field of a motor current (no reference)"
INJECTED = np.array([1.5, -1.0, 2.0])


class NormModel:
    """|A·(x − b − c·I)| − n on rows; p = [a_xx, a_yy, a_zz, a_xy, a_xz, a_yz, b (3), c (3)]."""

    def __init__(self, x: np.ndarray, current: np.ndarray, norm: float) -> None:
        self.x, self.current, self.norm = x, current, norm

    def __call__(self, p: np.ndarray, rows: np.ndarray) -> np.ndarray:
        a = np.array([[p[0], p[3], p[4]], [p[3], p[1], p[5]], [p[4], p[5], p[2]]])
        moved = self.x[rows] - p[6:9] - np.outer(self.current[rows], p[9:12])
        return np.linalg.norm(moved @ (np.eye(3) + a).T, axis=1) - self.norm


def _fit(model: NormModel, rows: np.ndarray, free: np.ndarray, start: np.ndarray) -> np.ndarray:
    """The parameters with only `free` (bool, 12) fitted from `start`."""
    def residual(q):
        p = start.copy()
        p[free] = q
        return model(p, rows)
    p = start.copy()
    p[free] = least_squares(residual, start[free]).x
    return p


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data")
    args = parser.parse_args(argv)
    _, effect, magnitude, _, _ = CASES[CASE]
    with tempfile.TemporaryDirectory() as tmp:
        calibration, paths, _ = _xio(args.data, effect, magnitude, Path(tmp), 1.0)
        model_path = train(calibration, seed=0, progress=False).save(Path(tmp) / "model.json")
        datasets, _, smoothed = load_recordings(paths)
        r = residuals(load_artefact(model_path), datasets, targets_of(datasets[0]), smoothed)
    res = r.residual["mag_norm"][:, 0]
    ok = np.isfinite(res)
    x = np.column_stack([r.signals[f"mag_{a}"] for a in "xyz"])
    model = NormModel(x, r.signals["aux_motor_current"], float(np.median((np.linalg.norm(x, axis=1) - res)[ok])))
    train_rows, test_rows = r.train & ok, r.test & ok
    gain, offset, current = np.arange(12) < 6, (np.arange(12) >= 6) & (np.arange(12) < 9), np.arange(12) >= 9
    held = _fit(model, train_rows, offset | current, np.zeros(12))
    fits = {
        "current + calibration refitted, from zero": _fit(model, train_rows, np.ones(12, bool), np.zeros(12)),
        "current held at the injected value, calibration refitted": _fit(model, train_rows, gain | offset,
                                                                          np.r_[np.zeros(9), INJECTED]),
        "calibration held at train's, offset + current": held,
        "calibration held first, then everything freed": _fit(model, train_rows, np.ones(12, bool), held),
    }
    print(f"x-io, diagnosed part: field norm error RMS (held-out) before: {np.sqrt(np.mean(res[test_rows] ** 2)):.3f} µT; "
          f"injected c = {INJECTED.tolist()} µT/A\n")
    print("| fit | current c [µT/A] | largest gain change | offset b [µT] | field norm error RMS (held-out), µT |")
    print("|---|---|---|---|---|")
    for name, p in fits.items():
        print(f"| {name} | {np.round(p[9:12], 2).tolist()} | {100 * np.max(np.abs(p[:6])):.0f} % | "
              f"{np.round(p[6:9], 1).tolist()} | {np.sqrt(np.mean(model(p, test_rows) ** 2)):.3f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
