"""Magnetometer hard/soft iron from the field-norm invariant, and its alignment to the
accelerometer from the dip-angle invariant.

1. Field norm: without disturbance the earth field has the same magnitude F in every pose, so
   h_c = M (h - o) must satisfy ‖h_c‖ = F for every sample of the recording: an ellipsoid fit
   (M symmetric, o the hard iron; Vasconcelos et al., "Geometric approach to strapdown
   magnetometer calibration in sensor frame", IEEE TAES 2011; training/models/ellipsoid.py). It needs
   field directions over much of the sphere; with fewer only the hard iron o (a sphere,
   M = F/r I) is identifiable, with a flat turn nothing. Samples disturbed by a local field
   (their calibrated norm off by more than OUTLIER_SIGMAS robust σ) are dropped and the fit repeated.
   When the recording spans temperatures, the runtime's full model ‖M (G(T) ⊙ (h - B(T)))‖ = F
   (hard-iron drift B(T), gain drift G(T)) is then fitted by IPOPT from the ellipsoid and kept
   when the Jacobian pins its drift terms (accel.fit_norm_model, judge).
2. Dip: gravity and the field make a fixed angle, so at every rest k with calibrated
   specific-force direction f̂_k and field direction ĥ_k, -f̂_k · (R ĥ_k) = sin(dip)
   (Kok & Schön, "Maximum likelihood calibration of a magnetometer using inertial sensors",
   IFAC 2014; Tedaldi et al. ICRA 2014 §IV-C use the same invariant). R (3 angles) rotates the
   magnetometer frame onto the accelerometer frame, which the symmetric M cannot do; the
   runtime's A is then R M (not symmetric).
"""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from training.models.ellipsoid import MAX_SAMPLES, EllipsoidFit, apply_ellipsoid, fit_ellipsoid
from training.models.thermal import ThermalModel, apply_thermal
from training.selfcal.accel import (MAX_CONDITION, ModelCheck, fit_norm_model, gain_summary, judge, pack,
                                    unpack)
from training.selfcal.poses import direction_groups
from training.selfcal.temperature import choose_degree, cluster_labels, powers

#: Equal-area cells of the coverage check: 6 bands of equal height in z (equal area on a sphere,
#: Archimedes) x 12 sectors of azimuth = 72 cells of ~30° x 30°.
COVERAGE_BANDS = 6
COVERAGE_SECTORS = 12
#: A cell counts as visited with this many samples (one noisy sample is not a direction covered).
MIN_CELL_SAMPLES = 3
#: Coverage needed for the ellipsoid (hard + soft iron) [fraction of cells]: an ellipsoid through
#: a cap or a belt leaves the gain across it free; 0.4 (29 cells) is most of a hemisphere. The
#: Jacobian check then decides.
FULL_COVERAGE = 0.4
#: Coverage needed for the hard iron alone (sphere) [fraction]: a flat turn at one tilt visits at
#: most one band, 12 cells = 1/6, and pins the offset in the plane of the turn only; 0.2 asks for
#: directions off that band. The Jacobian check then decides.
SPHERE_COVERAGE = 0.2
#: Samples whose calibrated norm is further than this many robust σ (1.4826 x MAD) from the
#: median are disturbed (a magnet, steel nearby) and dropped: for Gaussian noise 4σ drops 6e-5 of
#: the clean samples, while a disturbance of a few µT over a field of ~50 µT is caught.
OUTLIER_SIGMAS = 4.0
#: Passes of fit -> drop outliers -> refit (the second pass catches what the first, biased by
#: the disturbance, missed).
ROBUST_PASSES = 2
#: Fewest finite samples for any field fit: a tumble of a few seconds at 50 Hz.
MIN_SAMPLES = 100
#: Smallest sphere radius [µT] that can be the earth field turning: the geomagnetic field is
#: 22-67 µT everywhere (IGRF), so even with a -50 % sensor gain its vector traces a sphere of
#: more than 10 µT; a smaller "sphere" is noise around a static reading.
MIN_FIELD_UT = 10.0
#: Smallest RMS distance of the samples from their mean, relative to the sphere radius [1]: 0.25
#: is a cap of about ±20° of field directions. On a smaller cap the centre and radius of a sphere
#: trade off against each other (a nearly static log fits spheres of any size).
MIN_TURN_SPREAD = 0.25
#: Largest standard error of a field-fit parameter for the fit to be worth applying: the offset
#: (hard iron) relative to F, 5 % — hard iron on a board is typically 20-100 % of F, so an offset
#: pinned to 5 % removes most of it (the runtime's particle filter refines it online); the matrix
#: (soft iron, scale) 1 % — soft iron is only ~2-10 %, so it must be pinned tighter to help. The
#: independent data points are the visited cells (samples in one cell repeat one direction), and
#: the residual includes any nonlinearity of the sensor and non-uniformity of the local field.
MAX_OFFSET_STD = 5e-2
MAX_MATRIX_STD = 1e-2
#: Largest standard error of a temperature-drift coefficient (hard-iron drift relative to F, gain
#: drift dimensionless, per unit of Tn): 0.2 %. Drifts over a calibration's temperature range are
#: ~1 % of F (a few tenths of a µT per 10 °C), so one pinned worse than 0.2 % is not worth fitting.
MAX_DRIFT_STD = 2e-3
#: A field fit is applied only when it leaves at most this share of the raw sensor's robust norm
#: spread: hard or soft iron worth correcting (a few µT and more) makes the raw norm vary with
#: orientation far more than field non-uniformity and noise do, and its fit removes most of that
#: (simulated unit: 34 % -> 0.4 %). A fit that removes less is absorbing the place — BROAD's lab
#: field varies by 41-45 µT across the room, which a sphere fit turns into a ~1 µT "hard iron" that
#: cost 0.3-0.9° of heading on single-trial calibrations; xio_handheld's fit even raised the spread.
MIN_SPREAD_REDUCTION = 0.5
#: Largest standard error of the alignment rotation R [deg] for it to be accepted: well below the
#: ~1-2° heading accuracy of a calibrated MEMS compass, above what a dozen well-spread poses give.
MAX_ALIGN_STD_DEG = 0.5
#: The 24 proper rotations mapping axes onto axes: starting points of the alignment fit, so a
#: magnetometer mounted with swapped or flipped axes is found too (deterministic multi-start).
_CUBE = [Rotation.create_group("O")[i] for i in range(24)]


@dataclass(frozen=True)
class MagFit:
    """Field fit: level ('hard + soft iron (ellipsoid)', 'hard iron only (sphere)', 'nothing'),
    offset (3,) µT, matrix (3, 3) (symmetric M), field norm F [µT] and its source, coverage
    [fraction of cells], inlier mask over the samples passed in (N,), robust σ of the calibrated
    norm [µT], norm residual RMS over the inliers before/after [µT], relative norm spread
    std/mean over all finite samples before/after [1], the identifiability check, and why not more;
    with temperature terms: b (3, P+1) µT hard iron in powers of Tn (column 0 = offset), g (3, Q)
    gain drift, and the normalisation t0, ts [°C] (P = Q = 0: constant)."""

    level: str
    offset: np.ndarray
    matrix: np.ndarray
    field_norm: float
    field_norm_source: str
    coverage: float
    inliers: np.ndarray
    sigma: float
    rms_before: float
    rms_after: float
    spread_before: float
    spread_after: float
    check: ModelCheck | None
    reason: str
    b: np.ndarray | None = None
    g: np.ndarray | None = None
    t0: float = 25.0
    ts: float = 1.0

    def model(self, R: np.ndarray | None = None) -> ThermalModel:
        """The runtime model x_c = R M (G(T) ⊙ (x - B(T))) (R = I when None)."""
        b = self.offset[:, None] if self.b is None else self.b
        g = np.zeros((3, 0)) if self.g is None else self.g
        p = max(b.shape[1] - 1, g.shape[1])
        bb, gg = np.zeros((3, p + 1)), np.zeros((3, p))
        bb[:, :b.shape[1]], gg[:, :g.shape[1]] = b, g
        a = self.matrix if R is None else R @ self.matrix
        return ThermalModel(self.level != "nothing", self.t0, self.ts, p, a, gg, bb)


@dataclass(frozen=True)
class Alignment:
    """Dip fit: R (3, 3) magnetometer -> accelerometer frame (I when not fitted), dip [deg]
    (with R = I when R is not fitted), fitted flag, rests used, RMS of -f̂·Rĥ - sin(dip) before
    (R = I) and after [1], the check, and the reason when not fitted."""

    R: np.ndarray
    dip_deg: float
    fitted: bool
    rests: int
    rms_before: float
    rms_after: float
    check: ModelCheck | None
    reason: str


def fit_sphere(mag: np.ndarray) -> tuple[np.ndarray, float]:
    """Algebraic sphere fit of mag (N, 3) µT: ‖h‖² = 2 c·h + d, r² = d + ‖c‖² (linear least
    squares). Returns (centre (3,) µT, radius µT)."""
    design = np.column_stack([2.0 * mag, np.ones(len(mag))])
    sol, *_ = np.linalg.lstsq(design, np.sum(mag ** 2, axis=1), rcond=None)
    centre = sol[:3]
    return centre, float(np.sqrt(max(sol[3] + centre @ centre, 0.0)))


def robust_inliers(norms: np.ndarray, target: float | None = None) -> tuple[np.ndarray, float]:
    """(inlier mask (N,), robust σ) of norms (N,): within OUTLIER_SIGMAS x 1.4826 MAD of the
    median (or of `target`, when given, for the centre)."""
    centre = float(np.median(norms)) if target is None else target
    sigma = 1.4826 * float(np.median(np.abs(norms - np.median(norms))))
    return np.abs(norms - centre) <= OUTLIER_SIGMAS * max(sigma, 1e-12), sigma


def direction_cells(mag: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Index (N,) of the COVERAGE_BANDS x COVERAGE_SECTORS equal-area cell that each direction of
    mag - centre (N, 3) falls in."""
    u = mag - centre
    u = u / np.linalg.norm(u, axis=1, keepdims=True)
    band = np.clip(((u[:, 2] + 1.0) * 0.5 * COVERAGE_BANDS).astype(int), 0, COVERAGE_BANDS - 1)
    sector = np.clip(((np.arctan2(u[:, 1], u[:, 0]) + np.pi) / (2 * np.pi) * COVERAGE_SECTORS).astype(int),
                     0, COVERAGE_SECTORS - 1)
    return band * COVERAGE_SECTORS + sector


def sphere_coverage(mag: np.ndarray, centre: np.ndarray) -> float:
    """Fraction of the equal-area cells that the directions of mag - centre (N, 3) visit with at
    least MIN_CELL_SAMPLES samples."""
    counts = np.bincount(direction_cells(mag, centre), minlength=COVERAGE_BANDS * COVERAGE_SECTORS)
    return float(np.mean(counts >= MIN_CELL_SAMPLES))


def _visited_cells(coverage: float) -> float:
    """Number of visited cells: the independent directions behind a field fit."""
    return coverage * COVERAGE_BANDS * COVERAGE_SECTORS


def ellipsoid_jacobian(mag: np.ndarray, offset: np.ndarray, matrix: np.ndarray,
                       field_norm: float) -> tuple[np.ndarray, np.ndarray]:
    """(scaled residual (N,) = (‖M (h - o)‖ - F)/F, Jacobian (N, 9)) for o / F (3) and the upper
    triangle of M (6: 11 12 13 22 23 33). With d = h - o, y = M d:
    ∂‖y‖/∂o = -M y/‖y‖; ∂‖y‖/∂M_ij = (y_i d_j + y_j d_i)/‖y‖ (i ≠ j), y_i d_i/‖y‖ (i = j)."""
    d = mag - offset
    y = d @ matrix.T
    n = np.linalg.norm(y, axis=1)
    cols = [-(y @ matrix) / n[:, None]]
    for i, j in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)):
        g = y[:, i] * d[:, j] + (y[:, j] * d[:, i] if i != j else 0.0)
        cols.append((g / n / field_norm)[:, None])
    return (n - field_norm) / field_norm, np.hstack(cols)


def sphere_jacobian(mag: np.ndarray, centre: np.ndarray, scale: float,
                    field_norm: float) -> tuple[np.ndarray, np.ndarray]:
    """(scaled residual (N,) = (s‖h - c‖ - F)/F, Jacobian (N, 4)) for c / F (3) and s."""
    d = mag - centre
    n = np.linalg.norm(d, axis=1)
    jac = np.hstack([-scale * d / n[:, None], (n / field_norm)[:, None]])
    return (scale * n - field_norm) / field_norm, jac


def _check(res: np.ndarray, jac: np.ndarray, coverage: float, names: list[str], field_norm: float,
           matrix_bound: float = MAX_MATRIX_STD) -> ModelCheck:
    """Identifiability of a field fit (first 3 parameters: the offset / F, then matrix terms
    bounded by matrix_bound); the visited cells are the independent data points."""
    weights = np.full(len(res), _visited_cells(coverage) / len(res))
    bounds = np.array([MAX_OFFSET_STD] * 3 + [matrix_bound] * (jac.shape[1] - 3))
    return judge(jac, res, weights, names, 0.0, field_norm, MAX_CONDITION, bounds)


def _robust_sphere(m: np.ndarray) -> tuple[np.ndarray, float, np.ndarray]:
    """(centre, radius, inliers) of the sphere fit with ROBUST_PASSES outlier passes."""
    inliers = np.ones(len(m), dtype=bool)
    for _ in range(ROBUST_PASSES):
        centre, radius = fit_sphere(m[inliers])
        inliers, _ = robust_inliers(np.linalg.norm(m - centre, axis=1))
    centre, radius = fit_sphere(m[inliers])
    return centre, radius, inliers


def _robust_ellipsoid(m: np.ndarray, inliers: np.ndarray,
                      field_norm: float) -> tuple[EllipsoidFit, np.ndarray]:
    """Ellipsoid fit on the inliers, then ROBUST_PASSES - 1 refits after dropping the samples
    whose calibrated norm is an outlier."""
    fit = fit_ellipsoid(m[inliers], field_norm)
    for _ in range(ROBUST_PASSES - 1):
        inliers, _ = robust_inliers(np.linalg.norm(apply_ellipsoid(fit, m), axis=1))
        fit = fit_ellipsoid(m[inliers], field_norm)
    inliers, _ = robust_inliers(np.linalg.norm(apply_ellipsoid(fit, m), axis=1))
    return fit, inliers


def fit_magnetometer(mag: np.ndarray, field_norm: float | None, temp: np.ndarray | None = None,
                     t0: float = 25.0, ts: float = 1.0, degree: int = 0,
                     lengths: list[int] | None = None) -> MagFit:
    """The field fit of `_candidate_fit`, applied only when it makes the field norm more constant than
    the raw sensor does: robust spread 1.4826·MAD/median of |h| within each recording (`lengths`:
    the rows of each concatenated recording, None = one), averaged with the sample counts as weights
    (a disturbance is a minority of samples and moves neither median; recordings made at places of
    different field strength are not compared with each other). A magnetometer that is already
    calibrated inside the sensor, seen over a small part of the sphere, can be fitted by a smaller
    sphere about a shifted centre that scatters the norm more than the raw readings: that fit is
    refused (identity, said in `reason`), never applied silently."""
    fit = _candidate_fit(mag, field_norm, temp, t0, ts, degree)
    if fit.level == "nothing":
        return fit
    finite = np.all(np.isfinite(mag), axis=1)
    calibrated = apply_field(fit, mag, temp)
    raw, cal = (_spread_within(np.linalg.norm(x, axis=1), finite, lengths) for x in (mag, calibrated))
    if cal <= MIN_SPREAD_REDUCTION * raw:
        return fit
    return replace(_nothing(mag, finite, field_norm, f"the {fit.level} fit does not make the field norm clearly more "
                    f"constant than the raw sensor (robust spread {raw:.2%} -> {cal:.2%}, needs at most "
                    f"{MIN_SPREAD_REDUCTION:.0%} of it): the raw magnetometer is calibrated as far as this "
                    "recording can tell, and the fit would mostly absorb the place (a non-uniform field, a "
                    "nearby disturbance); not applied"), coverage=fit.coverage)


def _spread_within(norms: np.ndarray, finite: np.ndarray, lengths: list[int] | None) -> float:
    """Sample-weighted mean of `robust_spread` over the recordings (rows split by `lengths`)."""
    edges = np.cumsum([0] + list(lengths if lengths else [len(norms)]))
    parts = [norms[a:b][finite[a:b]] for a, b in zip(edges[:-1], edges[1:])]
    parts = [p for p in parts if p.size]
    return float(np.average([robust_spread(p) for p in parts], weights=[p.size for p in parts]))


def robust_spread(norms: np.ndarray) -> float:
    """Relative robust spread 1.4826 · MAD / median of norms (N,) [1]."""
    median = float(np.median(norms))
    return float(1.4826 * np.median(np.abs(norms - median)) / median)


def _candidate_fit(mag: np.ndarray, field_norm: float | None, temp: np.ndarray | None = None,
                   t0: float = 25.0, ts: float = 1.0, degree: int = 0) -> MagFit:
    """Hard/soft iron of mag (N, 3) µT (all samples of all recordings; NaN rows ignored), with
    temperature drift terms of degree <= `degree` when temp (N,) °C spans distinct temperatures
    (t0, ts: the runtime's normalisation).

    field_norm: the local earth-field magnitude F [µT] the calibrated field is scaled to. Pass the
    sidecar's earth_field.norm_ut, or a geomagnetic-model value (training.data.geomag) for the place
    and date of the recording, or the recording's own median raw norm; None uses the median norm
    about the hard-iron centre (sphere fit): the calibrated field is then in the sensor's own
    (uncalibrated) scale, and field_norm_source says so."""
    finite = np.all(np.isfinite(mag), axis=1)
    m = mag[finite]
    if len(m) < MIN_SAMPLES:
        return _nothing(mag, finite, field_norm, "the magnetometer is not recorded" if not len(m) else
                        f"{len(m)} finite samples < {MIN_SAMPLES}")
    centre, radius, inliers = _robust_sphere(m)
    spread = float(np.sqrt(np.mean(np.sum((m[inliers] - m[inliers].mean(axis=0)) ** 2, axis=1))))
    if radius < MIN_FIELD_UT or spread < MIN_TURN_SPREAD * radius:
        return _nothing(mag, finite, field_norm,
                        f"the field hardly turns: samples spread {spread:.2f} µT RMS about their mean, "
                        f"sphere radius {radius:.2f} µT (need radius >= {MIN_FIELD_UT} µT and spread >= "
                        f"{MIN_TURN_SPREAD} x radius)")
    if field_norm is None:
        field_norm = float(np.median(np.linalg.norm(m[inliers] - centre, axis=1)))
        source = "median raw norm about the hard-iron centre (sphere fit) of the recordings"
    else:
        source = "passed by the caller"
    coverage = sphere_coverage(m[inliers], centre)
    reasons = []
    if coverage >= FULL_COVERAGE:
        fit, ell_in = _robust_ellipsoid(m, inliers, field_norm)
        res, jac = ellipsoid_jacobian(m[ell_in], fit.offset, fit.matrix, field_norm)
        check = _check(res, jac, coverage, ["o_x", "o_y", "o_z", "M11", "M12", "M13", "M22", "M23",
                                            "M33"], field_norm)
        if check.accepted:
            base = _result("hard + soft iron (ellipsoid)", fit.offset, fit.matrix, field_norm, source,
                           coverage, mag, finite, ell_in, check, "")
            if temp is None or degree == 0:
                return base
            return _with_temperature(base, m, temp[finite], t0, ts, degree, mag, finite)
        reasons.append(f"ellipsoid: {check.reason}")
    else:
        reasons.append(f"ellipsoid: field directions cover {coverage:.0%} of the sphere "
                       f"< {FULL_COVERAGE:.0%}")
    if coverage >= SPHERE_COVERAGE:
        scale = field_norm / radius
        res, jac = sphere_jacobian(m[inliers], centre, scale, field_norm)
        # the sphere's scale F / r only sets the norm, not the field direction, and is F's echo
        # when F comes from the data: a nuisance parameter, the offset decides
        check = _check(res, jac, coverage, ["c_x", "c_y", "c_z", "scale"], field_norm, np.inf)
        if check.accepted:
            return _result("hard iron only (sphere)", centre, scale * np.eye(3), field_norm, source,
                           coverage, mag, finite, inliers, check, "; ".join(reasons))
        reasons.append(f"sphere: {check.reason}")
    else:
        reasons.append(f"sphere: field directions cover {coverage:.0%} of the sphere "
                       f"< {SPHERE_COVERAGE:.0%}")
    out = _nothing(mag, finite, field_norm, "; ".join(reasons))
    return MagFit(out.level, out.offset, out.matrix, field_norm, source, coverage, out.inliers, out.sigma,
                  out.rms_before, out.rms_after, out.spread_before, out.spread_after, None, out.reason)


def _with_temperature(base: MagFit, m: np.ndarray, temp: np.ndarray, t0: float, ts: float, degree: int,
                      mag: np.ndarray, finite: np.ndarray) -> MagFit:
    """The ellipsoid `base` refined with hard-iron drift B(T) and gain drift G(T) of the largest
    identifiable degree <= `degree` (from the inliers m (N, 3) µT at temp (N,) °C), or `base`
    with the reason why not. Independent data points: visited (cell, temperature cluster) pairs."""
    inl = base.inliers[finite]
    rows = np.flatnonzero(inl)
    rows = rows[np.linspace(0, len(rows) - 1, min(len(rows), MAX_SAMPLES)).astype(int)]
    x, t = m[rows], temp[rows]
    keys = list(zip(direction_cells(x, base.offset), cluster_labels(t)))
    counts = Counter(keys)
    weights = np.array([1.0 / counts[k] for k in keys])
    p, why = choose_degree(t, degree, len(counts) - 3, per_degree=6)  # 9 + 6p parameters
    reasons = [f"temperature drift: {why.replace('bias', 'hard iron')}"] if why else []
    for q in range(p, 0, -1):
        sol, res, jac, names = fit_norm_model(x, powers(t, t0, ts, q), weights, base.field_norm, "symmetric",
                                              q, q, pack(base.matrix, np.column_stack([base.offset,
                                                                                       np.zeros((3, q))]),
                                                         np.zeros((3, q))))
        bounds = np.array([MAX_MATRIX_STD] * 6 + [MAX_OFFSET_STD] * 3 + [MAX_DRIFT_STD] * 6 * q)
        check = judge(jac, res, weights, names, 0.0, base.field_norm, MAX_CONDITION, bounds)
        if check.accepted:
            matrix, b, g = unpack("symmetric", q, sol, q)
            fit = replace(base, offset=b[:, 0], matrix=matrix, b=b, g=g, t0=t0, ts=ts)
            cal = np.linalg.norm(apply_field(fit, m, temp), axis=1)
            inliers, _ = robust_inliers(cal)
            out = _result(f"{base.level} + temperature drift B(T), G(T) of degree {q}", b[:, 0], matrix,
                          base.field_norm, base.field_norm_source, base.coverage, mag, finite, inliers, check,
                          "; ".join(reasons), cal)
            return replace(out, b=b, g=g, t0=t0, ts=ts)
        reasons.append(f"temperature drift of degree {q}: {check.reason}")
    return replace(base, reason="; ".join(reasons) or "no temperature recorded: no drift terms", t0=t0, ts=ts)


def _spread(norms: np.ndarray) -> float:
    """Relative spread std/mean of norms (N,) [1]."""
    return float(np.std(norms) / np.mean(norms))


def _result(level, offset, matrix, field_norm, source, coverage, mag, finite, inliers_m, check,
            reason, cal: np.ndarray | None = None) -> MagFit:
    """MagFit with residuals; inliers_m is over the finite rows, returned over all rows; cal: the
    calibrated norms of the finite rows (default: of the constant model offset, matrix)."""
    m = mag[finite]
    raw = np.linalg.norm(m, axis=1)
    cal = np.linalg.norm((m - offset) @ matrix.T, axis=1) if cal is None else cal
    inliers = np.zeros(len(mag), dtype=bool)
    inliers[np.flatnonzero(finite)[inliers_m]] = True
    _, sigma = robust_inliers(cal[inliers_m])
    return MagFit(level, np.asarray(offset, dtype=float), np.asarray(matrix, dtype=float),
                  float(field_norm), source, coverage, inliers, sigma,
                  float(np.sqrt(np.mean((raw[inliers_m] - field_norm) ** 2))),
                  float(np.sqrt(np.mean((cal[inliers_m] - field_norm) ** 2))),
                  _spread(raw), _spread(cal), check, reason)


def _nothing(mag: np.ndarray, finite: np.ndarray, field_norm: float | None, reason: str) -> MagFit:
    """MagFit of the identity (nothing identifiable)."""
    m = mag[finite]
    raw = np.linalg.norm(m, axis=1)
    f = float(field_norm) if field_norm is not None else (float(np.median(raw)) if raw.size else np.nan)
    rms = float(np.sqrt(np.mean((raw - f) ** 2))) if raw.size else np.nan
    spread = _spread(raw) if raw.size else np.nan
    sigma = float(1.4826 * np.median(np.abs(raw - np.median(raw)))) if raw.size else np.nan
    source = "passed by the caller" if field_norm is not None else "median raw norm"
    return MagFit("nothing", np.zeros(3), np.eye(3), f, source, 0.0, finite.copy(), sigma, rms, rms,
                  spread, spread, None, reason)


def apply_field(fit: MagFit, mag: np.ndarray, temp: np.ndarray | None = None) -> np.ndarray:
    """h_c = M (G(T) ⊙ (h - B(T))) for mag (N, 3) µT at temp (N,) °C (None: constant terms only)
    -> (N, 3) µT, before the alignment R."""
    mag = np.asarray(mag, dtype=np.float64)
    if fit.b is None and fit.g is None:
        return (mag - fit.offset) @ fit.matrix.T
    model = fit.model()
    return apply_thermal(replace(model, enabled=True), mag,
                         np.full(len(mag), np.nan) if temp is None else np.asarray(temp, dtype=np.float64))


def _dip_residual(params: np.ndarray, f: np.ndarray, h: np.ndarray, sw: np.ndarray) -> np.ndarray:
    """√w (-f̂·(R ĥ) - sin dip), params = [rotation vector (3) rad, dip rad]."""
    r = Rotation.from_rotvec(params[:3]).as_matrix()
    return sw * (-np.sum(f * (h @ r.T), axis=1) - np.sin(params[3]))


def alignment_jacobian(R: np.ndarray, dip: float, f: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Jacobian (K, 4) of -f̂·(exp([δ]x) R ĥ) - sin dip at δ = 0: -(R ĥ x f̂) for δ, -cos dip."""
    v = h @ R.T
    return np.hstack([-np.cross(v, f), np.full((len(f), 1), -np.cos(dip))])


def fit_alignment(f_hat: np.ndarray, h_hat: np.ndarray) -> Alignment:
    """Rotation R and dip from unit specific-force f_hat (K, 3) and field h_hat (K, 3) directions
    at the undisturbed rests (both calibrated). Rests repeating one (gravity, field) direction
    pair count once. Deterministic multi-start from the 24 axis-to-axis rotations."""
    keys = list(zip(direction_groups(f_hat), direction_groups(h_hat)))
    counts = Counter(keys)
    weights = np.array([1.0 / counts[k] for k in keys])
    rms_identity = _rms_dip(np.eye(3), f_hat, h_hat, weights)
    dip_identity = float(np.degrees(np.arcsin(np.clip(np.average(-np.sum(f_hat * h_hat, axis=1),
                                                                 weights=weights), -1, 1))))
    if len(counts) < 5:
        return Alignment(np.eye(3), dip_identity, False, len(f_hat), rms_identity, rms_identity, None,
                         f"{len(counts)} distinct (gravity, field) direction pairs at the rests; "
                         f"R (3 angles) and dip need at least 5: R = I, dip with R = I")
    sw = np.sqrt(weights)
    best = None
    for start in _CUBE:
        dip0 = np.arcsin(np.clip(np.average(-np.sum(f_hat * (h_hat @ start.as_matrix().T), axis=1),
                                            weights=weights), -1, 1))
        sol = least_squares(_dip_residual, np.concatenate([start.as_rotvec(), [dip0]]),
                            args=(f_hat, h_hat, sw), method="lm", xtol=1e-14, ftol=1e-14)
        if best is None or sol.cost < best.cost - 1e-15:
            best = sol
    R = Rotation.from_rotvec(best.x[:3]).as_matrix()
    dip = float(best.x[3])
    if dip > np.pi / 2 or dip < -np.pi / 2:  # sin is even about ±90°: report the principal value
        dip = float(np.arcsin(np.sin(dip)))
    res = -np.sum(f_hat * (h_hat @ R.T), axis=1) - np.sin(dip)
    check = judge(alignment_jacobian(R, dip, f_hat, h_hat), res, weights,
                  ["R_x", "R_y", "R_z", "dip"], 0.0, 1.0, MAX_CONDITION, np.inf)
    rot_std = _rotation_std_deg(check, alignment_jacobian(R, dip, f_hat, h_hat), res, weights)
    rms_after = _rms_dip(R, f_hat, h_hat, weights, dip)
    if not check.accepted or rot_std > MAX_ALIGN_STD_DEG:
        why = check.reason or f"rotation standard error {rot_std:.2f}° > {MAX_ALIGN_STD_DEG}°"
        return Alignment(np.eye(3), dip_identity, False, len(f_hat), rms_identity, rms_identity,
                         check, f"alignment not identifiable ({why}): R = I, dip with R = I")
    return Alignment(R, float(np.degrees(dip)), True, len(f_hat), rms_identity, rms_after, check, "")


def _rotation_std_deg(check: ModelCheck, jac: np.ndarray, res: np.ndarray,
                      weights: np.ndarray) -> float:
    """Largest standard error of the three rotation angles [deg] (inf when not computable)."""
    dof = weights.sum() - jac.shape[1]
    if not np.isfinite(check.condition) or dof < 1:
        return np.inf
    jw = jac * np.sqrt(weights)[:, None]
    sigma2 = np.sum(weights * res ** 2) / dof
    return float(np.degrees(np.sqrt(np.max(np.diag(np.linalg.inv(jw.T @ jw))[:3] * sigma2))))


def _rms_dip(R: np.ndarray, f: np.ndarray, h: np.ndarray, weights: np.ndarray,
             dip: float | None = None) -> float:
    """Weighted RMS of -f̂·(R ĥ) - sin dip [1]; dip None -> the weighted mean of -f̂·(R ĥ)."""
    c = -np.sum(f * (h @ R.T), axis=1)
    s = np.average(c, weights=weights) if dip is None else np.sin(dip)
    return float(np.sqrt(np.average((c - s) ** 2, weights=weights)))


def summarise(fit: MagFit, alignment: Alignment | None) -> dict:
    """Report entries of the magnetometer fit and alignment (numpy values allowed)."""
    R = alignment.R if alignment is not None else np.eye(3)
    aligned = alignment is not None and alignment.fitted
    why = [r for r in (fit.reason, alignment.reason if alignment else "no undisturbed rest: no alignment")
           if r] if fit.level != "nothing" else [fit.reason]
    out = {"unit": "µT", "fitted": fit.level + (" + alignment R to the accelerometer" if aligned else ""),
           "why_not_more": "; ".join(why), "field_norm_ut": fit.field_norm,
           "field_norm_source": fit.field_norm_source, "coverage": fit.coverage,
           "inlier_fraction": float(np.mean(fit.inliers)) if fit.inliers.size else None,
           "disturbance_sigma_ut": fit.sigma, "hard_iron_ut": fit.offset, "soft_iron": fit.matrix,
           "bias": fit.offset, "bias_coefficients": fit.model().b, "gain_coefficients": fit.model().g,
           "degree": fit.model().degree, "t0_c": fit.t0, "ts_c": fit.ts,
           "dip_deg": alignment.dip_deg if alignment is not None else None, "alignment_fitted": aligned,
           "alignment_angle_deg": float(np.degrees(Rotation.from_matrix(R).magnitude())), "alignment_R": R,
           "residual": {"field_norm_rms_ut": {"before": fit.rms_before, "after": fit.rms_after},
                        "field_norm_spread": {"before": fit.spread_before, "after": fit.spread_after}}}
    out.update(gain_summary(R @ fit.matrix) if fit.level != "nothing" else gain_summary(np.eye(3)))
    notes = [f"{fit.level}: field-norm RMS {fit.rms_before:.2f} -> {fit.rms_after:.2f} µT over the "
             f"undisturbed samples, directions cover {fit.coverage:.0%} of the sphere; F = "
             f"{fit.field_norm:.2f} µT ({fit.field_norm_source})"] if np.isfinite(fit.rms_before) else []
    if alignment is not None:
        out["alignment_rests"] = alignment.rests
        out["residual"]["dip_invariant_rms"] = {"before": alignment.rms_before, "after": alignment.rms_after}
        what = f"R fitted ({out['alignment_angle_deg']:.2f}°)" if aligned else alignment.reason
        notes.append(f"alignment to the accelerometer: {what}; dip {alignment.dip_deg:.2f}°")
    if out["why_not_more"]:
        notes.append(f"not richer: {out['why_not_more']}")
    out["notes"] = notes
    return out
