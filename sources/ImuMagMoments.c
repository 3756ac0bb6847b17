/**
 * @file ImuMagMoments.c
 * @brief Power sums of field samples and the hard-iron likelihood with the soft iron integrated
 *        out (formulas: ImuMagMoments.h, docs/magpf.md).
 */
#include <math.h>
#include <string.h>
#include "ImuMagMoments.h"

#define IMU_MAG_MAX_DEGREE 4
#define IMU_MAG_SQRT_ITERATIONS 12 /* Newton steps of sqrt(I + M); quadratic convergence from I */

/** Exponents and factors of phi(d) = [d1^2, 2 d1 d2, 2 d1 d3, d2^2, 2 d2 d3, d3^2]. */
static const int ImuMagPhiExponent[IMU_MAG_SOFT_COUNT][3] = {{2, 0, 0}, {1, 1, 0}, {1, 0, 1},
                                                            {0, 2, 0}, {0, 1, 1}, {0, 0, 2}};
static const double ImuMagPhiFactor[IMU_MAG_SOFT_COUNT] = {1.0, 2.0, 2.0, 1.0, 2.0, 1.0};
/** Entries of phi that are squares (d1^2, d2^2, d3^2): |d|^2 = sum of these. */
static const int ImuMagSquareEntry[3] = {0, 3, 5};
/** Row and column of the entries m11 m12 m13 m22 m23 m33 in the symmetric 3x3 matrix. */
static const int ImuMagSoftRow[IMU_MAG_SOFT_COUNT] = {0, 0, 0, 1, 1, 2};
static const int ImuMagSoftColumn[IMU_MAG_SOFT_COUNT] = {0, 1, 2, 1, 2, 2};

/** ImuMagIndex[a][b][c]: position of u1^a u2^b u3^c in the power sums (s = a + b + c <= 4:
 *  s(s+1)(s+2)/6 + (s-a)(s-a+1)/2 + (s-a-b); -1 above degree 4). */
static const signed char ImuMagIndex[5][5][5] = {
    {{0, 3, 9, 19, 34}, {2, 8, 18, 33, -1}, {7, 17, 32, -1, -1}, {16, 31, -1, -1, -1}, {30, -1, -1, -1, -1}},
    {{1, 6, 15, 29, -1}, {5, 14, 28, -1, -1}, {13, 27, -1, -1, -1}, {26, -1, -1, -1, -1}, {-1, -1, -1, -1, -1}},
    {{4, 12, 25, -1, -1}, {11, 24, -1, -1, -1}, {23, -1, -1, -1, -1}, {-1, -1, -1, -1, -1}, {-1, -1, -1, -1, -1}},
    {{10, 22, -1, -1, -1}, {21, -1, -1, -1, -1}, {-1, -1, -1, -1, -1}, {-1, -1, -1, -1, -1}, {-1, -1, -1, -1, -1}},
    {{20, -1, -1, -1, -1}, {-1, -1, -1, -1, -1}, {-1, -1, -1, -1, -1}, {-1, -1, -1, -1, -1}, {-1, -1, -1, -1, -1}}};

/** @brief powers[i][k] = v[i]^k for k = 0..4. */
static void ImuMagPowers(const double v[3], double powers[3][IMU_MAG_MAX_DEGREE + 1])
{
    int i, k;
    for (i = 0; i < 3; i++) {
        powers[i][0] = 1.0;
        for (k = 1; k <= IMU_MAG_MAX_DEGREE; k++) {
            powers[i][k] = powers[i][k - 1] * v[i];
        }
    }
}

void ImuMagMomentsAdd(double sums[IMU_MAG_MOMENT_COUNT], const double u[3])
{
    double powers[3][IMU_MAG_MAX_DEGREE + 1];
    int a, b, c;
    ImuMagPowers(u, powers);
    for (a = 0; a <= IMU_MAG_MAX_DEGREE; a++) {
        for (b = 0; a + b <= IMU_MAG_MAX_DEGREE; b++) {
            for (c = 0; a + b + c <= IMU_MAG_MAX_DEGREE; c++) {
                sums[ImuMagIndex[a][b][c]] += powers[0][a] * powers[1][b] * powers[2][c];
            }
        }
    }
}

/** ImuMagShiftChain[axis]: the power-sum positions of the chains of ImuMagShiftAxis one after the
 *  other — for each pair of the other two exponents (i, j) in order, ImuMagIndex with e_axis = 0, 1, ...
 *  up to degree 4 — and ImuMagShiftChainLength their lengths (the same for every axis). A table, not
 *  computed per call: the shift runs for every particle at every update (tests/test_mag_moments.py
 *  rebuilds it from ImuMagIndex). */
static const signed char ImuMagShiftChain[3][IMU_MAG_MOMENT_COUNT] = {
    {0, 1, 4, 10, 20, 3, 6, 12, 22, 9, 15, 25, 19, 29, 34, 2, 5, 11, 21, 8, 14, 24, 18, 28, 33, 7, 13, 23, 17, 27, 32,
     16, 26, 31, 30},
    {0, 2, 7, 16, 30, 3, 8, 17, 31, 9, 18, 32, 19, 33, 34, 1, 5, 13, 26, 6, 14, 27, 15, 28, 29, 4, 11, 23, 12, 24, 25,
     10, 21, 22, 20},
    {0, 3, 9, 19, 34, 2, 8, 18, 33, 7, 17, 32, 16, 31, 30, 1, 6, 15, 29, 5, 14, 28, 13, 27, 26, 4, 12, 25, 11, 24, 23,
     10, 22, 21, 20}};
static const int ImuMagShiftChainLength[] = {5, 4, 3, 2, 1, 4, 3, 2, 1, 3, 2, 1, 2, 1, 1};

/** @brief One axis of the shift, in place: t[e] <- sum_k C(e_axis, k) q^(e_axis - k) t[e with e_axis = k],
 *         one chain of monomials at a time (the other two exponents fixed, e_axis = 0, 1, ...) by
 *         repeated synthetic steps v[a] += q v[a - 1] (Taylor shift: L(L-1)/2 multiply-adds for a
 *         chain of length L, 35 per axis). */
static void ImuMagShiftAxis(double t[IMU_MAG_MOMENT_COUNT], int axis, double q)
{
    const signed char *index = ImuMagShiftChain[axis];
    int chain, a, step;
    for (chain = 0; chain < (int)(sizeof ImuMagShiftChainLength / sizeof ImuMagShiftChainLength[0]); chain++) {
        const int length = ImuMagShiftChainLength[chain];
        for (step = 1; step < length; step++) {
            for (a = length - 1; a >= step; a--) {
                t[index[a]] += q * t[index[a - 1]];
            }
        }
        index += length;
    }
}

void ImuMagMomentsShift(const double sums[IMU_MAG_MOMENT_COUNT], const double p[3],
                        double shifted[IMU_MAG_MOMENT_COUNT])
{
    int axis;
    memcpy(shifted, sums, IMU_MAG_MOMENT_COUNT * sizeof(double));
    for (axis = 0; axis < 3; axis++) { /* (u - p)^e expanded one axis at a time */
        ImuMagShiftAxis(shifted, axis, -p[axis]);
    }
}

/** @brief Shifted sum of the product of phi entries i and j (degree 4) or of entry i alone (j < 0). */
static double ImuMagPhiMoment(const double t[IMU_MAG_MOMENT_COUNT], int i, int j)
{
    const int *e = ImuMagPhiExponent[i];
    if (j < 0) {
        return t[ImuMagIndex[e[0]][e[1]][e[2]]];
    }
    return t[ImuMagIndex[e[0] + ImuMagPhiExponent[j][0]][e[1] + ImuMagPhiExponent[j][1]]
                       [e[2] + ImuMagPhiExponent[j][2]]];
}

/** @brief Information matrix J = sum phi phi^T / var + I / s^2 (lower triangle) and vector eta = sum phi z / var + m0 / s^2
 *         with z = offset - |d|^2; returns sum z^2 / var. */
static double ImuMagNormalEquations(const double t[IMU_MAG_MOMENT_COUNT], const ImuMagMarginalPrior *prior,
                                    double information[IMU_MAG_SOFT_COUNT][IMU_MAG_SOFT_COUNT],
                                    double eta[IMU_MAG_SOFT_COUNT])
{
    const double precision = 1.0 / (prior->softSpread * prior->softSpread), inverseVariance = 1.0 / prior->variance;
    double squares = 0.0, fourth = 0.0;
    int i, j;
    for (i = 0; i < IMU_MAG_SOFT_COUNT; i++) {
        double sumSquares = 0.0;
        for (j = 0; j <= i; j++) { /* the lower triangle: all the Cholesky factorisation reads */
            information[i][j] = ImuMagPhiFactor[i] * ImuMagPhiFactor[j] * ImuMagPhiMoment(t, i, j) * inverseVariance;
        }
        information[i][i] += precision;
        for (j = 0; j < 3; j++) {
            sumSquares += ImuMagPhiMoment(t, i, ImuMagSquareEntry[j]);
        }
        eta[i] = ImuMagPhiFactor[i] * (prior->offset * ImuMagPhiMoment(t, i, -1) - sumSquares) * inverseVariance +
                 prior->softMean[i] * precision;
    }
    for (i = 0; i < 3; i++) {
        squares += ImuMagPhiMoment(t, ImuMagSquareEntry[i], -1);
        for (j = 0; j < 3; j++) {
            fourth += ImuMagPhiMoment(t, ImuMagSquareEntry[i], ImuMagSquareEntry[j]);
        }
    }
    return (prior->offset * prior->offset * t[0] - 2.0 * prior->offset * squares + fourth) * inverseVariance;
}

/** @brief In-place Cholesky factor (lower) of a 6x6 matrix and the reciprocals of its diagonal; 0, or -1
 *         if not positive definite. */
static int ImuMagCholesky(double a[IMU_MAG_SOFT_COUNT][IMU_MAG_SOFT_COUNT], double inverse[IMU_MAG_SOFT_COUNT])
{
    int i, j, k;
    for (j = 0; j < IMU_MAG_SOFT_COUNT; j++) {
        double d = a[j][j];
        for (k = 0; k < j; k++) {
            d -= a[j][k] * a[j][k];
        }
        if (!(d > 0.0)) {
            return -1;
        }
        a[j][j] = sqrt(d);
        inverse[j] = 1.0 / a[j][j];
        for (i = j + 1; i < IMU_MAG_SOFT_COUNT; i++) {
            double s = a[i][j];
            for (k = 0; k < j; k++) {
                s -= a[i][k] * a[j][k];
            }
            a[i][j] = s * inverse[j];
        }
    }
    return 0;
}

/** @brief 1 if the symmetric 3x3 matrix is positive definite (leading minors, Sylvester). */
static int ImuMagPositiveDefinite(double s[3][3])
{
    const double minor2 = s[0][0] * s[1][1] - s[0][1] * s[1][0];
    const double det = s[0][0] * (s[1][1] * s[2][2] - s[1][2] * s[2][1]) -
                       s[0][1] * (s[1][0] * s[2][2] - s[1][2] * s[2][0]) +
                       s[0][2] * (s[1][0] * s[2][1] - s[1][1] * s[2][0]);
    return s[0][0] > 0.0 && minor2 > 0.0 && det > 0.0;
}

/** @brief 1 if every eigenvalue of I + M lies in (low, high). */
static int ImuMagAdmissible(const double m[IMU_MAG_SOFT_COUNT], double low, double high)
{
    double above[3][3], below[3][3];
    int k, i, j;
    for (k = 0; k < IMU_MAG_SOFT_COUNT; k++) {
        i = ImuMagSoftRow[k];
        j = ImuMagSoftColumn[k];
        above[i][j] = above[j][i] = m[k];
        below[i][j] = below[j][i] = -m[k];
    }
    for (i = 0; i < 3; i++) {
        above[i][i] += 1.0 - low;
        below[i][i] += high - 1.0;
    }
    return ImuMagPositiveDefinite(above) && ImuMagPositiveDefinite(below);
}

int ImuMagMarginal(const double sums[IMU_MAG_MOMENT_COUNT], const double p[3], const ImuMagMarginalPrior *prior,
                   double *logLikelihood, double soft[IMU_MAG_SOFT_COUNT])
{
    double t[IMU_MAG_MOMENT_COUNT], l[IMU_MAG_SOFT_COUNT][IMU_MAG_SOFT_COUNT], y[IMU_MAG_SOFT_COUNT];
    double inverse[IMU_MAG_SOFT_COUNT], residual, fit = 0.0, determinant = 1.0, priorFit = 0.0, hard = 0.0;
    int i, k;
    ImuMagMomentsShift(sums, p, t);
    residual = ImuMagNormalEquations(t, prior, l, y);
    *logLikelihood = -HUGE_VAL;
    if (ImuMagCholesky(l, inverse) != 0) {
        return 0;
    }
    for (i = 0; i < IMU_MAG_SOFT_COUNT; i++) { /* forward: y = L^-1 eta */
        for (k = 0; k < i; k++) {
            y[i] -= l[i][k] * y[k];
        }
        y[i] *= inverse[i];
        fit += y[i] * y[i];
        determinant *= l[i][i]; /* sqrt(det J): one logarithm below */
        priorFit += prior->softMean[i] * prior->softMean[i];
    }
    for (i = IMU_MAG_SOFT_COUNT - 1; i >= 0; i--) { /* backward: m = L^-T y */
        soft[i] = y[i];
        for (k = i + 1; k < IMU_MAG_SOFT_COUNT; k++) {
            soft[i] -= l[k][i] * soft[k];
        }
        soft[i] *= inverse[i];
    }
    if (!ImuMagAdmissible(soft, prior->minEigen, prior->maxEigen)) {
        return 0;
    }
    for (i = 0; i < 3; i++) {
        const double d = (p[i] - prior->hardCentre[i]) / prior->hardSpread;
        hard += d * d;
    }
    priorFit /= prior->softSpread * prior->softSpread;
    *logLikelihood = -0.5 * (residual - fit + priorFit) - log(determinant) - 0.5 * hard;
    return 1;
}

/** @brief Inverse of a symmetric 3x3 matrix by the adjugate. */
static void ImuMagInverse3(double a[3][3], double inverse[3][3])
{
    const double c00 = a[1][1] * a[2][2] - a[1][2] * a[2][1];
    const double c01 = a[1][2] * a[2][0] - a[1][0] * a[2][2];
    const double c02 = a[1][0] * a[2][1] - a[1][1] * a[2][0];
    const double det = a[0][0] * c00 + a[0][1] * c01 + a[0][2] * c02;
    inverse[0][0] = c00 / det;
    inverse[1][0] = c01 / det;
    inverse[2][0] = c02 / det;
    inverse[0][1] = (a[0][2] * a[2][1] - a[0][1] * a[2][2]) / det;
    inverse[1][1] = (a[0][0] * a[2][2] - a[0][2] * a[2][0]) / det;
    inverse[2][1] = (a[0][1] * a[2][0] - a[0][0] * a[2][1]) / det;
    inverse[0][2] = (a[0][1] * a[1][2] - a[0][2] * a[1][1]) / det;
    inverse[1][2] = (a[0][2] * a[1][0] - a[0][0] * a[1][2]) / det;
    inverse[2][2] = (a[0][0] * a[1][1] - a[0][1] * a[1][0]) / det;
}

void ImuMagSoftFromQuadratic(const double m[IMU_MAG_SOFT_COUNT], double b[IMU_MAG_SOFT_COUNT])
{
    double a[3][3], x[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}, inverse[3][3];
    int k, i, j, n;
    for (k = 0; k < IMU_MAG_SOFT_COUNT; k++) {
        a[ImuMagSoftRow[k]][ImuMagSoftColumn[k]] = a[ImuMagSoftColumn[k]][ImuMagSoftRow[k]] = m[k];
    }
    for (i = 0; i < 3; i++) {
        a[i][i] += 1.0;
    }
    for (n = 0; n < IMU_MAG_SQRT_ITERATIONS; n++) { /* X <- (X + X^-1 A) / 2, then symmetrised */
        double next[3][3];
        ImuMagInverse3(x, inverse);
        for (i = 0; i < 3; i++) {
            for (j = 0; j < 3; j++) {
                next[i][j] = 0.5 * (x[i][j] + inverse[i][0] * a[0][j] + inverse[i][1] * a[1][j] + inverse[i][2] * a[2][j]);
            }
        }
        for (i = 0; i < 3; i++) {
            for (j = 0; j < 3; j++) {
                x[i][j] = 0.5 * (next[i][j] + next[j][i]);
            }
        }
    }
    for (k = 0; k < IMU_MAG_SOFT_COUNT; k++) {
        b[k] = x[ImuMagSoftRow[k]][ImuMagSoftColumn[k]] - (ImuMagSoftRow[k] == ImuMagSoftColumn[k] ? 1.0 : 0.0);
    }
}

void ImuMagQuadraticFromSoft(const double b[IMU_MAG_SOFT_COUNT], double m[IMU_MAG_SOFT_COUNT])
{
    double s[3][3];
    int k;
    for (k = 0; k < IMU_MAG_SOFT_COUNT; k++) {
        s[ImuMagSoftRow[k]][ImuMagSoftColumn[k]] = s[ImuMagSoftColumn[k]][ImuMagSoftRow[k]] = b[k];
    }
    for (k = 0; k < IMU_MAG_SOFT_COUNT; k++) {
        const int i = ImuMagSoftRow[k], j = ImuMagSoftColumn[k];
        m[k] = 2.0 * s[i][j] + s[i][0] * s[0][j] + s[i][1] * s[1][j] + s[i][2] * s[2][j];
    }
}
