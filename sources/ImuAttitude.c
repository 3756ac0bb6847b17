/**
 * @file ImuAttitude.c
 * @brief Adaptive-gain fusion of a gyro Euler set and an accelerometer/magnetometer Euler set.
 *
 * Per sample (dt since the previous one):
 * 1. Gyro set: the previous fused rotation R is propagated over dt with the mean of the previous
 *    and the current corrected rate (trapezoidal rule: holding the previous rate alone lags by
 *    half a sample, about 0.1 deg RMS at 100 Hz and 100 deg/s), R <- R exp([w x] dt), and
 *    decomposed into ZYX angles. Each angle's mean-square error grows,
 *    P_i += gyro_noise^2 dt + (gyro_bias_residual dt)^2 (white-noise random walk plus the drift
 *    of the residual bias over the step; a step without any finite rate adds the random walk of
 *    untracked motion instead of propagating).
 * 2. Acc/mag set: roll = atan2(-f_y, -f_z), pitch = atan2(f_x, |f_yz|); yaw = atan2(-m_y', m_x')
 *    of the field m' de-tilted into the level frame.
 * 3. Per angle: innovation e_i = wrap(acc/mag angle - gyro angle); R_i = moving mean of e_i^2
 *    (time constant mse_time_constant) floored by angle_noise^2, plus a term for the current
 *    departure of |f| from g (or |m| from field_norm); K_i = P_i / (P_i + R_i); fused angle =
 *    wrap(gyro angle + K_i e_i); P_i <- (1 - K_i) P_i. R is rebuilt from the fused angles.
 * Roll/pitch are set directly from the first finite accelerometer sample and yaw from the first
 * finite magnetometer sample (P_i = angle_noise^2 from the start). A non-finite rate is left out
 * of the propagation (the other one is held alone; neither finite: no propagation) and a
 * non-finite acc/mag sample skips its correction, so the state stays finite.
 */
#include <math.h>
#include "ImuAttitude.h"
#include "ImuMath.h"

/*
 * Roll/pitch measurement variance [rad^2] added per squared relative departure of |f| from g.
 * A linear acceleration a tilts the measured gravity direction by up to |a|/g rad and
 * |a| >= ||f| - g|, so ((|f| - g)/g)^2 is a lower bound of the squared tilt error it causes.
 */
#define IMU_ATTITUDE_ACC_DEPARTURE_VARIANCE 1.0
/*
 * Yaw measurement variance [rad^2] added per squared relative departure of |m| from field_norm.
 * A disturbance d turns the horizontal field by up to |d|/F_h rad; at mid-latitude dips (about
 * 60 deg) F_h is about F/2, so the yaw error is about 2|d|/F: variance 4 ((|m| - F)/F)^2.
 */
#define IMU_ATTITUDE_MAG_DEPARTURE_VARIANCE 4.0
/*
 * Angle random walk [rad/sqrt(s)] of motion that no gyro sample tracked (both rates of a step
 * non-finite): handheld motion turns by about 1 rad within 1 s, so after such a gap P_i is of the
 * order of the possible rotation and the next acc/mag fix is trusted accordingly.
 */
#define IMU_ATTITUDE_UNTRACKED_MOTION 1.0

/** @brief Set the settings and reset the state (level, yaw 0, nothing initialised). */
void ImuAttitudeInitialise(ImuAttitude *a, const ImuAttitudeSettings *s)
{
    a->settings = *s;
    ImuAttitudeReset(a);
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
    ImuMatrixFromEuler(0.0, 0.0, 0.0, a->rotation);
    a->tiltInitialised = 0;
    a->yawInitialised = 0;
}

/**
 * @brief Rate [rad/s] held over the step: the mean of the previous and current corrected rates
 *        (trapezoidal rule), or the one that is finite; 0 if neither is.
 */
static int ImuAttitudeStepRate(const ImuAttitude *a, const double gyr[3], double rate[3])
{
    const int previous = ImuAllFinite(a->previousRate, 3), current = ImuAllFinite(gyr, 3);
    int i;
    for (i = 0; i < 3; i++) {
        if (previous && current) {
            rate[i] = 0.5 * (a->previousRate[i] + gyr[i]);
        } else {
            rate[i] = previous ? a->previousRate[i] : gyr[i];
        }
    }
    return previous || current;
}

/** @brief Gyro Euler set: propagate R with the rate gyr [rad/s] over dt [s] and grow P_i. */
static void ImuAttitudePredict(ImuAttitude *a, const double gyr[3], double dt)
{
    const ImuAttitudeSettings *s = &a->settings;
    double rate[3], growth;
    int i;
    if (!(dt > 0.0)) {
        return;
    }
    growth = s->gyroNoise * s->gyroNoise * dt + (s->gyroBiasResidual * dt) * (s->gyroBiasResidual * dt);
    if (ImuAttitudeStepRate(a, gyr, rate)) {
        ImuMatrixPropagate(a->rotation, rate, dt);
        ImuMatrixToEuler(a->rotation, a->euler);
    } else {
        growth += IMU_ATTITUDE_UNTRACKED_MOTION * IMU_ATTITUDE_UNTRACKED_MOTION * dt;
    }
    for (i = 0; i < 3; i++) {
        a->variance[i] += growth;
    }
}

/**
 * @brief Fuse angle i with its acc/mag measurement [rad]; extra [rad^2] is the departure
 *        variance of this sample, alpha [1] the moving-mean weight of this sample.
 */
static void ImuAttitudeCorrect(ImuAttitude *a, int i, double measured, double extra, double alpha)
{
    const double floor = a->settings.angleNoise * a->settings.angleNoise;
    const double e = ImuWrapAngle(measured - a->euler[i]);
    double k;
    a->mse[i] += alpha * (e * e - a->mse[i]);
    if (a->mse[i] < floor) {
        a->mse[i] = floor;
    }
    k = a->variance[i] / (a->variance[i] + a->mse[i] + extra);
    a->euler[i] = ImuWrapAngle(a->euler[i] + k * e);
    a->variance[i] *= 1.0 - k;
    a->gain[i] = k;
}

/** @brief Roll/pitch from a finite specific force acc [m/s^2]: initialise or correct. */
static void ImuAttitudeCorrectTilt(ImuAttitude *a, const double acc[3], double alpha)
{
    const double roll = atan2(-acc[1], -acc[2]);
    const double pitch = atan2(acc[0], sqrt(acc[1] * acc[1] + acc[2] * acc[2]));
    const double departure = (ImuVectorNorm(acc) - IMU_ATTITUDE_GRAVITY) / IMU_ATTITUDE_GRAVITY;
    const double extra = IMU_ATTITUDE_ACC_DEPARTURE_VARIANCE * departure * departure;
    if (!a->tiltInitialised) {
        a->euler[0] = roll;
        a->euler[1] = pitch;
        a->tiltInitialised = 1;
        return;
    }
    ImuAttitudeCorrect(a, 0, roll, extra, alpha);
    ImuAttitudeCorrect(a, 1, pitch, extra, alpha);
}

/**
 * @brief Yaw from a finite field mag [uT] de-tilted with roll/pitch tilt[2] [rad]: initialise
 *        or correct.
 */
static void ImuAttitudeCorrectYaw(ImuAttitude *a, const double mag[3], const double tilt[2], double alpha)
{
    const double fieldNorm = a->settings.fieldNorm;
    const double departure = (ImuVectorNorm(mag) - fieldNorm) / fieldNorm;
    double level[9], m[3], yaw;
    ImuMatrixFromEuler(tilt[0], tilt[1], 0.0, level); /* Ry(pitch) Rx(roll): body -> level */
    ImuMatrixVector(level, mag, m);
    yaw = atan2(-m[1], m[0]);
    if (!a->yawInitialised) {
        a->euler[2] = yaw;
        a->yawInitialised = 1;
        return;
    }
    ImuAttitudeCorrect(a, 2, yaw, IMU_ATTITUDE_MAG_DEPARTURE_VARIANCE * departure * departure, alpha);
}

/** @brief Process one sample: gyr [rad/s], acc [m/s^2], mag [uT]; dt [s] since the previous. */
void ImuAttitudeUpdate(ImuAttitude *a, const double gyr[3], const double acc[3], const double mag[3],
                       double dt)
{
    const double alpha = dt > 0.0 ? 1.0 - exp(-dt / a->settings.mseTimeConstant) : 0.0;
    const int tiltWasInitialised = a->tiltInitialised;
    double predictedTilt[2];
    int i;
    ImuAttitudePredict(a, gyr, dt);
    predictedTilt[0] = a->euler[0];
    predictedTilt[1] = a->euler[1];
    for (i = 0; i < 3; i++) {
        a->gain[i] = 0.0;
        a->previousRate[i] = gyr[i];
    }
    if (ImuAllFinite(acc, 3)) {
        ImuAttitudeCorrectTilt(a, acc, alpha);
    }
    if (ImuAllFinite(mag, 3)) {
        /* De-tilt with the gyro-predicted roll/pitch: unlike the accelerometer angles they are
         * not disturbed by linear acceleration. Before the first tilt fix, use the fresh one. */
        ImuAttitudeCorrectYaw(a, mag, tiltWasInitialised ? predictedTilt : a->euler, alpha);
    }
    ImuMatrixFromEuler(a->euler[0], a->euler[1], a->euler[2], a->rotation);
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

/** @brief Fusion gains [1] of roll, pitch, yaw from the last update. */
void ImuAttitudeGetGains(const ImuAttitude *a, double gains[3])
{
    int i;
    for (i = 0; i < 3; i++) {
        gains[i] = a->gain[i];
    }
}
