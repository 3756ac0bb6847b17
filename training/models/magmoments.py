"""Power sums of field samples and the hard-iron likelihood with the soft iron integrated out.

Twin of sources/ImuMagMoments.c (same operations in the same order, scalar Python), used by the
numpy twin of the Rao-Blackwellised particle filter (training.models.magpf_rb) and by tests. With
d = h_m − h_p and I + M = (I + B)ᵀ(I + B), a calibrated sample satisfies
φ(d)ᵀm = |h_0|² + 3σ² − |d|² + noise, linear in m = [M11 M12 M13 M22 M23 M33],
φ(d) = [d1², 2d1d2, 2d1d3, d2², 2d2d3, d3²]; all sums it needs are polynomials of degree ≤ 4 in d,
so the 35 power sums of u = h_m − reference are sufficient statistics for any h_p.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

MOMENT_COUNT = 35
MAX_DEGREE = 4
SQRT_ITERATIONS = 12
PHI_EXPONENT = ((2, 0, 0), (1, 1, 0), (1, 0, 1), (0, 2, 0), (0, 1, 1), (0, 0, 2))
PHI_FACTOR = (1.0, 2.0, 2.0, 1.0, 2.0, 1.0)
SQUARE_ENTRY = (0, 3, 5)
SOFT_ROW = (0, 0, 0, 1, 1, 2)
SOFT_COLUMN = (0, 1, 2, 1, 2, 2)


@dataclass
class MarginalPrior:
    """Priors of one evaluation (ImuMagMarginalPrior): hard_centre [µT, relative to the moment
    reference], hard_spread [µT], soft_mean (6,) and soft_spread of m, offset |h_0|² + 3σ² [µT²],
    variance 4|h_0|²σ² + 6σ⁴ [µT⁴], admissible eigenvalue range (min_eigen, max_eigen) of I + M."""

    hard_centre: np.ndarray
    hard_spread: float
    soft_mean: np.ndarray
    soft_spread: float
    offset: float
    variance: float
    min_eigen: float
    max_eigen: float


def moment_index(a: int, b: int, c: int) -> int:
    """Index of the monomial u1^a u2^b u3^c (a + b + c ≤ 4)."""
    s = a + b + c
    return s * (s + 1) * (s + 2) // 6 + (s - a) * (s - a + 1) // 2 + (s - a - b)


def _powers(v) -> list[list[float]]:
    out = []
    for i in range(3):
        row = [1.0]
        for _ in range(MAX_DEGREE):
            row.append(row[-1] * float(v[i]))
        out.append(row)
    return out


def _exponents():
    for a in range(MAX_DEGREE + 1):
        for b in range(MAX_DEGREE + 1 - a):
            for c in range(MAX_DEGREE + 1 - a - b):
                yield a, b, c


def moments_add(sums: list[float], u) -> None:
    """sums += all monomials of the sample u (3,) [µT^k], in place."""
    p = _powers(u)
    for a, b, c in _exponents():
        sums[moment_index(a, b, c)] += p[0][a] * p[1][b] * p[2][c]


def power_sums(samples) -> list[float]:
    """The 35 power sums of samples (N, 3)."""
    sums = [0.0] * MOMENT_COUNT
    for u in np.asarray(samples, dtype=np.float64):
        moments_add(sums, u)
    return sums


def _shift_axis(t: list[float], axis: int, q: float) -> None:
    """One axis of the shift, in place (ImuMagShiftAxis): per chain of monomials (the other two
    exponents fixed), repeated synthetic steps v[a] += q·v[a − 1] (Taylor shift)."""
    first, second = (1, 2) if axis == 0 else ((0, 2) if axis == 1 else (0, 1))
    for i in range(MAX_DEGREE + 1):
        for j in range(MAX_DEGREE + 1 - i):
            length = MAX_DEGREE + 1 - i - j
            index = []
            for a in range(length):
                e = [0, 0, 0]
                e[first], e[second], e[axis] = i, j, a
                index.append(moment_index(*e))
            for step in range(1, length):
                for a in range(length - 1, step - 1, -1):
                    t[index[a]] += q * t[index[a - 1]]


def moments_shift(sums, p) -> list[float]:
    """Sums of the monomials of (u − p) from the power sums of u (binomial expansion, one axis at a
    time as in the C code)."""
    t = [float(v) for v in sums]
    for axis in range(3):
        _shift_axis(t, axis, -float(p[axis]))
    return t


def _phi_moment(t, i: int, j: int | None = None) -> float:
    e = PHI_EXPONENT[i]
    if j is None:
        return t[moment_index(*e)]
    f = PHI_EXPONENT[j]
    return t[moment_index(e[0] + f[0], e[1] + f[1], e[2] + f[2])]


def _normal_equations(t, prior: MarginalPrior):
    precision = 1.0 / (prior.soft_spread * prior.soft_spread)
    inverse_variance = 1.0 / prior.variance
    info = [[0.0] * 6 for _ in range(6)]
    eta = [0.0] * 6
    for i in range(6):
        sum_squares = 0.0
        for j in range(i + 1):   # the lower triangle: all the Cholesky factorisation reads
            info[i][j] = PHI_FACTOR[i] * PHI_FACTOR[j] * _phi_moment(t, i, j) * inverse_variance
        info[i][i] += precision
        for j in range(3):
            sum_squares += _phi_moment(t, i, SQUARE_ENTRY[j])
        eta[i] = (PHI_FACTOR[i] * (prior.offset * _phi_moment(t, i) - sum_squares) * inverse_variance
                  + float(prior.soft_mean[i]) * precision)
    squares = fourth = 0.0
    for i in range(3):
        squares += _phi_moment(t, SQUARE_ENTRY[i])
        for j in range(3):
            fourth += _phi_moment(t, SQUARE_ENTRY[i], SQUARE_ENTRY[j])
    residual = (prior.offset * prior.offset * t[0] - 2.0 * prior.offset * squares + fourth) * inverse_variance
    return info, eta, residual


def _cholesky(a, inverse) -> bool:
    for j in range(6):
        d = a[j][j]
        for k in range(j):
            d -= a[j][k] * a[j][k]
        if not d > 0.0:
            return False
        a[j][j] = math.sqrt(d)
        inverse[j] = 1.0 / a[j][j]
        for i in range(j + 1, 6):
            s = a[i][j]
            for k in range(j):
                s -= a[i][k] * a[j][k]
            a[i][j] = s * inverse[j]
    return True


def _positive_definite(s) -> bool:
    minor2 = s[0][0] * s[1][1] - s[0][1] * s[1][0]
    det = (s[0][0] * (s[1][1] * s[2][2] - s[1][2] * s[2][1])
           - s[0][1] * (s[1][0] * s[2][2] - s[1][2] * s[2][0])
           + s[0][2] * (s[1][0] * s[2][1] - s[1][1] * s[2][0]))
    return s[0][0] > 0.0 and minor2 > 0.0 and det > 0.0


def admissible(m, low: float, high: float) -> bool:
    """True if every eigenvalue of I + M lies in (low, high)."""
    above = [[0.0] * 3 for _ in range(3)]
    below = [[0.0] * 3 for _ in range(3)]
    for k in range(6):
        i, j = SOFT_ROW[k], SOFT_COLUMN[k]
        above[i][j] = above[j][i] = float(m[k])
        below[i][j] = below[j][i] = -float(m[k])
    for i in range(3):
        above[i][i] += 1.0 - low
        below[i][i] += high - 1.0
    return _positive_definite(above) and _positive_definite(below)


def marginal(sums, p, prior: MarginalPrior) -> tuple[float, np.ndarray, bool]:
    """(log target, posterior mean of m (6,), admissible) of the hard iron p [µT, relative to the
    moment reference]; the log target is −inf when not admissible."""
    t = moments_shift(sums, p)
    l, y, residual = _normal_equations(t, prior)
    soft = np.zeros(6)
    inverse = [0.0] * 6
    if not _cholesky(l, inverse):
        return -math.inf, soft, False
    fit = prior_fit = 0.0
    determinant = 1.0
    for i in range(6):
        for k in range(i):
            y[i] -= l[i][k] * y[k]
        y[i] *= inverse[i]
        fit += y[i] * y[i]
        determinant *= l[i][i]
        prior_fit += float(prior.soft_mean[i]) * float(prior.soft_mean[i])
    for i in range(5, -1, -1):
        v = y[i]
        for k in range(i + 1, 6):
            v -= l[k][i] * soft[k]
        soft[i] = v * inverse[i]
    if not admissible(soft, prior.min_eigen, prior.max_eigen):
        return -math.inf, soft, False
    hard = 0.0
    for i in range(3):
        d = (float(p[i]) - float(prior.hard_centre[i])) / prior.hard_spread
        hard += d * d
    prior_fit /= prior.soft_spread * prior.soft_spread
    return -0.5 * (residual - fit + prior_fit) - math.log(determinant) - 0.5 * hard, soft, True


def _inverse3(a):
    c00 = a[1][1] * a[2][2] - a[1][2] * a[2][1]
    c01 = a[1][2] * a[2][0] - a[1][0] * a[2][2]
    c02 = a[1][0] * a[2][1] - a[1][1] * a[2][0]
    det = a[0][0] * c00 + a[0][1] * c01 + a[0][2] * c02
    inv = [[0.0] * 3 for _ in range(3)]
    inv[0][0], inv[1][0], inv[2][0] = c00 / det, c01 / det, c02 / det
    inv[0][1] = (a[0][2] * a[2][1] - a[0][1] * a[2][2]) / det
    inv[1][1] = (a[0][0] * a[2][2] - a[0][2] * a[2][0]) / det
    inv[2][1] = (a[0][1] * a[2][0] - a[0][0] * a[2][1]) / det
    inv[0][2] = (a[0][1] * a[1][2] - a[0][2] * a[1][1]) / det
    inv[1][2] = (a[0][2] * a[1][0] - a[0][0] * a[1][2]) / det
    inv[2][2] = (a[0][0] * a[1][1] - a[0][1] * a[1][0]) / det
    return inv


def soft_from_quadratic(m) -> np.ndarray:
    """Symmetric B = sqrt(I + M) − I as b11 b12 b13 b22 b23 b33 (Newton iteration from I)."""
    a = [[0.0] * 3 for _ in range(3)]
    for k in range(6):
        a[SOFT_ROW[k]][SOFT_COLUMN[k]] = a[SOFT_COLUMN[k]][SOFT_ROW[k]] = float(m[k])
    for i in range(3):
        a[i][i] += 1.0
    x = [[1.0 if i == j else 0.0 for j in range(3)] for i in range(3)]
    for _ in range(SQRT_ITERATIONS):
        inv = _inverse3(x)
        nxt = [[0.5 * (x[i][j] + inv[i][0] * a[0][j] + inv[i][1] * a[1][j] + inv[i][2] * a[2][j])
                for j in range(3)] for i in range(3)]
        x = [[0.5 * (nxt[i][j] + nxt[j][i]) for j in range(3)] for i in range(3)]
    return np.array([x[SOFT_ROW[k]][SOFT_COLUMN[k]] - (1.0 if SOFT_ROW[k] == SOFT_COLUMN[k] else 0.0)
                     for k in range(6)])


def quadratic_from_soft(b) -> np.ndarray:
    """m of M = (I + B)² − I for a symmetric B given as b11 b12 b13 b22 b23 b33."""
    s = [[0.0] * 3 for _ in range(3)]
    for k in range(6):
        s[SOFT_ROW[k]][SOFT_COLUMN[k]] = s[SOFT_COLUMN[k]][SOFT_ROW[k]] = float(b[k])
    return np.array([2.0 * s[i][j] + s[i][0] * s[0][j] + s[i][1] * s[1][j] + s[i][2] * s[2][j]
                     for i, j in zip(SOFT_ROW, SOFT_COLUMN)])
