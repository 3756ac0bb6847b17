/**
 * @file ImuAttitudeEuler.c
 * @brief Attitude mode IMU_ATTITUDE_EULER: adaptive-gain fusion of two ZYX Euler sets (the method).
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
 * Each addition has a switch, a bit of ImuAttitudeSettings.eulerAdditions (ImuEulerAddition; all on
 * in the FMU, any in the batch entry ImuBatchRunEuler for the ablation): the trapezoidal rule, the floor of R_i, the departure terms of R_i (all three from the
 * first runtime, issue 2's turn) and (a), (b), (c) above. With none the filter is the method as
 * issue 2 describes it: the current rate held over the step, P_i grown by the gyro noise alone,
 * R_i the bare moving mean-square innovation (started at angle_noise^2). The de-tilting with the
 * gyro-predicted roll/pitch and the random walk of steps without a finite rate have no switch.
 */
#include <math.h>
#include "ImuAttitudePrivate.h"
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
/* cos^2 of 80 deg: caps the tan^2(dip) by which a tilt error enters the yaw measurement. */
#define IMU_ATTITUDE_COS2_DIP_MIN 0.0301536896

/** @brief 1 if the Euler addition bit (ImuEulerAddition) is switched on in the settings of a. */
static int ImuAttitudeEulerUses(const ImuAttitude *a, int addition)
{
    return (a->settings.eulerAdditions & addition) != 0;
}

/**
 * @brief Rate [rad/s] held over the step: the trapezoidal mean (IMU_EULER_TRAPEZOID) or the
 *        current rate alone, each falling back on the finite one; 0 if neither rate is finite.
 */
static int ImuAttitudeEulerStepRate(const ImuAttitude *a, const double gyr[3], double rate[3])
{
    int i;
    if (ImuAttitudeEulerUses(a, IMU_EULER_TRAPEZOID) || !ImuAllFinite(gyr, 3)) {
        return ImuAttitudeStepRate(a, gyr, rate);
    }
    for (i = 0; i < 3; i++) {
        rate[i] = gyr[i];
    }
    return 1;
}

/** @brief Gyro Euler set: propagate R with the rate gyr [rad/s] over dt [s] and grow P_i. */
static void ImuAttitudeEulerPredict(ImuAttitude *a, const double gyr[3], double dt)
{
    const ImuAttitudeSettings *s = &a->settings;
    double rate[3], growth, stepError;
    int i;
    if (!(dt > 0.0)) {
        return;
    }
    growth = s->gyroNoise * s->gyroNoise * dt + (s->gyroBiasResidual * dt) * (s->gyroBiasResidual * dt);
    if (ImuAttitudeEulerStepRate(a, gyr, rate)) {
        ImuMatrixPropagate(a->rotation, rate, dt);
        ImuMatrixToEuler(a->rotation, a->euler);
        stepError = ImuAttitudeStepError(a, gyr, dt);
        if (ImuAttitudeEulerUses(a, IMU_EULER_STEP_ERROR)) {
            growth += stepError;
        }
        a->stepError = a->stepError * exp(-dt / s->mseTimeConstant) + stepError;
        if (ImuAttitudeEulerUses(a, IMU_EULER_RESTART) && a->stepError > IMU_ATTITUDE_RESTART_VARIANCE) {
            a->stepError = 0.0; /* restart as at power-on */
            a->tiltInitialised = 0;
            a->yawInitialised = 0;
        }
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
    double k, total;
    a->mse[i] += alpha * (e * e - a->mse[i]);
    if (ImuAttitudeEulerUses(a, IMU_EULER_MSE_FLOOR) && a->mse[i] < floor) {
        a->mse[i] = floor;
    }
    total = a->variance[i] + a->mse[i] + extra;
    k = total > 0.0 ? a->variance[i] / total : 0.0; /* 0 only without the floor and gyro noise */
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
    const double extra = ImuAttitudeEulerUses(a, IMU_EULER_DEPARTURE)
                             ? IMU_ATTITUDE_ACC_DEPARTURE_VARIANCE * departure * departure : 0.0;
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
    const double tiltTerm = ImuAttitudeEulerUses(a, IMU_EULER_YAW_TILT_VARIANCE)
                                ? tiltVariance * sinDip * sinDip / fmax(cosDip * cosDip, IMU_ATTITUDE_COS2_DIP_MIN)
                                : 0.0;
    const double departureTerm = ImuAttitudeEulerUses(a, IMU_EULER_DEPARTURE)
                                     ? IMU_ATTITUDE_MAG_DEPARTURE_VARIANCE * departure * departure : 0.0;
    double level[9], m[3], yaw;
    ImuMatrixFromEuler(tilt[0], tilt[1], 0.0, level); /* Ry(pitch) Rx(roll): body -> level */
    ImuMatrixVector(level, mag, m);
    yaw = atan2(-m[1], m[0]);
    if (!a->yawInitialised) {
        a->euler[2] = yaw;
        a->yawInitialised = 1;
        return;
    }
    ImuAttitudeCorrect(a, 2, yaw, departureTerm + tiltTerm, alpha);
}

/** @brief Euler mode: one sample of corrected gyr [rad/s], acc [m/s^2], mag [uT]; dt [s]. */
void ImuAttitudeEulerUpdate(ImuAttitude *a, const double gyr[3], const double acc[3], const double mag[3],
                            double dt)
{
    const double alpha = dt > 0.0 ? 1.0 - exp(-dt / a->settings.mseTimeConstant) : 0.0;
    int tiltWasInitialised;
    double predictedTilt[2], predictedTiltVariance;
    ImuAttitudeEulerPredict(a, gyr, dt); /* may restart: clears tiltInitialised */
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
