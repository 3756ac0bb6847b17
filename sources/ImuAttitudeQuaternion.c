/**
 * @file ImuAttitudeQuaternion.c
 * @brief Attitude mode IMU_ATTITUDE_QUATERNION: quaternion filter with disturbance rejection
 *        (ideas of VQF, Laidig & Seel, Information Fusion 91, 2023).
 *
 * Quaternion mode, q = Rz(heading offset) (x) qAcc (x) qGyr:
 * 1. qGyr <- qGyr (x) exp(w dt / 2) with the rate held over the step (gyro_hold) or the
 *    trapezoidal rate (strapdown into a frame that is inertial up to the gyro's drift).
 * 2. f is rotated into that frame and low-passed by a second-order Butterworth filter of time
 *    constant tau_acc (ImuLowPass.h): there a linear acceleration, which integrates to a velocity
 *    change, averages out while gravity stays put. qAcc is then turned about a horizontal axis so that the
 *    low-passed f points up (-z); the heading is untouched. With motion_bias, the turn's rate also
 *    measures the gyro bias in motion (ImuMotionBias.h).
 * 3. The field is rotated into the level frame qAcc (x) qGyr; its heading gives the measured
 *    offset -atan2(m_y, m_x). A field whose norm departs from field_norm by more than
 *    IMU_ATTITUDE_MAG_NORM_TOLERANCE or whose dip departs from field_dip by more than
 *    IMU_ATTITUDE_MAG_DIP_TOLERANCE, or has been within them for less than
 *    IMU_ATTITUDE_MAG_MIN_CLEAN_TIME, is rejected for at most mag_reject_time (the rejection time
 *    decays IMU_ATTITUDE_MAG_RECOVERY times faster while the field is clean, so a persistent new
 *    field is accepted again); an accepted one moves the offset with gain 1 - exp(-dt/tau_mag)
 *    (1/n over the first n samples, so the start averages instead of trusting one sample). A
 *    rejected sample sets magDisturbed (the FMU output mag_disturbed).
 * 4. Restart (issue 15): when the summed integration-error bounds of the recent steps
 *    (ImuAttitudeStepError, decaying with tau_acc) exceed IMU_ATTITUDE_RESTART_VARIANCE (a rate
 *    spike, lost samples, a clock jump), the strapdown frame may have turned by more than 10 deg
 *    and the corrections restart as at power-on: the low-passed f from the current sample, the
 *    heading averaging 1/n again, no field rejected. Without it the heading recovered only with
 *    tau_mag (five 2000 deg/s samples: still 14 deg after 10-20 s).
 */
#include <math.h>
#include "ImuAttitudePrivate.h"
#include "ImuMath.h"
#include "ImuQuaternion.h"

/* Relative tolerance of the field norm: the field of an undisturbed, calibrated magnetometer
 * stays within a few percent of the earth-field norm (BROAD undisturbed: 5-95 % within 7 %). */
#define IMU_ATTITUDE_MAG_NORM_TOLERANCE 0.1
/* Tolerance [rad] of the dip: 10 deg (BROAD undisturbed: 5-95 % within about 5 deg). */
#define IMU_ATTITUDE_MAG_DIP_TOLERANCE 0.1745329252
/* Rejection time decays this many times faster than it grows while the field is clean. */
#define IMU_ATTITUDE_MAG_RECOVERY 2.0

/**
 * @brief Quaternion mode: strapdown qGyr with the rate gyr [rad/s] over dt [s]. When the summed
 *        integration-error bounds of the recent steps (ImuAttitudeStepError, decaying with tau_acc)
 *        exceed IMU_ATTITUDE_RESTART_VARIANCE, the corrections restart as at power-on: the
 *        low-passed f restarts from the current sample and the heading averages 1/n again.
 */
static void ImuAttitudeQuaternionPredict(ImuAttitude *a, const double gyr[3], double dt)
{
    double rate[3];
    if (!(dt > 0.0)) {
        return;
    }
    a->stepError *= exp(-dt / a->settings.tauAcc);
    if (ImuAttitudeStepRate(a, gyr, rate)) {
        ImuQuaternionIntegrate(a->qGyr, rate, dt);
        a->stepError += ImuAttitudeStepError(a, gyr, dt);
    } else {
        a->stepError += IMU_ATTITUDE_UNTRACKED_MOTION * IMU_ATTITUDE_UNTRACKED_MOTION * dt;
    }
    if (a->stepError > IMU_ATTITUDE_RESTART_VARIANCE) {
        a->stepError = 0.0;
        a->tiltInitialised = 0;
        a->magSamples = 0.0;
        a->magRejected = 0.0;
        a->magClean = IMU_ATTITUDE_MAG_MIN_CLEAN_TIME;
    }
}

/**
 * @brief Inclination-rate error [rad/s] that linear acceleration may leave in a low-passed specific
 *        force of norm n [m/s^2]: the departure of n from g beyond the still accelerometer's own
 *        (acc_norm_tolerance: a scale error is not linear acceleration), over g tau_acc.
 */
static double ImuAttitudeLinearAccelerationRate(const ImuAttitude *a, double n)
{
    const double excess = fabs(n - IMU_ATTITUDE_GRAVITY) - a->settings.accNormTolerance * IMU_ATTITUDE_GRAVITY;
    return fmax(0.0, excess) / (IMU_ATTITUDE_GRAVITY * a->settings.tauAcc);
}

/** @brief Quaternion mode: low-pass f [m/s^2] in the inertial frame, turn qAcc to level it. */
static void ImuAttitudeQuaternionTilt(ImuAttitude *a, const double acc[3], double dt)
{
    double inertial[3], lowPassed[3], e[3], turn[4], product[4], n;
    ImuLowPassDesign design;
    int i;
    if (!a->tiltInitialised) {
        ImuLowPassReset(&a->accLowPass);
        ImuMotionBiasRestart(&a->motionBias);
    }
    ImuLowPassDesignStep(a->settings.tauAcc, dt, &design);
    ImuQuaternionRotate(a->qGyr, acc, inertial);
    ImuLowPassApply(&a->accLowPass, &design, inertial, lowPassed);
    ImuQuaternionRotate(a->qAcc, lowPassed, e);
    n = ImuVectorNorm(e);
    if (!(n > 0.0)) {
        return;
    }
    /* Shortest turn of the unit vector e onto up (0, 0, -1): [1 + e.up, e x up], normalised;
     * about x when e points straight down. */
    turn[0] = 1.0 - e[2] / n;
    turn[1] = -e[1] / n;
    turn[2] = e[0] / n;
    turn[3] = 0.0;
    if (turn[0] < 1e-12) {
        turn[0] = 0.0;
        turn[1] = 1.0;
        turn[2] = 0.0;
    }
    ImuQuaternionNormalise(turn);
    ImuQuaternionMultiply(turn, a->qAcc, product);
    for (i = 0; i < 4; i++) {
        a->qAcc[i] = product[i];
    }
    ImuQuaternionNormalise(a->qAcc);
    a->gain[0] = a->gain[1] = a->tiltInitialised ? 1.0 - exp(-dt / a->settings.tauAcc) : 1.0;
    if (a->settings.motionBias && dt > 0.0) {
        for (i = 0; i < 3; i++) {
            e[i] /= n;
        }
        ImuQuaternionMultiply(a->qAcc, a->qGyr, product);
        ImuMotionBiasUpdate(&a->motionBias, product, e, ImuAttitudeLinearAccelerationRate(a, n), &design, dt,
                            a->tiltInitialised && !a->atRest, a->bias);
    }
    a->tiltInitialised = 1;
}

/** @brief 1 if the level-frame field m [uT] disagrees with field_norm or field_dip. */
static int ImuAttitudeMagOff(const ImuAttitude *a, const double m[3])
{
    const double norm = ImuVectorNorm(m);
    const double dip = atan2(m[2], sqrt(m[0] * m[0] + m[1] * m[1]));
    return fabs(norm - a->settings.fieldNorm) > IMU_ATTITUDE_MAG_NORM_TOLERANCE * a->settings.fieldNorm
           || fabs(dip - a->settings.fieldDip) > IMU_ATTITUDE_MAG_DIP_TOLERANCE;
}

/** @brief Quaternion mode: correct the heading offset with the field mag [uT] after dt [s]. */
static void ImuAttitudeQuaternionHeading(ImuAttitude *a, const double mag[3], double dt)
{
    double level[4], m[3], k;
    int off;
    ImuQuaternionMultiply(a->qAcc, a->qGyr, level);
    ImuQuaternionRotate(level, mag, m);
    if (!(ImuVectorNorm(m) > 0.0)) {
        return;
    }
    off = ImuAttitudeMagOff(a, m);
    a->magClean = off ? 0.0 : a->magClean + dt;
    if (a->yawInitialised && a->settings.magRejectTime > 0.0
        && (off || a->magClean < IMU_ATTITUDE_MAG_MIN_CLEAN_TIME)) {
        if (a->magRejected < a->settings.magRejectTime) {
            a->magRejected += dt;
            a->magDisturbed = 1.0;
            return;
        }
    } else {
        a->magRejected = fmax(0.0, a->magRejected - IMU_ATTITUDE_MAG_RECOVERY * dt);
    }
    a->magSamples += 1.0;
    k = fmax(dt > 0.0 ? 1.0 - exp(-dt / a->settings.tauMag) : 0.0, 1.0 / a->magSamples);
    a->headingOffset = ImuWrapAngle(a->headingOffset + k * ImuWrapAngle(-atan2(m[1], m[0]) - a->headingOffset));
    a->gain[2] = k;
    a->yawInitialised = 1;
}

/** @brief Quaternion mode: one sample of corrected gyr [rad/s], acc [m/s^2], mag [uT]; dt [s]. */
void ImuAttitudeQuaternionUpdate(ImuAttitude *a, const double gyr[3], const double acc[3],
                                 const double mag[3], double dt)
{
    double q[4];
    a->magDisturbed = 0.0;
    ImuAttitudeQuaternionPredict(a, gyr, dt);
    if (ImuAllFinite(acc, 3)) {
        ImuAttitudeQuaternionTilt(a, acc, dt);
    }
    if (ImuAllFinite(mag, 3)) {
        ImuAttitudeQuaternionHeading(a, mag, dt);
    }
    ImuQuaternionMultiply(a->qAcc, a->qGyr, q);
    ImuQuaternionTurnNav(q, a->headingOffset);
    ImuQuaternionToMatrix(q, a->rotation);
    ImuMatrixToEuler(a->rotation, a->euler);
}
