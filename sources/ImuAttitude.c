/**
 * @file ImuAttitude.c
 * @brief Attitude: adaptive-gain Euler fusion (the method) or a quaternion filter, both on gyro
 *        rates corrected by a bias estimated at rest.
 *
 * Gyro bias (both modes): while the rest detector holds (ImuRestDetector.h; enabled by
 * rest_gyro_threshold > 0), the bias follows the low-passed rate with time constant
 * IMU_ATTITUDE_REST_BIAS_TIME; every rate is used minus the bias.
 *
 * Euler mode, per sample (dt since the previous one):
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
 * finite magnetometer sample (P_i = angle_noise^2 from the start).
 *
 * Quaternion mode, q = Rz(heading offset) (x) qAcc (x) qGyr:
 * 1. qGyr <- qGyr (x) exp(w dt / 2) with the trapezoidal rate (strapdown into a frame that is
 *    inertial up to the gyro's drift).
 * 2. f is rotated into that frame and low-passed by two first-order stages of time constant
 *    tau_acc / 2: there a linear acceleration, which integrates to a velocity change, averages
 *    out while gravity stays put. qAcc is then turned about a horizontal axis so that the
 *    low-passed f points up (-z); the heading is untouched.
 * 3. The field is rotated into the level frame qAcc (x) qGyr; its heading gives the measured
 *    offset -atan2(m_y, m_x). A field whose norm departs from field_norm by more than
 *    IMU_ATTITUDE_MAG_NORM_TOLERANCE or whose dip departs from field_dip by more than
 *    IMU_ATTITUDE_MAG_DIP_TOLERANCE is rejected for at most mag_reject_time (the rejection time
 *    decays IMU_ATTITUDE_MAG_RECOVERY times faster while the field is clean, so a persistent new
 *    field is accepted again); an accepted one moves the offset with gain 1 - exp(-dt/tau_mag)
 *    (1/n over the first n samples, so the start averages instead of trusting one sample).
 *
 * A non-finite rate is left out of the propagation (the other one is held alone; neither finite:
 * no propagation) and a non-finite acc/mag sample skips its correction, so the state stays finite.
 */
#include <math.h>
#include "ImuAttitude.h"
#include "ImuMath.h"
#include "ImuQuaternion.h"

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
/*
 * Time constant [s] of the bias estimate at rest: averages the rest detector's low-passed rate
 * (itself 0.5 s) further, so sensor noise leaves a bias error far below the rest threshold.
 */
#define IMU_ATTITUDE_REST_BIAS_TIME 2.0
/* Relative tolerance of the field norm: the field of an undisturbed, calibrated magnetometer
 * stays within a few percent of the earth-field norm (BROAD undisturbed: 5-95 % within 7 %). */
#define IMU_ATTITUDE_MAG_NORM_TOLERANCE 0.1
/* Tolerance [rad] of the dip: 10 deg (BROAD undisturbed: 5-95 % within about 5 deg). */
#define IMU_ATTITUDE_MAG_DIP_TOLERANCE 0.1745329252
/* Rejection time decays this many times faster than it grows while the field is clean. */
#define IMU_ATTITUDE_MAG_RECOVERY 2.0

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
    for (i = 0; i < 4; i++) {
        a->qGyr[i] = i == 0 ? 1.0 : 0.0;
        a->qAcc[i] = i == 0 ? 1.0 : 0.0;
    }
    for (i = 0; i < 3; i++) {
        a->bias[i] = 0.0;
        a->accLp[0][i] = 0.0;
        a->accLp[1][i] = 0.0;
    }
    ImuRestDetectorReset(&a->rest);
    a->headingOffset = 0.0;
    a->magRejected = 0.0;
    a->magSamples = 0.0;
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

/** @brief Euler mode: one sample of corrected gyr [rad/s], acc [m/s^2], mag [uT]; dt [s]. */
static void ImuAttitudeUpdateEuler(ImuAttitude *a, const double gyr[3], const double acc[3], const double mag[3],
                                   double dt)
{
    const double alpha = dt > 0.0 ? 1.0 - exp(-dt / a->settings.mseTimeConstant) : 0.0;
    const int tiltWasInitialised = a->tiltInitialised;
    double predictedTilt[2];
    ImuAttitudePredict(a, gyr, dt);
    predictedTilt[0] = a->euler[0];
    predictedTilt[1] = a->euler[1];
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

/** @brief Quaternion mode: strapdown qGyr with the rate gyr [rad/s] over dt [s]. */
static void ImuAttitudeQuaternionPredict(ImuAttitude *a, const double gyr[3], double dt)
{
    double rate[3];
    if (dt > 0.0 && ImuAttitudeStepRate(a, gyr, rate)) {
        ImuQuaternionIntegrate(a->qGyr, rate, dt);
    }
}

/** @brief Quaternion mode: low-pass f [m/s^2] in the inertial frame, turn qAcc to level it. */
static void ImuAttitudeQuaternionTilt(ImuAttitude *a, const double acc[3], double dt)
{
    const double alpha = dt > 0.0 ? 1.0 - exp(-2.0 * dt / a->settings.tauAcc) : 0.0;
    double inertial[3], e[3], turn[4], product[4], n;
    int i;
    ImuQuaternionRotate(a->qGyr, acc, inertial);
    for (i = 0; i < 3; i++) {
        if (!a->tiltInitialised) {
            a->accLp[0][i] = inertial[i];
            a->accLp[1][i] = inertial[i];
        }
        a->accLp[0][i] += alpha * (inertial[i] - a->accLp[0][i]);
        a->accLp[1][i] += alpha * (a->accLp[0][i] - a->accLp[1][i]);
    }
    ImuQuaternionRotate(a->qAcc, a->accLp[1], e);
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
    a->gain[0] = a->gain[1] = a->tiltInitialised ? alpha : 1.0;
    a->tiltInitialised = 1;
}

/** @brief 1 if the level-frame field m [uT] disagrees with field_norm or field_dip. */
static int ImuAttitudeMagDisturbed(const ImuAttitude *a, const double m[3])
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
    ImuQuaternionMultiply(a->qAcc, a->qGyr, level);
    ImuQuaternionRotate(level, mag, m);
    if (!(ImuVectorNorm(m) > 0.0)) {
        return;
    }
    if (a->yawInitialised && a->settings.magRejectTime > 0.0 && ImuAttitudeMagDisturbed(a, m)) {
        if (a->magRejected < a->settings.magRejectTime) {
            a->magRejected += dt;
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
static void ImuAttitudeUpdateQuaternion(ImuAttitude *a, const double gyr[3], const double acc[3],
                                        const double mag[3], double dt)
{
    double q[4];
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

/** @brief Update the gyro bias [rad/s] from a finite sample gyr [rad/s], acc [m/s^2] at rest. */
static void ImuAttitudeUpdateBias(ImuAttitude *a, const double gyr[3], const double acc[3], double dt)
{
    const ImuAttitudeSettings *s = &a->settings;
    const double k = 1.0 - exp(-dt / IMU_ATTITUDE_REST_BIAS_TIME);
    double rate[3];
    int i;
    if (ImuRestDetectorUpdate(&a->rest, gyr, acc, dt, s->restGyroThreshold, s->restAccThreshold)) {
        ImuRestDetectorGetRate(&a->rest, rate);
        for (i = 0; i < 3; i++) {
            a->bias[i] += k * (rate[i] - a->bias[i]);
        }
    }
}

/** @brief Process one sample: gyr [rad/s], acc [m/s^2], mag [uT]; dt [s] since the previous. */
void ImuAttitudeUpdate(ImuAttitude *a, const double gyr[3], const double acc[3], const double mag[3],
                       double dt)
{
    double rate[3];
    int i;
    if (a->settings.restGyroThreshold > 0.0 && dt > 0.0 && ImuAllFinite(gyr, 3) && ImuAllFinite(acc, 3)) {
        ImuAttitudeUpdateBias(a, gyr, acc, dt);
    }
    for (i = 0; i < 3; i++) {
        rate[i] = gyr[i] - a->bias[i];
        a->gain[i] = 0.0;
    }
    if (a->settings.mode == IMU_ATTITUDE_QUATERNION) {
        ImuAttitudeUpdateQuaternion(a, rate, acc, mag, dt);
    } else {
        ImuAttitudeUpdateEuler(a, rate, acc, mag, dt);
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

/** @brief Fusion gains [1] of roll, pitch, yaw from the last update. */
void ImuAttitudeGetGains(const ImuAttitude *a, double gains[3])
{
    int i;
    for (i = 0; i < 3; i++) {
        gains[i] = a->gain[i];
    }
}
