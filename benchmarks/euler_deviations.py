"""Two deviations of the adaptive-gain Euler fusion from its source, measured (issue 33 item 2,
docs/euler.md "As written / as built"): prints one Markdown table.

    python benchmarks/euler_deviations.py [--trials 01 02 ...] [--samples N] [--seed 0]

Recordings: the simulated `eval_handheld` scenario (its true rate, specific force and body field
plus seeded white noise of a calibrated MEMS unit, `simulated_recording`) and the BROAD trials
(default: all of ../shared/data/broad; `--trials` takes name prefixes). `--samples N` keeps the first
N samples of each (`--trials 01 --samples 3000` is the small input tests/test_doc_tables.py runs).

1. **Heading formula.** The product's Euler fusion (`--method attitude=euler`, every addition) is
   run through the batch runtime; its corrected field is de-tilted with its own roll and pitch
   outputs, m' = Ry(pitch) Rx(roll) m, and the heading RMS error against the reference (magnetic
   north, every eval_mask sample) is computed for the product's yaw = atan2(−m'_y, +m'_x) and for
   the source's formula read literally in the product's NED/FRD frame, atan2(−m'_y, −m'_x) = π − ψ.
2. **MSE propagation.** The source's form (`--method attitude=source-euler`, no bias estimate as in
   the BROAD ablation) is re-implemented in Python (`euler_fusion`) twice: with the product's
   growth of each angle's mean-square error, P_i += σ²·dt + (b·dt)² (`grow_diagonal`), and with the
   3×3 covariance of the angles propagated through the rotation-matrix update R ← R exp([ω×] dt)
   (`grow_through_rotation`, the source's propagation as docs/euler.md reads it). Both run on the same
   corrected rates, specific forces and fields (the runtime's outputs); the table gives the total,
   inclination and heading RMSE of each and, to show that the Python form is the C filter, the
   largest angle difference of the diagonal form from the runtime's own outputs.
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from contract import layout  # noqa: E402
from training import runtime  # noqa: E402
from training.bench.bench import broad_errors, trial_paths  # noqa: E402
from training.data.dataset import ImuData  # noqa: E402
from training.data.io import read_imu_csv  # noqa: E402
from training.data.reference import reference_euler_magnetic  # noqa: E402
from training.frames import quat_from_euler, wrap_angle  # noqa: E402
from training.main_job import SCENARIO_DIR  # noqa: E402
from training.models.methods import METHODS  # noqa: E402
from training.simulator import load_scenario, simulate  # noqa: E402

#: The product's Euler fusion (every addition) and the source's form; no gyro bias estimate in the
#: source's form (the source has none; as the "source's form" row of the BROAD ablation).
PRODUCT = dict(METHODS["attitude"]["euler"].settings)
SOURCE = {**METHODS["attitude"]["source-euler"].settings, "rest_gyro_threshold": 0.0}
#: White noise of a calibrated MEMS unit added to the simulated truth (as tests/test_attitude_recovery.py's
#: sensors, without their constant residual biases): gyro [rad/s], specific force [m/s²], field [µT] per sample.
SIM_NOISE = (math.radians(0.03), 0.02, 0.5)
#: Runtime output name -> column; the corrected rate, specific force and field triads; roll, pitch, yaw.
OUTPUT_COLUMN = {name: layout.OUTPUTS.index(name) for name in layout.OUTPUTS}
TRIAD_COLUMNS = [[OUTPUT_COLUMN[f"{p}_{a}"] for a in "xyz"] for p in ("rate", "accel", "field")]
EULER_COLUMNS = [OUTPUT_COLUMN[n] for n in ("roll", "pitch", "yaw")]


def simulated_recording(seed: int) -> ImuData:
    """eval_handheld: the simulator's true rate, specific force and body field plus SIM_NOISE (seeded)."""
    d = simulate(load_scenario(SCENARIO_DIR / "eval_handheld.toml"))
    rng = np.random.default_rng(seed)
    for triad, sigma in zip(("gyr", "acc", "mag"), SIM_NOISE):
        truth = getattr(d, f"ref_{triad}")
        setattr(d, triad, truth + sigma * rng.normal(size=truth.shape))
    return d


def settings(data: ImuData, overrides: dict) -> dict[str, float]:
    """The runtime's settings by name: defaults, the recording's field norm and dip, overrides."""
    ef = data.meta.get("earth_field") or {}
    return {**layout.settings_defaults(), "field_norm": float(ef["norm_ut"]),
            "field_dip": math.radians(float(ef["dip_deg"])), **overrides}


def run(data: ImuData, s: dict[str, float]) -> np.ndarray:
    """Runtime outputs (N, len(OUTPUTS)) of a recording (identity coefficients) at settings s."""
    return runtime.run_batch(layout.identity_coefficients(), layout.settings_array(s), data.t - data.t[0],
                             data.inputs())


def eval_rows(data: ImuData) -> np.ndarray:
    """(N,) bool: the samples that count (eval_mask where given) with a finite reference."""
    ok = np.isfinite(data.ref_q).all(axis=1)
    return ok & data.eval_mask.astype(bool) if data.eval_mask is not None else ok


def heading_errors_deg(data: ImuData, out: np.ndarray) -> tuple[float, float]:
    """Heading RMS error [°] of (the product's formula, the source's literal formula) on the runtime's
    corrected field de-tilted with its own roll and pitch."""
    roll, pitch = out[:, OUTPUT_COLUMN["roll"]], out[:, OUTPUT_COLUMN["pitch"]]
    m = out[:, TRIAD_COLUMNS[2]]
    cr, sr, cp, sp = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch)
    mx = cp * m[:, 0] + sp * sr * m[:, 1] + sp * cr * m[:, 2]       # Ry(pitch) Rx(roll) m, row x
    my = cr * m[:, 1] - sr * m[:, 2]                                 # row y
    ref = reference_euler_magnetic(data)[:, 2]
    rows = eval_rows(data) & np.isfinite(mx)

    def rms(yaw):
        return float(np.degrees(np.sqrt(np.mean(wrap_angle(yaw - ref)[rows] ** 2))))
    return rms(np.arctan2(-my, mx)), rms(np.arctan2(-my, -mx))


def rotation_from_euler(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Body -> NED rotation matrix of ZYX Euler angles [rad] (sources/ImuMath.c ImuMatrixFromEuler)."""
    cr, sr, cp, sp, cy, sy = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch), math.cos(yaw), math.sin(yaw)
    return np.array([[cp * cy, sr * sp * cy - cr * sy, cr * sp * cy + sr * sy],
                     [cp * sy, sr * sp * sy + cr * cy, cr * sp * sy - sr * cy],
                     [-sp, sr * cp, cr * cp]])


def euler_from_rotation(r: np.ndarray) -> np.ndarray:
    """[roll, pitch, yaw] [rad] of a body -> NED rotation matrix (ImuMatrixToEuler)."""
    return np.array([math.atan2(r[2, 1], r[2, 2]), math.atan2(-r[2, 0], math.hypot(r[2, 1], r[2, 2])),
                     math.atan2(r[1, 0], r[0, 0])])


def rotation_step(w: np.ndarray, dt: float) -> np.ndarray:
    """exp([w×] dt) (Rodrigues) for a body rate w [rad/s] over dt [s]."""
    v = w * dt
    angle = math.sqrt(float(v @ v))
    k = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    if angle < 1e-4:
        return np.eye(3) + (1.0 - angle * angle / 6.0) * k + (0.5 - angle * angle / 24.0) * (k @ k)
    return np.eye(3) + math.sin(angle) / angle * k + (1.0 - math.cos(angle)) / angle ** 2 * (k @ k)


def euler_rate_matrix(roll: float, pitch: float) -> np.ndarray:
    """E with d[roll, pitch, yaw] = E · (small body-frame rotation) [1] (ZYX kinematics)."""
    cr, sr, cp, tp = math.cos(roll), math.sin(roll), math.cos(pitch), math.tan(pitch)
    return np.array([[1.0, sr * tp, cr * tp], [0.0, cr, -sr], [0.0, sr / cp, cr / cp]])


def grow_diagonal(p: np.ndarray, before: np.ndarray, after: np.ndarray, step: np.ndarray, q: float) -> np.ndarray:
    """The product's growth: each angle's mean-square error [rad²] grows by q = σ²·dt + (b·dt)²."""
    return p + q * np.eye(3)


def grow_through_rotation(p: np.ndarray, before: np.ndarray, after: np.ndarray, step: np.ndarray,
                          q: float) -> np.ndarray:
    """The angles' covariance [rad²] through R ← R·step: a body-frame attitude error δ becomes stepᵀ δ and
    gains the rate noise q·I; the angle errors are E·δ before (E_b) and after (E_a) the step:
    P ← F P Fᵀ + q E_a E_aᵀ, F = E_a stepᵀ E_b⁻¹."""
    e_before, e_after = euler_rate_matrix(*before[:2]), euler_rate_matrix(*after[:2])
    f = e_after @ step.T @ np.linalg.inv(e_before)
    return f @ p @ f.T + q * (e_after @ e_after.T)


def correct(euler: np.ndarray, p: np.ndarray, mse: np.ndarray, axes: list[int], measured: list[float],
            alpha: float) -> np.ndarray:
    """Fuse the angles `axes` with their acc/mag measurements [rad] (gain K_i = P_ii / (P_ii + R_i),
    R_i the moving mean-square innovation, weight alpha); returns P after it, (I − K) P (I − K)ᵀ + K R K
    (for a diagonal P the product's P_i ← (1 − K_i) P_i)."""
    k = np.zeros(3)
    for i, z in zip(axes, measured):
        e = float(wrap_angle(z - euler[i]))
        mse[i] += alpha * (e * e - mse[i])
        k[i] = p[i, i] / (p[i, i] + mse[i]) if p[i, i] + mse[i] > 0.0 else 0.0
        euler[i] = float(wrap_angle(euler[i] + k[i] * e))
    a = np.eye(3) - np.diag(k)
    return a @ p @ a.T + np.diag(k * k * mse)


def tilt_measurement(acc: np.ndarray) -> list[float]:
    """[roll, pitch] [rad] of a specific force [m/s²]."""
    return [math.atan2(-acc[1], -acc[2]), math.atan2(acc[0], math.hypot(acc[1], acc[2]))]


def yaw_measurement(mag: np.ndarray, roll: float, pitch: float) -> float:
    """The product's yaw [rad] of a field [µT] de-tilted with roll, pitch: atan2(−m'_y, m'_x)."""
    m = rotation_from_euler(roll, pitch, 0.0) @ mag
    return math.atan2(-m[1], m[0])


def euler_fusion(t: np.ndarray, gyr: np.ndarray, acc: np.ndarray, mag: np.ndarray, s: dict[str, float],
                 grow, detilt_with_acc: bool = False) -> np.ndarray:
    """The adaptive-gain Euler fusion in the source's form (sources/ImuAttitudeEuler.c with
    euler_additions 0: the current rate held over the step, R_i the bare moving mean-square innovation,
    yaw de-tilted with the gyro-predicted tilt, or with the accelerometer's when detilt_with_acc) with the
    mean-square-error growth `grow`; inputs (N, 3) corrected rad/s, m/s², µT at times t (N,) s.
    Returns (N, 3) [roll, pitch, yaw] rad."""
    noise2 = s["angle_noise"] ** 2
    euler, p, mse = np.zeros(3), noise2 * np.eye(3), np.full(3, noise2)
    rotation, tilt_set, yaw_set = np.eye(3), False, False
    out = np.empty((len(t), 3))
    for k in range(len(t)):
        dt = t[k] - t[k - 1] if k else 0.0
        alpha = 1.0 - math.exp(-dt / s["mse_time_constant"]) if dt > 0.0 else 0.0
        if dt > 0.0 and np.isfinite(gyr[k]).all():
            step = rotation_step(gyr[k], dt)
            before = euler.copy()
            rotation = rotation @ step
            euler = euler_from_rotation(rotation)
            p = grow(p, before, euler, step, s["gyro_noise"] ** 2 * dt + (s["gyro_bias_residual"] * dt) ** 2)
        predicted = tilt_measurement(acc[k]) if detilt_with_acc and np.isfinite(acc[k]).all() else euler[:2].copy()
        if np.isfinite(acc[k]).all():
            if tilt_set:
                p = correct(euler, p, mse, [0, 1], tilt_measurement(acc[k]), alpha)
            else:
                euler[:2], tilt_set, predicted = tilt_measurement(acc[k]), True, tilt_measurement(acc[k])
        if np.isfinite(mag[k]).all():
            yaw = yaw_measurement(mag[k], *predicted)
            if yaw_set:
                p = correct(euler, p, mse, [2], [yaw], alpha)
            else:
                euler[2], yaw_set = yaw, True
        rotation = rotation_from_euler(*euler)
        out[k] = euler
    return out


def errors_deg(data: ImuData, euler: np.ndarray) -> dict[str, float]:
    """Total, heading and inclination RMSE [°] of [roll, pitch, yaw] (N, 3) against the reference."""
    return broad_errors(quat_from_euler(euler[:, ::-1]), data)


def measure(data: ImuData) -> dict[str, float]:
    """Both measurements of one recording (module docstring)."""
    product = run(data, settings(data, PRODUCT))
    formula, literal = heading_errors_deg(data, product)
    s = settings(data, SOURCE)
    c_out = run(data, s)
    gyr, acc, mag = (c_out[:, cols] for cols in TRIAD_COLUMNS)
    t = data.t - data.t[0]
    diagonal = euler_fusion(t, gyr, acc, mag, s, grow_diagonal)
    through_r = euler_fusion(t, gyr, acc, mag, s, grow_through_rotation)
    acc_tilt = euler_fusion(t, gyr, acc, mag, s, grow_diagonal, detilt_with_acc=True)
    twin = float(np.degrees(np.max(np.abs(wrap_angle(diagonal - c_out[:, EULER_COLUMNS])))))
    return {"formula": formula, "literal": literal, "twin": twin,
            **{f"diag_{k}": v for k, v in errors_deg(data, diagonal).items()},
            **{f"rot_{k}": v for k, v in errors_deg(data, through_r).items()},
            **{f"acc_{k}": v for k, v in errors_deg(data, acc_tilt).items()}}


HEADER = ("| recording | samples | heading, product's atan2(−m'_y, +m'_x) [°] | heading, source's atan2(−m'_y, −m'_x) "
          "[°] | source's form, P += σ²·dt: total / inclination / heading [°] | source's form, P through R: "
          "total / inclination / heading [°] | source's form, yaw de-tilted with the accelerometer's tilt: total / "
          "inclination / heading [°] | Python form vs C runtime, max [°] |")


def row(name: str, n: int, r: dict[str, float]) -> str:
    """One table row of `measure`'s figures."""
    def triple(prefix):
        return " / ".join(f"{r[f'{prefix}_{k}']:.2f}" for k in ("total", "inclination", "heading"))
    return (f"| {name} | {n} | {r['formula']:.2f} | {r['literal']:.2f} | {triple('diag')} | {triple('rot')} "
            f"| {triple('acc')} | {r['twin']:.1e} |")


def first_samples(data: ImuData, samples: int | None) -> ImuData:
    """The first `samples` samples of a recording (all when None)."""
    return data if samples is None else data.slice(slice(0, samples))


def mean_figures(results: list[dict[str, float]]) -> dict[str, float]:
    """Mean of each figure over recordings, the largest Python-vs-C difference."""
    return {k: (max if k == "twin" else np.mean)([r[k] for r in results]) for k in results[0]}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--trials", nargs="*", default=None, help="BROAD trial name prefixes (default: every trial)")
    p.add_argument("--samples", type=int, default=None, help="first N samples of each recording (default all)")
    p.add_argument("--seed", type=int, default=0, help="seed of the simulated sensor noise (default 0)")
    a = p.parse_args(argv)
    if a.samples is not None and a.samples < 100:
        p.error("--samples must be at least 100")
    try:
        paths = trial_paths(a.trials)
    except FileNotFoundError as e:
        p.error(str(e))
    print(HEADER)
    print("|---|---|---|---|---|---|---|---|")
    sim = first_samples(simulated_recording(a.seed), a.samples)
    print(row("simulated eval_handheld", len(sim), measure(sim)), flush=True)
    broad, samples = [], 0
    for path in paths:
        data = first_samples(read_imu_csv(path), a.samples)
        broad.append(measure(data))
        samples += len(data)
        print(row(path.name.removesuffix(".csv.gz"), len(data), broad[-1]), flush=True)
    print(row(f"BROAD, mean of {len(broad)} trials (Python vs C: largest)", samples, mean_figures(broad)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
