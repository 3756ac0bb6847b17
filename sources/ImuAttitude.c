/**
 * @file ImuAttitude.c
 * @brief Attitude facade: settings, reset and restart, the gyro bias at rest, the dispatch to the
 *        mode's filter, the getters (the verbs ImuPipeline.c uses).
 *
 * Gyro bias (both modes): while the rest detector holds (ImuRestDetector.h; enabled by
 * rest_gyro_threshold > 0), the bias follows the low-passed rate with time constant
 * IMU_ATTITUDE_REST_BIAS_TIME; in motion the quaternion mode's inclination correction moves it
 * (motion_bias: ImuMotionBias.h). Every rate is used minus the bias.
 *
 * Files, dependencies one way: ImuAttitude.c (this facade) -> ImuAttitudeEuler.c (adaptive-gain
 * Euler fusion, the method) and ImuAttitudeQuaternion.c (quaternion filter) -> ImuAttitudeStep.c
 * (the integration step both use); shared declarations in ImuAttitudePrivate.h.
 *
 * A non-finite rate is left out of the propagation (the other one is held alone; neither finite:
 * no propagation) and a non-finite acc/mag sample skips its correction, so the state stays finite.
 */
#include <math.h>
#include "ImuAttitudePrivate.h"
#include "ImuMath.h"
#include "ImuQuaternion.h"

/*
 * Time constant [s] of the bias estimate at rest: averages the rest detector's low-passed rate
 * (itself 0.5 s) further, so sensor noise leaves a bias error far below the rest threshold.
 */
#define IMU_ATTITUDE_REST_BIAS_TIME 2.0

/** @brief Set the settings and reset the state (level, yaw 0, nothing initialised). */
void ImuAttitudeInitialise(ImuAttitude *a, const ImuAttitudeSettings *s)
{
    a->settings = *s;
    ImuAttitudeReset(a);
}

/** @brief 1 if flag is 0 or 1. */
static int ImuAttitudeFlag(int flag)
{
    return flag == 0 || flag == 1;
}

int ImuAttitudeStateValid(const ImuAttitude *a)
{
    return ImuAttitudeFlag(a->tiltInitialised) && ImuAttitudeFlag(a->yawInitialised) && ImuAttitudeFlag(a->atRest)
           && isfinite(a->nominalStep) && a->nominalStep >= 0.0 && ImuLowPassStateValid(&a->accLowPass)
           && ImuMotionBiasStateValid(&a->motionBias);
}

/** @brief Reset the state, keeping the settings. */
void ImuAttitudeReset(ImuAttitude *a)
{
    const double floor = a->settings.angleNoise * a->settings.angleNoise;
    int i;
    for (i = 0; i < 3; i++) {
        a->euler[i] = 0.0;
        a->variance[i] = floor;
        a->mse[i] = floor;
        a->gain[i] = 0.0;
        a->previousRate[i] = 0.0;
    }
    a->nominalStep = 0.0;
    ImuMatrixFromEuler(0.0, 0.0, 0.0, a->rotation);
    a->tiltInitialised = 0;
    a->yawInitialised = 0;
    for (i = 0; i < 4; i++) {
        a->qGyr[i] = i == 0 ? 1.0 : 0.0;
        a->qAcc[i] = i == 0 ? 1.0 : 0.0;
    }
    for (i = 0; i < 3; i++) {
        a->bias[i] = 0.0;
    }
    ImuRestDetectorReset(&a->rest);
    a->atRest = 0;
    ImuMotionBiasReset(&a->motionBias);
    ImuLowPassReset(&a->accLowPass);
    a->headingOffset = 0.0;
    a->magRejected = 0.0;
    a->magClean = IMU_ATTITUDE_MAG_MIN_CLEAN_TIME;
    a->magSamples = 0.0;
    a->magDisturbed = 0.0;
    a->stepError = 0.0;
}

/** @brief After a gap [s]: restart the corrections as at power-on, keeping the gyro bias and the
 *         angles; the variance grows by the untracked motion over the gap. */
void ImuAttitudeRestart(ImuAttitude *a, double gap)
{
    const double untracked = fmin(IMU_ATTITUDE_UNTRACKED_MOTION * gap, IMU_PI); /* rad: no angle is more unknown than +-pi */
    int i;
    for (i = 0; i < 3; i++) {
        a->variance[i] += untracked * untracked;
    }
    a->tiltInitialised = 0;
    a->yawInitialised = 0;
    ImuRestDetectorReset(&a->rest);
    a->atRest = 0;
    a->magRejected = 0.0;
    a->magClean = IMU_ATTITUDE_MAG_MIN_CLEAN_TIME;
    a->magSamples = 0.0;
    a->stepError = 0.0;
}

/** @brief Update the gyro bias [rad/s] from a finite sample gyr [rad/s], acc [m/s^2] at rest. */
static void ImuAttitudeUpdateBias(ImuAttitude *a, const double gyr[3], const double acc[3], double dt)
{
    const ImuAttitudeSettings *s = &a->settings;
    const double k = 1.0 - exp(-dt / IMU_ATTITUDE_REST_BIAS_TIME);
    double rate[3];
    int i;
    a->atRest = ImuRestDetectorUpdate(&a->rest, gyr, acc, dt, s->restGyroThreshold, s->restAccThreshold);
    if (a->atRest) {
        ImuRestDetectorGetRate(&a->rest, rate);
        for (i = 0; i < 3; i++) {
            a->bias[i] += k * (rate[i] - a->bias[i]);
        }
    }
}

/** @brief Process one sample: gyr [rad/s], acc [m/s^2], mag [uT]; dt [s] since the previous. */
void ImuAttitudeUpdate(ImuAttitude *a, const double gyr[3], const double acc[3], const double mag[3],
                       double dt, double nominalStep)
{
    static const double unused[3] = {NAN, NAN, NAN};
    double rate[3];
    int i;
    a->nominalStep = nominalStep;
    if (!a->settings.magHeading) {
        mag = unused; /* 6D: as without a magnetometer */
    }
    if (a->settings.restGyroThreshold > 0.0 && dt > 0.0 && ImuAllFinite(gyr, 3) && ImuAllFinite(acc, 3)) {
        ImuAttitudeUpdateBias(a, gyr, acc, dt);
    }
    for (i = 0; i < 3; i++) {
        rate[i] = gyr[i] - a->bias[i];
        a->gain[i] = 0.0;
    }
    if (a->settings.mode == IMU_ATTITUDE_QUATERNION) {
        ImuAttitudeQuaternionUpdate(a, rate, acc, mag, dt);
    } else {
        ImuAttitudeEulerUpdate(a, rate, acc, mag, dt);
    }
    for (i = 0; i < 3; i++) {
        a->previousRate[i] = rate[i];
    }
}

/** @brief Fused roll, pitch, yaw [rad], each in (-pi, pi]. */
void ImuAttitudeGetEuler(const ImuAttitude *a, double euler[3])
{
    int i;
    for (i = 0; i < 3; i++) {
        euler[i] = ImuWrapAngle(a->euler[i]);
    }
}

/** @brief Attitude quaternion [w, x, y, z] body -> magnetic NED, w >= 0. */
void ImuAttitudeGetQuaternion(const ImuAttitude *a, double q[4])
{
    ImuQuaternionFromMatrix(a->rotation, q);
}

/** @brief 1 while the filter rejects the field as disturbed (quaternion mode), else 0. */
int ImuAttitudeMagDisturbed(const ImuAttitude *a)
{
    return a->magDisturbed > 0.0;
}

/** @brief Fusion gains [1] of roll, pitch, yaw from the last update. */
void ImuAttitudeGetGains(const ImuAttitude *a, double gains[3])
{
    int i;
    for (i = 0; i < 3; i++) {
        gains[i] = a->gain[i];
    }
}
