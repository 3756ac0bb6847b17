/**
 * @file ImuMagMoments.h
 * @brief Sufficient statistics of field samples and the hard-iron likelihood with the soft iron
 *        integrated out (Rao-Blackwellisation of the magnetometer particle filter, docs/magpf.md).
 *
 * With d = h_m - h_p and A = (I + B)^T (I + B) = I + M, a calibrated sample satisfies
 * d^T (I + M) d = |h_0|^2, i.e. phi(d)^T m = |h_0|^2 + 3 sigma^2 - |d|^2 + noise, linear in the six
 * entries m = [M11 M12 M13 M22 M23 M33] with phi(d) = [d1^2, 2 d1 d2, 2 d1 d3, d2^2, 2 d2 d3, d3^2].
 * Given h_p and a Gaussian prior on m, m has a Gaussian posterior and the likelihood of h_p is
 * exact. Every term it needs is a sum over samples of a polynomial of degree <= 4 in d, so the
 * 35 power sums of u = h_m - reference (all monomials u1^a u2^b u3^c, a + b + c <= 4) are
 * sufficient: the likelihood of any h_p follows from them by a binomial shift, whatever the
 * number of samples.
 */
#ifndef IMU_MAG_MOMENTS_H
#define IMU_MAG_MOMENTS_H

#include "ImuCommon.h"

#define IMU_MAG_MOMENT_COUNT 35 /* monomials of degree <= 4 in 3 variables */
#define IMU_MAG_SOFT_COUNT 6    /* m11 m12 m13 m22 m23 m33 */

/** Gaussian priors of one likelihood evaluation. */
typedef struct {
    double hardCentre[3];              /* uT, prior mean of h_p (relative to the moment reference) */
    double hardSpread;                 /* uT, prior sigma of each h_p component, > 0 */
    double softMean[IMU_MAG_SOFT_COUNT]; /* 1, prior mean of m */
    double softSpread;                 /* 1, prior sigma of each m entry, > 0 */
    double offset;                     /* uT^2, |h_0|^2 + 3 sigma^2 */
    double variance;                   /* uT^4, 4 |h_0|^2 sigma^2 + 6 sigma^4 */
    double minEigen;                   /* 1, smallest admissible eigenvalue of I + M */
    double maxEigen;                   /* 1, largest admissible eigenvalue of I + M */
} ImuMagMarginalPrior;

/** @brief sums += all monomials of u [uT^k] (one sample). */
IMU_HIDDEN void ImuMagMomentsAdd(double sums[IMU_MAG_MOMENT_COUNT], const double u[3]);
/** @brief shifted[k] = sum over samples of the monomials of (u - p), from the power sums of u. */
IMU_HIDDEN void ImuMagMomentsShift(const double sums[IMU_MAG_MOMENT_COUNT], const double p[3],
                                   double shifted[IMU_MAG_MOMENT_COUNT]);
/**
 * @brief Log of p(samples | h_p) p(h_p) with m integrated out (up to a constant) for a hard iron p
 *        [uT, relative to the moment reference]; soft[6] receives the posterior mean of m.
 * @return 1 if the posterior mean gives I + M eigenvalues inside (minEigen, maxEigen), else 0
 *         (*logLikelihood is then -HUGE_VAL).
 */
IMU_HIDDEN int ImuMagMarginal(const double sums[IMU_MAG_MOMENT_COUNT], const double p[3],
                              const ImuMagMarginalPrior *prior, double *logLikelihood,
                              double soft[IMU_MAG_SOFT_COUNT]);
/** @brief Symmetric B = sqrt(I + M) - I [1] (b11 b12 b13 b22 b23 b33) of m (Newton iteration). */
IMU_HIDDEN void ImuMagSoftFromQuadratic(const double m[IMU_MAG_SOFT_COUNT], double b[IMU_MAG_SOFT_COUNT]);
/** @brief m of M = (I + B)^2 - I for a symmetric B given as b11 b12 b13 b22 b23 b33. */
IMU_HIDDEN void ImuMagQuadraticFromSoft(const double b[IMU_MAG_SOFT_COUNT], double m[IMU_MAG_SOFT_COUNT]);

#endif
