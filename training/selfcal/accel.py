"""Accelerometer gains, misalignment and bias from the gravity-norm invariant at rest (and the
identifiability test `judge` that the magnetometer and gyro fits share).

At rest the specific force is -gravity whatever the pose, so its calibrated norm is g:

    ‖A (f_k - B(T_k))‖ = g   at every rest or hold k

(Tedaldi, Pretto, Menegatti, "A robust and easy to implement method for IMU calibration without
external equipments", ICRA 2014, eq. 10; Skog & Händel, "Calibration of a MEMS inertial
measurement unit", IMEKO XVII 2006).

A symmetric 3x3 (6 unknowns: 3 gains, 3 non-orthogonalities; the antisymmetric part is a
rotation, which no norm can see, so the body frame is defined as the orthogonal frame closest to
the sensor axes) and B(T) per-axis polynomials of normalised temperature. Fitted by casadi/IPOPT
(deterministic). What the poses identify is decided from the Jacobian at the solution: its
condition number and the parameters' standard errors. Models are tried from the richest down:
symmetric A + B(T), symmetric A + b, diagonal gains + b, bias b only, nothing.
"""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from training.selfcal.rest import RestWindow, count_poses
from training.selfcal.temperature import choose_degree, cluster_labels, powers

#: Local gravity differs from standard gravity by up to ±0.3 % (9.780 m/s² at the equator,
#: 9.832 m/s² at the poles, less with altitude); the fitted gains scale with the g passed in.
GRAVITY_NOTE = ("gains scale with the g used; local gravity differs from 9.80665 m/s² by up to "
                "±0.3 % (latitude, altitude): pass the local value for absolute accuracy")
#: Largest condition number of the scaled Jacobian (residual / g versus A entries and b / g) for a
#: model to count as identifiable: beyond it some parameter combination is determined 1000x
#: worse than the best one — numerically a missing rank, whatever the noise.
MAX_CONDITION = 1e3
#: Largest standard error of any parameter (A dimensionless, b relative to g) for a model to be
#: accepted: 2e-3 = 0.2 % of gain or 2 mg of bias, a fifth of the ~1 % / ~10 mg errors of a MEMS
#: accelerometer — a parameter the poses pin down worse than that is not worth fitting.
MAX_PARAM_STD = 2e-3
#: Levels, richest first: (name, shape of A, has temperature terms).
LEVELS = (("symmetric A + b(T)", "symmetric", True), ("symmetric A + b", "symmetric", False),
          ("diagonal scale + b", "diagonal", False), ("bias b only", "identity", False))
#: Upper-triangle entries of a symmetric A, in parameter order.
_SYMMETRIC = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))


@dataclass(frozen=True)
class ModelCheck:
    """Identifiability of one model: condition number of the scaled Jacobian, the largest
    parameter standard error (scaled) and its name, the residual RMS [unit], and the verdict."""

    condition: float
    worst_std: float
    worst_param: str
    residual_rms: float
    accepted: bool
    reason: str


@dataclass(frozen=True)
class AccelFit:
    """Result: level (one of LEVELS' names or 'nothing'), A (3, 3), b (3, P+1) m/s² in powers of
    Tn, degree P, reason (why not a richer model), poses and (pose, temperature) groups used,
    gravity-norm RMS over the rests before/after [m/s²], the check of the accepted model and
    every level tried [(name, ModelCheck or reason)]."""

    level: str
    A: np.ndarray
    b: np.ndarray
    degree: int
    reason: str
    poses: int
    groups: int
    rms_before: float
    rms_after: float
    check: ModelCheck | None
    tried: list = field(default_factory=list)


def gain_summary(A: np.ndarray) -> dict:
    """Gains, non-orthogonality and axis misalignment of the raw axes implied by x_c = A (x - b).

    The raw reading is x = A^-1 x_c + b, so row i of A^-1 is the sensitive axis of raw axis i in
    the calibrated frame: its norm is the axis gain [1], its angle to body axis i the misalignment
    [deg], and 90° minus the angle between two rows their non-orthogonality [deg]."""
    inv = np.linalg.inv(A)
    gains = np.linalg.norm(inv, axis=1)
    axes = inv / gains[:, None]
    pairs = {"xy": (0, 1), "xz": (0, 2), "yz": (1, 2)}
    return {"scale_factors": gains.tolist(),
            "scale_factor_error_pct": ((gains - 1.0) * 100.0).tolist(),
            "nonorthogonality_deg": {k: 90.0 - _angle_deg(axes[i] @ axes[j]) for k, (i, j) in pairs.items()},
            "misalignment_deg": [_angle_deg(axes[i, i]) for i in range(3)]}


def _angle_deg(cosine: float) -> float:
    """arccos of a cosine clipped to [-1, 1], in degrees."""
    return float(np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0))))


def judge(jac: np.ndarray, residual: np.ndarray, weights: np.ndarray, names: list[str],
          sigma_floor: float, unit_scale: float, max_condition: float, max_std) -> ModelCheck:
    """Identifiability from the scaled Jacobian jac (K, p) and scaled residuals (K,) with weights
    (K,) summing to the number of independent data points.

    Standard errors: cov = σ² (Jᵀ W J)⁻¹, σ² = Σ w r² / (Σ w - p), floored at sigma_floor²
    (ordinary least-squares theory); max_std: bound per parameter (scalar or (p,)). unit_scale
    converts the scaled residual RMS back to the unit."""
    p = jac.shape[1]
    dof = float(weights.sum()) - p
    rms = float(np.sqrt(np.sum(weights * residual ** 2) / max(weights.sum(), 1e-300))) * unit_scale
    if dof < 1:
        return ModelCheck(np.inf, np.inf, "", rms, False,
                          f"{p} parameters need more than {p} independent rests, have {weights.sum():.0f}")
    jw = jac * np.sqrt(weights)[:, None]
    sv = np.linalg.svd(jw, compute_uv=False)
    condition = float(sv[0] / sv[-1]) if sv[-1] > 0 else np.inf
    if condition > max_condition:
        return ModelCheck(condition, np.inf, "", rms, False,
                          f"Jacobian condition {condition:.3g} > {max_condition:.0g}: the data do not "
                          f"separate all {p} parameters")
    sigma2 = max(float(np.sum(weights * residual ** 2)) / dof, sigma_floor ** 2)
    std = np.sqrt(np.diag(np.linalg.inv(jw.T @ jw)) * sigma2)
    bound = np.broadcast_to(np.asarray(max_std, dtype=float), std.shape)
    worst = int(np.argmax(std / bound))
    if std[worst] > bound[worst]:
        return ModelCheck(condition, float(std[worst]), names[worst], rms, False,
                          f"standard error of {names[worst]} is {std[worst]:.2g} > {bound[worst]:.0e}")
    return ModelCheck(condition, float(std[worst]), names[worst], rms, True, "")


def _parameters(shape: str, degree: int, gain_degree: int = 0, sym=ca.MX) -> tuple:
    """(x, A(x) 3x3, B(x) 3x(P+1), G(x) 3xQ or None, parameter names) for an A of `shape`, bias
    degree P and gain degree Q; x = [A entries, B column-major, G column-major]. MX by default:
    the model is then a handful of whole-matrix operations on 3xK data (fast for large K)."""
    n_a = {"symmetric": 6, "diagonal": 3, "identity": 0}[shape]
    x = sym.sym("x", n_a + 3 * (degree + 1) + 3 * gain_degree)
    if shape == "symmetric":
        a = [[None] * 3 for _ in range(3)]
        for k, (i, j) in enumerate(_SYMMETRIC):
            a[i][j] = a[j][i] = x[k]
        A = ca.vertcat(*[ca.horzcat(*row) for row in a])
        names = [f"A[{i},{j}]" for i, j in _SYMMETRIC]
    elif shape == "diagonal":
        A = ca.diag(x[:3])
        names = [f"A[{i},{i}]" for i in range(3)]
    else:
        A = sym.eye(3)
        names = []
    n_b = n_a + 3 * (degree + 1)
    B = ca.reshape(x[n_a:n_b], 3, degree + 1)  # column k = coefficients of Tn^k
    G = ca.reshape(x[n_b:], 3, gain_degree) if gain_degree else None  # column k-1: Tn^k
    names += [f"b{'xyz'[i]}·Tn^{k}" for k in range(degree + 1) for i in range(3)]
    names += [f"g{'xyz'[i]}·Tn^{k}" for k in range(1, gain_degree + 1) for i in range(3)]
    return x, A, B, G, names


def _initial(shape: str, degree: int, gain_degree: int = 0) -> np.ndarray:
    """Start of the fit: A = I, b = 0, G = 1."""
    a0 = {"symmetric": [1, 0, 0, 1, 0, 1], "diagonal": [1, 1, 1], "identity": []}[shape]
    return np.concatenate([np.array(a0, dtype=float), np.zeros(3 * (degree + 1) + 3 * gain_degree)])


def pack(A: np.ndarray, b: np.ndarray, g: np.ndarray | None = None) -> np.ndarray:
    """Parameter vector of a symmetric A (3, 3), b (3, P+1) and g (3, Q) (see _parameters)."""
    parts = [np.array([A[i, j] for i, j in _SYMMETRIC]), b.T.ravel()]
    return np.concatenate(parts + ([g.T.ravel()] if g is not None and g.size else []))


def unpack(shape: str, degree: int, sol: np.ndarray, gain_degree: int = 0) -> tuple[np.ndarray, ...]:
    """(A (3, 3), b (3, P+1), g (3, Q)) from the solution vector."""
    x, A, B, G, _ = _parameters(shape, degree, gain_degree)
    outs = [A, B] + ([G] if G is not None else [])
    values = [np.asarray(v) for v in ca.Function("abg", [x], outs)(sol)]
    g = values[2].reshape(3, gain_degree) if gain_degree else np.zeros((3, 0))
    return values[0], values[1].reshape(3, degree + 1), g


def fit_norm_model(data: np.ndarray, tpow: np.ndarray, weights: np.ndarray, norm: float,
                   shape: str, degree: int, gain_degree: int = 0,
                   x0: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str]]:
    """Least squares of Σ w_k (‖A (G(T_k) ⊙ (x_k - B v_k))‖ - norm)² by IPOPT (the runtime's model).

    data (K, 3), tpow (K, P+1) powers Tn^0..Tn^max(P, Q), weights (K,); G_i = 1 + Σ_k g[i, k-1] Tn^k.
    Returns (solution vector, scaled residual (K,) = (‖·‖ - norm)/norm, scaled Jacobian (K, p): A
    and G entries as they are, b entries per unit of norm, parameter names)."""
    x, A, B, G, names = _parameters(shape, degree, gain_degree)
    d = ca.DM(data.T) - ca.mtimes(B, ca.DM(tpow[:, :degree + 1].T))
    if G is not None:
        d = d * (1 + ca.mtimes(G, ca.DM(tpow[:, 1:gain_degree + 1].T)))
    y = ca.mtimes(A, d)
    r = ((ca.sqrt(ca.sum1(y * y)) - norm) / norm).T
    solver = ca.nlpsol("norm_fit", "ipopt", {"x": x, "f": ca.sum1(ca.DM(weights) * r * r)},
                       {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes",
                        "ipopt.tol": 1e-12})
    start = _initial(shape, degree, gain_degree) if x0 is None else x0
    sol = np.asarray(solver(x0=start)["x"]).ravel()
    fn = ca.Function("rj", [x], [r, ca.jacobian(r, x)])
    res, jac = (np.asarray(v) for v in fn(sol))
    n_a = len(names) - 3 * (degree + 1) - 3 * gain_degree
    jac = jac.copy()
    jac[:, n_a:n_a + 3 * (degree + 1)] *= norm  # derivative per (b / norm): dimensionless like A
    return sol, res.ravel(), jac, names


def group_weights(windows: list[RestWindow]) -> tuple[np.ndarray, int]:
    """(weights (K,), groups): 1 / size of each window's (pose, temperature cluster) group, so every
    distinct pose at every distinct temperature counts once however long it was held."""
    keys = list(zip([w.pose for w in windows], cluster_labels(np.array([w.temp for w in windows]))))
    counts = Counter(keys)
    return np.array([1.0 / counts[k] for k in keys]), len(counts)


def _noise_floor(windows: list[RestWindow], g: float) -> float:
    """Median noise of a rest mean relative to g: ‖per-axis std‖ / √count / g."""
    return float(np.median([np.linalg.norm(w.acc_std) / np.sqrt(w.count) for w in windows])) / g


def fit_accelerometer(windows: list[RestWindow], gravity: float, t0: float, ts: float,
                      degree: int) -> AccelFit:
    """Fit the richest identifiable model to the rests' mean specific force (acc finite).

    gravity: local g [m/s²]; t0, ts: temperature normalisation [°C]; degree: largest B(T) degree."""
    use = [w for w in windows if np.all(np.isfinite(w.acc))]
    if not use:
        return AccelFit("nothing", np.eye(3), np.zeros((3, 1)), 0,
                        "no rest with the accelerometer recorded", 0, 0, np.nan, np.nan, None)
    f = np.array([w.acc for w in use])
    temp = np.array([w.temp for w in use])
    weights, groups = group_weights(use)
    weights = weights * groups / weights.sum()
    before = float(np.sqrt(np.mean((np.linalg.norm(f, axis=1) - gravity) ** 2)))
    p_temp, why_degree = choose_degree(temp, degree, groups - 6, per_degree=3)
    floor = _noise_floor(use, gravity)
    tried = []
    for name, shape, thermal in LEVELS:
        p = p_temp if thermal else 0
        if thermal and p == 0:
            tried.append((name, why_degree or "no temperature span"))
            continue
        sol, res, jac, names = fit_norm_model(f, powers(temp, t0, ts, p), weights, gravity, shape, p)
        check = judge(jac, res, weights, names, floor, gravity, MAX_CONDITION, MAX_PARAM_STD)
        tried.append((name, check))
        if check.accepted:
            A, b, _ = unpack(shape, p, sol)
            after = _norm_rms(A, b, f, powers(temp, t0, ts, p), gravity)
            return AccelFit(name, A, b, p, _why_not_more(tried[:-1]), count_poses(use), groups,
                            before, after, check, tried)
    return AccelFit("nothing", np.eye(3), np.zeros((3, 1)), 0, _why_not_more(tried), count_poses(use),
                    groups, before, before, None, tried)


def _norm_rms(A: np.ndarray, b: np.ndarray, x: np.ndarray, tpow: np.ndarray, norm: float) -> float:
    """RMS of ‖A (x_k - b v_k)‖ - norm over the rows of x (K, 3)."""
    y = (x - tpow @ b.T) @ A.T
    return float(np.sqrt(np.mean((np.linalg.norm(y, axis=1) - norm) ** 2)))


def _why_not_more(tried: list) -> str:
    """'; '-joined reasons of the richer levels that were rejected."""
    return "; ".join(f"{name}: {c if isinstance(c, str) else c.reason}" for name, c in tried)


def summarise(fit: AccelFit, gravity: float, t0: float, ts: float) -> dict:
    """Report entries of the accelerometer fit (numpy values; the caller makes them JSON-ready)."""
    out = {"unit": "m/s²", "fitted": fit.level, "why_not_more": fit.reason,
           "poses": fit.poses, "pose_temperature_groups": fit.groups, "degree": fit.degree,
           "bias": fit.b[:, 0], "bias_coefficients": fit.b, "t0_c": t0, "ts_c": ts,
           "gravity_ms2": gravity, "gravity_note": GRAVITY_NOTE,
           "residual": {"gravity_norm_rms_ms2": {"before": fit.rms_before, "after": fit.rms_after}},
           "levels_tried": [{"level": name, "accepted": not isinstance(c, str) and c.accepted,
                             "reason": c if isinstance(c, str) else c.reason,
                             "condition": None if isinstance(c, str) else c.condition}
                            for name, c in fit.tried]}
    out.update(gain_summary(fit.A))
    if fit.check is not None:
        out["jacobian_condition"] = fit.check.condition
        out["largest_std"] = {"parameter": fit.check.worst_param, "value": fit.check.worst_std}
    notes = [f"{fit.level} from {fit.poses} poses ({fit.groups} pose/temperature groups); gravity-norm "
             f"RMS {fit.rms_before:.4f} -> {fit.rms_after:.4f} m/s²"]
    if fit.reason:
        notes.append(f"not richer: {fit.reason}")
    out["notes"] = notes
    return out
