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
 *    untracked motion instead of propagating) + the integration-error bound of the step
 *    (ImuAttitudeStepError: a rate jump |dw| may lie anywhere within the step, |dw| dt / 2; a
 *    step that lost samples adds the untracked motion over the missing time, 1 rad/s x time).
 * 2. Acc/mag set: roll = atan2(-f_y, -f_z), pitch = atan2(f_x, |f_yz|); yaw = atan2(-m_y', m_x')
 *    of the field m' de-tilted into the level frame.
 * 3. Per angle: innovation e_i = wrap(acc/mag angle - gyro angle); R_i = moving mean of e_i^2
 *    (time constant mse_time_constant) floored by angle_noise^2, plus a term for the current
 *    departure of |f| from g (or |m| from field_norm) and, for yaw, tan^2(dip) times the variance
 *    of the tilt it was de-tilted with; K_i = P_i / (P_i + R_i); fused angle =
 *    wrap(gyro angle + K_i e_i); P_i <- (1 - K_i) P_i. R is rebuilt from the fused angles.
 * Roll/pitch are set directly from the first finite accelerometer sample and yaw from the first
 * finite magnetometer sample (P_i = angle_noise^2 from the start).
 *
 * Changes from the published adaptive-gain method (issue 15), so that a transient is recovered
 * from within seconds. In the method P grows only by the gyro noise while R tracks the mean
 * innovation^2, so after one glitch of the gyro set (a rate spike, samples lost, a clock jump) its
 * own error enters R as if it were acc/mag noise: the gain falls to ~1e-4 and the error stays for
 * minutes (eval_handheld: 19 deg after one 2000 deg/s sample, 100 deg after five, still 11 deg /
 * 93 deg three minutes later). Here (a) P also grows by the step's integration-error bound above,
 * so the filter knows when its gyro set may be wrong before that error reaches R (zero for smooth
 * motion up to the rate changes the gyro actually measured, which also makes the clean run
 * slightly more accurate: eval_handheld 1.25 -> 1.05 deg); (b) the yaw measurement carries the
 * variance of the tilt it is de-tilted with, so a wrong tilt does not pull yaw; (c) when the
 * summed bounds of the recent steps (decaying with mse_time_constant) exceed
 * IMU_ATTITUDE_RESTART_VARIANCE, the angles restart from the acc/mag set as at power-on (the
 * gyro set may then be off by more than the correction removes in the averaging time). Recovery:
 * within 10 s after the glitch the error is back within 2x the clean run's (tests/test_attitude_recovery.py).
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
 * 4. Restart (issue 15): when the summed integration-error bounds of the recent steps
 *    (ImuAttitudeStepError, decaying with tau_acc) exceed IMU_ATTITUDE_RESTART_VARIANCE (a rate
 *    spike, lost samples, a clock jump), the strapdown frame may have turned by more than 10 deg
 *    and the corrections restart as at power-on: the low-passed f from the current sample, the
 *    heading averaging 1/n again, no field rejected. Without it the heading recovered only with
 *    tau_mag (five 2000 deg/s samples: still 14 deg after 10-20 s).
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
 * order of the possible rotation and the next acc/mag fix is trusted accordingly. The same number
 * as a rate [rad/s] bounds the rotation over the time of lost samples (ImuAttitudeStepError).
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
/* A step longer than this many previous steps has missed samples (a dropped sample doubles the
 * step; clock jitter of recordings stays far below it). */
#define IMU_ATTITUDE_MISSING_STEPS 1.5
/* Angular acceleration [rad/s^2] that smooth motion reaches: a rate change up to this times the
 * step is motion the trapezoidal rule integrates well, not a glitch. BROAD's 20 trials (286 Hz,
 * hand-held, fast rotations and translations) reach 736 rad/s^2 at most outside tapping (1369);
 * a 34.9 rad/s one-sample spike at 100 Hz is 3490 rad/s^2. Counting every rate change instead
 * raised the Euler fusion's gain during fast motion (BROAD, Euler + rest bias: 4.82 -> 11.39 deg). */
#define IMU_ATTITUDE_SMOOTH_ANGULAR_ACCEL 1000.0
/* Both modes: restart the corrections once the recent steps may have turned the gyro set or the
 * strapdown frame by more than 10 deg (variance (10 deg)^2): more than a few time constants of the
 * correction take to remove, while a single dropped sample at 100 Hz (1e-4 rad^2) stays far below. */
#define IMU_ATTITUDE_RESTART_VARIANCE 0.0304617420
/* cos^2 of 80 deg: caps the tan^2(dip) by which a tilt error enters the yaw measurement. */
#define IMU_ATTITUDE_COS2_DIP_MIN 0.0301536896

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
    a->previousStep = 0.0;
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
    a->magRejected = 0.0;
    a->magSamples = 0.0;
    a->stepError = 0.0;
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

/**
 * @brief Mean-square angle error [rad^2] of integrating one step with the trapezoidal rule beyond
 *        the white noise: the rate change within the step and the samples missing from it.
 *
 * The trapezoidal rule assumes the rate varies linearly between two samples. A rate that changed
 * by dw beyond what smooth motion does in a step (IMU_ATTITUDE_SMOOTH_ANGULAR_ACCEL dt) may have
 * changed anywhere within the step, an angle error of up to that excess times dt / 2 (a 35 rad/s
 * spike at 100 Hz: 0.12 rad; hand-held motion: 0). A step longer than IMU_ATTITUDE_MISSING_STEPS previous steps has lost samples: the
 * motion over the excess time x was not measured; handheld motion turns by about
 * IMU_ATTITUDE_UNTRACKED_MOTION rad/s, an error of up to that rate times x (a dropped sample at
 * 100 Hz: 0.01 rad; 1 s lost: 1 rad).
 */
static double ImuAttitudeStepError(const ImuAttitude *a, const double gyr[3], double dt)
{
    double variance = 0.0, change;
    int i;
    if (ImuAllFinite(a->previousRate, 3) && ImuAllFinite(gyr, 3)) {
        for (i = 0; i < 3; i++) {
            change = 0.5 * fmax(fabs(gyr[i] - a->previousRate[i]) - IMU_ATTITUDE_SMOOTH_ANGULAR_ACCEL * dt, 0.0) * dt;
            variance += change * change;
        }
    }
    if (a->previousStep > 0.0 && dt > IMU_ATTITUDE_MISSING_STEPS * a->previousStep) {
        change = IMU_ATTITUDE_UNTRACKED_MOTION * (dt - a->previousStep);
        variance += change * change;
    }
    return variance;
}

/** @brief Gyro Euler set: propagate R with the rate gyr [rad/s] over dt [s] and grow P_i. */
static void ImuAttitudePredict(ImuAttitude *a, const double gyr[3], double dt)
{
    const ImuAttitudeSettings *s = &a->settings;
    double rate[3], growth, stepError;
    int i;
    if (!(dt > 0.0)) {
        return;
    }
    growth = s->gyroNoise * s->gyroNoise * dt + (s->gyroBiasResidual * dt) * (s->gyroBiasResidual * dt);
    if (ImuAttitudeStepRate(a, gyr, rate)) {
        ImuMatrixPropagate(a->rotation, rate, dt);
        ImuMatrixToEuler(a->rotation, a->euler);
        stepError = ImuAttitudeStepError(a, gyr, dt);
        growth += stepError;
        a->stepError = a->stepError * exp(-dt / s->mseTimeConstant) + stepError;
        if (a->stepError > IMU_ATTITUDE_RESTART_VARIANCE) { /* restart as at power-on */
            a->stepError = 0.0;
            a->tiltInitialised = 0;
            a->yawInitialised = 0;
        }
    } else {
        growth += IMU_ATTITUDE_UNTRACKED_MOTION * IMU_ATTITUDE_UNTRACKED_MOTION * dt;
    }
    a->previousStep = dt;
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
static void ImuAttitudeCorrectYaw(ImuAttitude *a, const double mag[3], const double tilt[2], double tiltVariance,
                                  double alpha)
{
    const double fieldNorm = a->settings.fieldNorm;
    const double departure = (ImuVectorNorm(mag) - fieldNorm) / fieldNorm;
    const double sinDip = sin(a->settings.fieldDip), cosDip = cos(a->settings.fieldDip);
    /* A tilt error d turns the de-tilted horizontal field by up to d tan(dip): the yaw measurement
     * inherits the variance of the tilt it was de-tilted with (tan^2 capped at dip 80 deg). */
    const double tiltTerm = tiltVariance * sinDip * sinDip / fmax(cosDip * cosDip, IMU_ATTITUDE_COS2_DIP_MIN);
    double level[9], m[3], yaw;
    ImuMatrixFromEuler(tilt[0], tilt[1], 0.0, level); /* Ry(pitch) Rx(roll): body -> level */
    ImuMatrixVector(level, mag, m);
    yaw = atan2(-m[1], m[0]);
    if (!a->yawInitialised) {
        a->euler[2] = yaw;
        a->yawInitialised = 1;
        return;
    }
    ImuAttitudeCorrect(a, 2, yaw, IMU_ATTITUDE_MAG_DEPARTURE_VARIANCE * departure * departure + tiltTerm, alpha);
}

/** @brief Euler mode: one sample of corrected gyr [rad/s], acc [m/s^2], mag [uT]; dt [s]. */
static void ImuAttitudeUpdateEuler(ImuAttitude *a, const double gyr[3], const double acc[3], const double mag[3],
                                   double dt)
{
    const double alpha = dt > 0.0 ? 1.0 - exp(-dt / a->settings.mseTimeConstant) : 0.0;
    int tiltWasInitialised;
    double predictedTilt[2], predictedTiltVariance;
    ImuAttitudePredict(a, gyr, dt); /* may restart: clears tiltInitialised */
    tiltWasInitialised = a->tiltInitialised;
    predictedTilt[0] = a->euler[0];
    predictedTilt[1] = a->euler[1];
    predictedTiltVariance = a->variance[0] + a->variance[1];
    if (ImuAllFinite(acc, 3)) {
        ImuAttitudeCorrectTilt(a, acc, alpha);
    }
    if (ImuAllFinite(mag, 3)) {
        /* De-tilt with the gyro-predicted roll/pitch: unlike the accelerometer angles they are
         * not disturbed by linear acceleration. Before the first tilt fix, use the fresh one. */
        ImuAttitudeCorrectYaw(a, mag, tiltWasInitialised ? predictedTilt : a->euler, predictedTiltVariance, alpha);
    }
    ImuMatrixFromEuler(a->euler[0], a->euler[1], a->euler[2], a->rotation);
}

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
    a->previousStep = dt;
    if (a->stepError > IMU_ATTITUDE_RESTART_VARIANCE) {
        a->stepError = 0.0;
        a->tiltInitialised = 0;
        a->magSamples = 0.0;
        a->magRejected = 0.0;
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
