/**
 * @file ImuAttitudeStep.c
 * @brief The integration step both attitude filters share: the rate held over a step and the
 *        error bound of integrating it (the restart test of issue 15).
 */
#include <math.h>
#include "ImuAttitudePrivate.h"
#include "ImuMath.h"

/* A step longer than this many nominal steps (ImuGuardNominalStep, the median of the recent steps:
 * one short step is not the reference) has missed samples (a dropped sample doubles the step; clock
 * jitter of recordings stays far below it). */
#define IMU_ATTITUDE_MISSING_STEPS 1.5
/* Angular acceleration [rad/s^2] that smooth motion reaches: a rate change up to this times the
 * step is motion the trapezoidal rule integrates well, not a glitch. BROAD's 20 trials (286 Hz,
 * hand-held, fast rotations and translations) reach 736 rad/s^2 at most outside tapping (1369);
 * a 34.9 rad/s one-sample spike at 100 Hz is 3490 rad/s^2. Counting every rate change instead
 * raised the Euler fusion's gain during fast motion (BROAD, Euler + rest bias: 4.82 -> 11.39 deg). */
#define IMU_ATTITUDE_SMOOTH_ANGULAR_ACCEL 1000.0

/**
 * @brief Rate [rad/s] held over the step: the current corrected rate when gyro_hold is set (the
 *        sample averages the rate over the interval before it), else the mean of the previous and
 *        current rates (trapezoidal rule); the one that is finite when only one is; 0 if neither is.
 */
int ImuAttitudeStepRate(const ImuAttitude *a, const double gyr[3], double rate[3])
{
    const int previous = ImuAllFinite(a->previousRate, 3), current = ImuAllFinite(gyr, 3);
    int i;
    for (i = 0; i < 3; i++) {
        if (previous && current && !a->settings.gyroHold) {
            rate[i] = 0.5 * (a->previousRate[i] + gyr[i]);
        } else {
            rate[i] = current ? gyr[i] : a->previousRate[i];
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
 * spike at 100 Hz: 0.12 rad; hand-held motion: 0). A step longer than IMU_ATTITUDE_MISSING_STEPS nominal steps has lost samples: the
 * motion over the excess time x was not measured; handheld motion turns by about
 * IMU_ATTITUDE_UNTRACKED_MOTION rad/s, an error of up to that rate times x (a dropped sample at
 * 100 Hz: 0.01 rad; 1 s lost: 1 rad).
 */
double ImuAttitudeStepError(const ImuAttitude *a, const double gyr[3], double dt)
{
    double variance = 0.0, change;
    int i;
    if (ImuAllFinite(a->previousRate, 3) && ImuAllFinite(gyr, 3)) {
        for (i = 0; i < 3; i++) {
            change = 0.5 * fmax(fabs(gyr[i] - a->previousRate[i]) - IMU_ATTITUDE_SMOOTH_ANGULAR_ACCEL * dt, 0.0) * dt;
            variance += change * change;
        }
    }
    if (a->nominalStep > 0.0 && dt > IMU_ATTITUDE_MISSING_STEPS * a->nominalStep) {
        change = IMU_ATTITUDE_UNTRACKED_MOTION * (dt - a->nominalStep);
        variance += change * change;
    }
    return variance;
}
