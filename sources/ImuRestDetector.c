/**
 * @file ImuRestDetector.c
 * @brief Rest detection on gyro and accelerometer (thresholds on deviations from low-passed values).
 */
#include <math.h>
#include "ImuRestDetector.h"

/** @brief Forget everything (not at rest). */
void ImuRestDetectorReset(ImuRestDetector *r)
{
    int i;
    for (i = 0; i < 3; i++) {
        r->gyrLp[i] = 0.0;
        r->accLp[i] = 0.0;
    }
    r->restTime = 0.0;
    r->initialised = 0;
}

/** @brief 1 if every sample of this step is within the thresholds [rad/s, m/s^2] of the filters and the
 *         low-passed rate within biasThreshold [rad/s] on every axis. */
static int ImuRestDetectorQuiet(const ImuRestDetector *r, const double gyr[3], const double acc[3],
                                double gyroThreshold, double biasThreshold, double accThreshold)
{
    double gyrDev = 0.0, accDev = 0.0;
    int i;
    for (i = 0; i < 3; i++) {
        gyrDev += (gyr[i] - r->gyrLp[i]) * (gyr[i] - r->gyrLp[i]);
        accDev += (acc[i] - r->accLp[i]) * (acc[i] - r->accLp[i]);
        if (fabs(r->gyrLp[i]) > biasThreshold) {
            return 0;
        }
    }
    return gyrDev < gyroThreshold * gyroThreshold && accDev < accThreshold * accThreshold;
}

int ImuRestDetectorUpdate(ImuRestDetector *r, const double gyr[3], const double acc[3], double dt,
                          double gyroThreshold, double accThreshold)
{
    return ImuRestDetectorUpdateBias(r, gyr, acc, dt, gyroThreshold, gyroThreshold, accThreshold);
}

/** @brief Feed one sample gyr [rad/s], acc [m/s^2] after dt [s]; 1 at rest, else 0. */
int ImuRestDetectorUpdateBias(ImuRestDetector *r, const double gyr[3], const double acc[3], double dt,
                              double gyroThreshold, double biasThreshold, double accThreshold)
{
    const double alpha = dt > 0.0 ? 1.0 - exp(-dt / IMU_REST_FILTER_TIME) : 0.0;
    int i;
    if (!r->initialised) {
        for (i = 0; i < 3; i++) {
            r->gyrLp[i] = gyr[i];
            r->accLp[i] = acc[i];
        }
        r->initialised = 1;
        return 0;
    }
    for (i = 0; i < 3; i++) {
        r->gyrLp[i] += alpha * (gyr[i] - r->gyrLp[i]);
        r->accLp[i] += alpha * (acc[i] - r->accLp[i]);
    }
    if (ImuRestDetectorQuiet(r, gyr, acc, gyroThreshold, biasThreshold, accThreshold)) {
        r->restTime += dt;
    } else {
        r->restTime = 0.0;
    }
    return r->restTime >= IMU_REST_MIN_TIME;
}

/** @brief Low-passed rate [rad/s]: the gyro bias while at rest. */
void ImuRestDetectorGetRate(const ImuRestDetector *r, double rate[3])
{
    int i;
    for (i = 0; i < 3; i++) {
        rate[i] = r->gyrLp[i];
    }
}
