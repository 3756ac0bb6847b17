/**
 * @file ImuMotionBias.c
 * @brief The gyro bias during motion from the inclination correction (ImuMotionBias.h).
 */
#include <math.h>
#include "ImuMotionBias.h"
#include "ImuMath.h"
#include "ImuQuaternion.h"

/* Prior standard deviation [deg/s] of the bias in motion, and the ceiling P grows back to. */
#define IMU_MOTION_BIAS_SIGMA_INIT 0.5
/* P grows from 0 to (0.1 deg/s)^2 in this time [s] without measurements (the bias wanders). */
#define IMU_MOTION_BIAS_FORGETTING_TIME 100.0
/* Standard deviation [deg/s] P settles at under a steady stream of motion measurements. */
#define IMU_MOTION_BIAS_SIGMA_MOTION 0.1
/* The vertical row's variance is the horizontal one's divided by this. */
#define IMU_MOTION_BIAS_VERTICAL_FORGETTING 1e-4
/* Largest bias disagreement [deg/s] one measurement may report (limits a first correction's harm). */
#define IMU_MOTION_BIAS_CLIP 2.0

/** @brief (deg/s)^2 -> (rad/s)^2 of the rate deg [deg/s]. */
static double ImuMotionBiasVariance(double deg)
{
    const double rad = deg * IMU_PI / 180.0;
    return rad * rad;
}

void ImuMotionBiasReset(ImuMotionBias *m)
{
    int i;
    for (i = 0; i < 9; i++) {
        m->covariance[i] = i % 4 == 0 ? ImuMotionBiasVariance(IMU_MOTION_BIAS_SIGMA_INIT) : 0.0;
    }
    ImuMotionBiasRestart(m);
}

void ImuMotionBiasRestart(ImuMotionBias *m)
{
    int i;
    for (i = 0; i < 3; i++) {
        ImuLowPassReset(&m->rotation[i]);
    }
    ImuLowPassReset(&m->rotatedBias);
}

int ImuMotionBiasStateValid(const ImuMotionBias *m)
{
    int i, valid = ImuLowPassStateValid(&m->rotatedBias);
    for (i = 0; i < 3; i++) {
        valid = valid && ImuLowPassStateValid(&m->rotation[i]);
    }
    for (i = 0; i < 9; i++) {
        valid = valid && isfinite(m->covariance[i]);
    }
    return valid;
}

/** @brief out = inverse of the symmetric 3x3 matrix s (row-major, positive definite). */
static void ImuMotionBiasInvert(const double s[9], double out[9])
{
    const double c0 = s[4] * s[8] - s[5] * s[7], c1 = s[5] * s[6] - s[3] * s[8], c2 = s[3] * s[7] - s[4] * s[6];
    const double det = s[0] * c0 + s[1] * c1 + s[2] * c2;
    out[0] = c0 / det;
    out[1] = (s[2] * s[7] - s[1] * s[8]) / det;
    out[2] = (s[1] * s[5] - s[2] * s[4]) / det;
    out[3] = c1 / det;
    out[4] = (s[0] * s[8] - s[2] * s[6]) / det;
    out[5] = (s[2] * s[3] - s[0] * s[5]) / det;
    out[6] = c2 / det;
    out[7] = (s[1] * s[6] - s[0] * s[7]) / det;
    out[8] = (s[0] * s[4] - s[1] * s[3]) / det;
}

/** @brief Kalman update of bias [rad/s] and P with the measurement error e [rad/s] = y - H bias,
 *         measurement matrix h (row-major) and measurement variances w [(rad/s)^2]. */
static void ImuMotionBiasKalman(ImuMotionBias *m, const double h[9], const double e[3], const double w[3],
                                double bias[3])
{
    double ht[9], pht[9], s[9], sInverse[9], k[9], kh[9], khp[9];
    int i, j;
    for (i = 0; i < 3; i++) {
        for (j = 0; j < 3; j++) {
            ht[3 * i + j] = h[3 * j + i];
        }
    }
    ImuMatrixMultiply(m->covariance, ht, pht);
    ImuMatrixMultiply(h, pht, s);
    for (i = 0; i < 3; i++) {
        s[4 * i] += w[i];
    }
    ImuMotionBiasInvert(s, sInverse);
    ImuMatrixMultiply(pht, sInverse, k);
    for (i = 0; i < 3; i++) {
        bias[i] += k[3 * i] * e[0] + k[3 * i + 1] * e[1] + k[3 * i + 2] * e[2];
    }
    ImuMatrixMultiply(k, h, kh);
    ImuMatrixMultiply(kh, m->covariance, khp);
    for (i = 0; i < 9; i++) {
        m->covariance[i] -= khp[i];
    }
}

void ImuMotionBiasUpdate(ImuMotionBias *m, const double q6d[4], const double up[3], double rateError,
                         const ImuLowPassDesign *design, double dt, int observe, double bias[3])
{
    const double ceiling = ImuMotionBiasVariance(IMU_MOTION_BIAS_SIGMA_INIT);
    const double p = ImuMotionBiasVariance(IMU_MOTION_BIAS_SIGMA_MOTION);
    const double v = p * dt / IMU_MOTION_BIAS_FORGETTING_TIME, clip = IMU_MOTION_BIAS_CLIP * IMU_PI / 180.0;
    double r[9], rotated[3], rotatedBias[3], h[9], hb[3], e[3], w[3];
    int i;
    ImuQuaternionToMatrix(q6d, r);
    ImuMatrixVector(r, bias, rotated);
    for (i = 0; i < 3; i++) {
        ImuLowPassApply(&m->rotation[i], design, &r[3 * i], &h[3 * i]);
    }
    ImuLowPassApply(&m->rotatedBias, design, rotated, rotatedBias);
    for (i = 0; i < 3; i++) {
        if (m->covariance[4 * i] < ceiling) {
            m->covariance[4 * i] += v;
        }
    }
    if (!observe) {
        return;
    }
    /* The correction turned up onto (0, 0, -1): about x by -up_y, about y by up_x, over dt. */
    ImuMatrixVector(h, bias, hb);
    e[0] = up[1] / dt + rotatedBias[0] - hb[0];
    e[1] = -up[0] / dt + rotatedBias[1] - hb[1];
    e[2] = -hb[2];
    for (i = 0; i < 3; i++) {
        e[i] = fmax(-clip, fmin(clip, e[i]));
    }
    w[0] = w[1] = (p * p / v + p) * (1.0 + rateError * rateError / p);
    w[2] = w[0] / IMU_MOTION_BIAS_VERTICAL_FORGETTING;
    ImuMotionBiasKalman(m, h, e, w, bias);
}
