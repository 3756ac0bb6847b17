"""Accelerometer gains, misalignment and bias from the gravity-norm invariant at rest, and from the
directions of the six faces of a box where a recording has them (and the norm-model helpers and the
identifiability test `judge` that the magnetometer fit uses).

At rest the specific force is -gravity whatever the pose, so its calibrated norm is g:

    ‖A (f_k - B(T_k))‖ = g   at every rest or hold k

(Tedaldi, Pretto, Menegatti, "A robust and easy to implement method for IMU calibration without
external equipments", ICRA 2014, eq. 10; Skog & Händel, "Calibration of a MEMS inertial
measurement unit", IMEKO XVII 2006).

A symmetric 3x3 (6 unknowns: 3 gains, 3 non-orthogonalities; the antisymmetric part is a
rotation, which no norm can see, so the body frame is defined as the orthogonal frame closest to
the sensor axes) and B(T) per-axis polynomials of normalised temperature. At six rests on the faces
of a box (training.selfcal.faces, the Ferraris protocol) the calibrated directions must also be ±e_i of
one orthogonal frame, up to the rotation of the sensor in its box (a nuisance): that pins the
non-orthogonality, which the norm sees only to second order there. Fitted by regularised least
squares (training.selfcal.regularised, residuals and Jacobian by casadi): what the rests determine is
fitted from them, the rest held near nominal, every parameter with its standard error.
"""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

import casadi as ca
import numpy as np

from training.selfcal.faces import FaceSet, find_faces
from training.selfcal.regularised import Group, RegularisedFit, regularised_fit, uncertainty_report
from training.selfcal.poses import count_poses
from training.selfcal.rest import RestWindow
from training.selfcal.temperature import choose_degree, cluster_labels, powers

#: Local gravity differs from standard gravity by up to ±0.3 % (9.780 m/s² at the equator,
#: 9.832 m/s² at the poles, less with altitude); the fitted gains scale with the g passed in.
GRAVITY_NOTE = ("gains scale with the g used (the sidecar's gravity_mps2, else the site's normal gravity, else "
                "9.80665 m/s²; the notes say which): local gravity differs from 9.80665 m/s² by up to ±0.3 %")
#: Largest condition number of the scaled Jacobian (residual / norm versus the parameters) for the
#: magnetometer's drift terms to count as identifiable (training.selfcal.magnet uses `judge`): beyond it
#: some parameter combination is determined 1000x worse than the best one.
MAX_CONDITION = 1e3
#: Fewest distinct poses for an accelerometer fit: every rest of a single pose measures one norm along
#: one direction, which a gain, a bias along it or the local g explain alike.
MIN_POSES = 2
ONE_POSE_REASON = ("all rests are in one pose: their gravity norm is one equation along one direction, which a gain, "
                   "a bias along it or the local g explain alike; nothing fitted")
#: Prior widths of the accelerometer model (training.selfcal.regularised: a combination the rests
#: determine better than half its width is fitted from them alone, a weaker one is held near nominal).
#: Gain 10 % (MEMS datasheets: ±1-3 %; a wrong range setting is a unit error, caught at import);
#: cross-axis 0.035 (2°; datasheets ±1°); bias 1 m/s² (0.1 g; datasheets ±20-60 mg) and its drift over
#: half the temperature span 0.2 m/s² (datasheets ±0.2-1 mg/°C over 35 °C ≈ 0.03-0.2 m/s²).
PRIOR_GAIN = 0.1
PRIOR_CROSS = 0.035
PRIOR_BIAS_MS2 = 1.0
PRIOR_BIAS_DRIFT_MS2 = 0.2
#: Prior width of the rotation of the sensor in its box [Gibbs vector ≈ rad/2]: a nuisance, wide.
PRIOR_FACE_FRAME = 0.3
#: Noise floor of the gravity-norm residual (relative to g): the norm spread a good calibration leaves
#: on real data (imucal's Ferraris example: 0.031 %; the simulated protocol 0.01 %) — no rest's norm
#: is trusted beyond 2e-4, whatever its averaging.
NORM_FLOOR = 2e-4
#: Noise floor of a face direction [rad]: a box laid on a flat table sits to ~0.01° (2e-4 rad).
FACE_FLOOR = 2e-4
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
    """Result: level ('symmetric A + b', '... + b(T)' or 'nothing'), A (3, 3), b (3, P+1) m/s² in
    powers of Tn, degree P, reason (why the degree is lower than asked; why nothing), poses and (pose,
    temperature) groups used, gravity-norm RMS over the rests before/after [m/s²], the regularised fit
    (parameters ± standard errors, which the prior held) and the face set (a Ferraris-style box) used."""

    level: str
    A: np.ndarray
    b: np.ndarray
    degree: int
    reason: str
    poses: int
    groups: int
    rms_before: float
    rms_after: float
    fit: RegularisedFit | None
    faces: FaceSet | None = None


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


def _gibbs_rotation(v):
    """Rotation matrix (casadi 3x3) of the Gibbs vector v (3,): the unit quaternion [1, v] / ‖[1, v]‖
    (smooth everywhere, v = tan(angle/2) · axis; v = 0 is the identity)."""
    w, x, y, z = 1, v[0], v[1], v[2]
    n = 1 + x * x + y * y + z * z
    return ca.vertcat(ca.horzcat(w + x * x - y * y - z * z, 2 * (x * y - z), 2 * (x * z + y)),
                      ca.horzcat(2 * (x * y + z), w - x * x + y * y - z * z, 2 * (y * z - x)),
                      ca.horzcat(2 * (x * z - y), 2 * (y * z + x), w - x * x - y * y + z * z)) / n


def _prior(degree: int, faces: bool) -> tuple[np.ndarray, np.ndarray]:
    """(nominal θ0, prior width σ) of [A upper triangle, B column-major, Gibbs vector of the face frame]."""
    a0 = np.array([1.0, 0.0, 0.0, 1.0, 0.0, 1.0])
    a_sigma = np.array([PRIOR_GAIN if i == j else PRIOR_CROSS for i, j in _SYMMETRIC])
    b_sigma = np.concatenate([np.full(3, PRIOR_BIAS_MS2)] + [np.full(3, PRIOR_BIAS_DRIFT_MS2)] * degree)
    theta0 = np.concatenate([a0, np.zeros(3 * (degree + 1))] + ([np.zeros(3)] if faces else []))
    sigma = np.concatenate([a_sigma, b_sigma] + ([np.full(3, PRIOR_FACE_FRAME)] if faces else []))
    return theta0, sigma


def _residual_function(f: np.ndarray, tpow: np.ndarray, weights: np.ndarray, gravity: float, degree: int,
                       faces: FaceSet | None):
    """fun(θ) -> (r, dr/dθ) of the accelerometer fit: per window √w (‖A (f - B v)‖ - g) / g, then per
    face window √w (R(ρ) R0 ŷ - t) (3 rows), ŷ the calibrated unit specific force."""
    x, A, B, _, names = _parameters("symmetric", degree, sym=ca.SX)
    y = ca.mtimes(A, ca.DM(f.T) - ca.mtimes(B, ca.DM(tpow[:, :degree + 1].T)))
    norm = ca.sqrt(ca.sum1(y * y))
    rows = [(ca.DM(np.sqrt(weights)).T * (norm - gravity) / gravity).T]
    if faces is not None:
        rho = ca.SX.sym("rho", 3)
        x = ca.vertcat(x, rho)
        at = np.flatnonzero(faces.axis >= 0)
        rotation = ca.mtimes(_gibbs_rotation(rho), ca.DM(faces.R0))
        unit = y[:, at.tolist()] / ca.repmat(norm[at.tolist()], 3, 1)
        diff = (ca.mtimes(rotation, unit) - ca.DM(faces.targets()[at].T)) * ca.repmat(ca.DM(np.sqrt(weights[at])).T, 3, 1)
        rows.append(ca.reshape(diff, -1, 1))
        names = names + ["face frame ρx", "face frame ρy", "face frame ρz"]
    r = ca.vertcat(*rows)
    fn = ca.Function("acc", [x], [r, ca.jacobian(r, x)])

    def fun(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        value, jac = fn(theta)
        return np.asarray(value).ravel(), np.asarray(ca.densify(jac))
    return fun, names


def norm_repeatability(windows: list[RestWindow], norm: float) -> float:
    """Pooled standard deviation of the raw specific-force norm between the rests of one pose, relative
    to `norm` (0 when no pose has two rests): how well a pose repeats its norm, whatever the model."""
    deviations, dof = 0.0, 0
    for pose in {w.pose for w in windows if w.pose >= 0}:
        norms = np.array([np.linalg.norm(w.acc) for w in windows if w.pose == pose])
        if len(norms) > 1:
            deviations += float(np.sum((norms - norms.mean()) ** 2))
            dof += len(norms) - 1
    return float(np.sqrt(deviations / dof)) / norm if dof else 0.0


def _groups(windows: list[RestWindow], weights: np.ndarray, faces: FaceSet | None, gravity: float) -> list[Group]:
    """The residual groups: gravity norm (K rows), face directions (3 rows per face window, 2 dof).

    With faces, the norm's noise is not estimated from the joint residuals but set to the poses' own
    repeatability (at least the floors): the norm invariant is exact physics up to noise, while the
    face directions also carry the box's placement on the table (a table tilted or uneven by 0.1° turns
    each face differently), and a joint estimate would spread that placement error into the norms."""
    k = len(weights)
    floor = max(_noise_floor(windows, gravity), NORM_FLOOR)
    norm_sigma = max(floor, norm_repeatability(windows, gravity))
    groups = [Group("gravity norm", np.arange(k), weights, floor, norm_sigma, fixed=faces is not None)]
    if faces is not None:
        at = np.flatnonzero(faces.axis >= 0)
        dof = np.repeat(weights[at], 3).reshape(-1, 3).T.ravel() * (2.0 / 3.0)
        groups.append(Group("face directions", k + np.arange(3 * len(at)), dof, FACE_FLOOR, FACE_FLOOR))
    return groups


def _fit(f: np.ndarray, tpow: np.ndarray, weights: np.ndarray, gravity: float, degree: int,
         windows: list[RestWindow], faces: FaceSet | None) -> RegularisedFit:
    """The regularised fit of the rests' means f (K, 3) (with the faces' directions when given)."""
    fun, names = _residual_function(f, tpow, weights, gravity, degree, faces)
    theta0, sigma = _prior(degree, faces is not None)
    return regularised_fit(fun, theta0, sigma, names, _groups(windows, weights, faces, gravity))


def fit_accelerometer(windows: list[RestWindow], gravity: float, t0: float, ts: float,
                      degree: int) -> AccelFit:
    """Fit A (symmetric) and B(T) to the rests' mean specific force (acc finite) by
    regularised least squares (training.selfcal.regularised): the gravity norm at every rest and,
    when the norm leaves a parameter undetermined and six rests are the faces of a box
    (training.selfcal.faces), their directions too. The faces' geometry is an assumption (a box laid
    flat on a flat table: ~0.1-0.2° of placement error on a real session), where the norm is physics
    up to noise: it is used only where it adds what the norm cannot give (the non-orthogonality of a
    Ferraris session), never on a multi-pose session whose poses determine everything.

    gravity: local g [m/s²]; t0, ts: temperature normalisation [°C]; degree: largest B(T) degree."""
    use = [w for w in windows if np.all(np.isfinite(w.acc))]
    if not use:
        return AccelFit("nothing", np.eye(3), np.zeros((3, 1)), 0,
                        "no rest with the accelerometer recorded", 0, 0, np.nan, np.nan, None)
    if count_poses(use) < MIN_POSES:
        return AccelFit("nothing", np.eye(3), np.zeros((3, 1)), 0, ONE_POSE_REASON, count_poses(use),
                        len(use), np.nan, np.nan, None)
    f = np.array([w.acc for w in use])
    temp = np.array([w.temp for w in use])
    weights, groups = group_weights(use)
    before = float(np.sqrt(np.mean((np.linalg.norm(f, axis=1) - gravity) ** 2)))
    p, why_degree = choose_degree(temp, degree, groups - 6, per_degree=3)
    tpow = powers(temp, t0, ts, p)
    fit = _fit(f, tpow, weights, gravity, p, use, None)
    faces = find_faces(use) if fit.held.any() else None
    if faces is not None:        # the box's geometry is assumed only for what the norm leaves open
        fit = _fit(f, tpow, weights, gravity, p, use, faces)
    A, b, _ = unpack("symmetric", p, fit.theta[:6 + 3 * (p + 1)])
    after = _norm_rms(A, b, f, powers(temp, t0, ts, p), gravity)
    level = "symmetric A + b" + ("(T)" if p else "")
    return AccelFit(level, A, b, p, why_degree, count_poses(use), groups, before, after, fit,
                    faces=faces)


def _norm_rms(A: np.ndarray, b: np.ndarray, x: np.ndarray, tpow: np.ndarray, norm: float) -> float:
    """RMS of ‖A (x_k - b v_k)‖ - norm over the rows of x (K, 3)."""
    y = (x - tpow @ b.T) @ A.T
    return float(np.sqrt(np.mean((np.linalg.norm(y, axis=1) - norm) ** 2)))


def summarise(fit: AccelFit, gravity: float, t0: float, ts: float) -> dict:
    """Report entries of the accelerometer fit (numpy values; the caller makes them JSON-ready)."""
    out = {"unit": "m/s²", "fitted": fit.level, "why_not_more": fit.reason,
           "poses": fit.poses, "pose_temperature_groups": fit.groups, "degree": fit.degree,
           "bias": fit.b[:, 0], "bias_coefficients": fit.b, "t0_c": t0, "ts_c": ts,
           "gravity_ms2": gravity, "gravity_note": GRAVITY_NOTE,
           "residual": {"gravity_norm_rms_ms2": {"before": fit.rms_before, "after": fit.rms_after}}}
    out.update(gain_summary(fit.A))
    if fit.fit is None:
        out["notes"] = [f"nothing fitted: {fit.reason}"]
        return out
    n_ab = 6 + 3 * (fit.degree + 1)
    out.update(uncertainty_report(fit.fit, lambda th: _derived(th, fit.degree), n_ab))
    if fit.faces is not None:
        out["faces"] = face_report(fit.faces, fit.fit)
    notes = [f"{fit.level} from {fit.poses} poses ({fit.groups} pose/temperature groups)"
             + (" with six faces of a box (Ferraris)" if fit.faces is not None else "")
             + f"; gravity-norm RMS {fit.rms_before:.4f} -> {fit.rms_after:.4f} m/s²"]
    if out["held"]:
        notes.append("held at nominal by the prior (the rests do not determine them): " + ", ".join(out["held"]))
    if fit.reason:
        notes.append(f"not richer: {fit.reason}")
    out["notes"] = notes
    return out


def _derived(theta: np.ndarray, degree: int) -> dict[str, np.ndarray]:
    """The reported quantities of a parameter vector: scale factors, non-orthogonality [deg] and the
    bias at t0 [m/s²] (for their standard errors by linear propagation)."""
    A, b, _ = unpack("symmetric", degree, theta[:6 + 3 * (degree + 1)])
    summary = gain_summary(A)
    return {"scale_factors": np.array(summary["scale_factors"]),
            "nonorthogonality_deg": np.array(list(summary["nonorthogonality_deg"].values())),
            "bias": b[:, 0]}


def face_report(faces: FaceSet, fit: RegularisedFit) -> dict:
    """What the face set says: its poses, the bias-free departure of the raw faces from a box [deg], the
    face directions' scatter after the fit [deg], and the rotation of the sensor axes in the box [deg]."""
    rotation = _gibbs_matrix(fit.theta[-3:]) @ faces.R0
    return {"poses": {f"{'+' if s > 0 else '-'}{'xyz'[a]}": int(p) for (a, s), p in faces.poses.items()},
            "raw_departure_deg": faces.departure_deg,
            "direction_scatter_deg": float(np.degrees(fit.sigma["face directions"])),
            "direction_scatter_estimated": bool(fit.sigma_estimated["face directions"]),
            "sensor_in_box_rotation_deg": _angle_deg((np.trace(rotation) - 1) / 2)}


def _gibbs_matrix(v: np.ndarray) -> np.ndarray:
    """Numeric rotation matrix of a Gibbs vector (see _gibbs_rotation)."""
    return np.asarray(ca.DM(_gibbs_rotation(ca.DM(v))))
