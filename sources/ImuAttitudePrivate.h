/**
 * @file ImuAttitudePrivate.h
 * @brief What the attitude facade (ImuAttitude.c) and its two filters share: the mode entry
 *        points (ImuAttitudeEuler.c, ImuAttitudeQuaternion.c) and the step helpers both filters
 *        use (ImuAttitudeStep.c). Not part of the pipeline's interface (ImuAttitude.h).
 */
#ifndef IMU_ATTITUDE_PRIVATE_H
#define IMU_ATTITUDE_PRIVATE_H

#include "ImuAttitude.h"

/*
 * Angle random walk [rad/sqrt(s)] of motion that no gyro sample tracked (both rates of a step
 * non-finite): handheld motion turns by about 1 rad within 1 s, so after such a gap P_i is of the
 * order of the possible rotation and the next acc/mag fix is trusted accordingly. The same number
 * as a rate [rad/s] bounds the rotation over the time of lost samples (ImuAttitudeStepError).
 */
#define IMU_ATTITUDE_UNTRACKED_MOTION 1.0
/* Both modes: restart the corrections once the recent steps may have turned the gyro set or the
 * strapdown frame by more than 10 deg (variance (10 deg)^2): more than a few time constants of the
 * correction take to remove, while a single dropped sample at 100 Hz (1e-4 rad^2) stays far below. */
#define IMU_ATTITUDE_RESTART_VARIANCE 0.0304617420
/* Quaternion mode: */
/* Time [s] a field must stay within the tolerances before it is trusted again (VQF's
 * magMinUndisturbedTime): where a disturbance fades, the field crosses back into tolerance while
 * still bent, and the samples at the edge would otherwise pull the heading. A field never rejected
 * (power-on, restart) counts as clean. BROAD, 20 trials,
 * identity calibration: undisturbed 1.754 -> 1.616 deg, disturbed 2.452 -> 1.910 deg. */
#define IMU_ATTITUDE_MAG_MIN_CLEAN_TIME 0.5

/** @brief Rate [rad/s] held over the step: the current corrected rate (gyro_hold) or the trapezoidal
 *         mean of the previous and current ones, or the one that is finite; 0 if neither is (no propagation). */
IMU_HIDDEN int ImuAttitudeStepRate(const ImuAttitude *a, const double gyr[3], double rate[3]);
/** @brief Mean-square angle error [rad^2] of integrating one step of dt [s] with the trapezoidal
 *         rule beyond the white noise: the rate change within the step, the samples missing from it. */
IMU_HIDDEN double ImuAttitudeStepError(const ImuAttitude *a, const double gyr[3], double dt);
/** @brief Euler mode: one sample of bias-corrected gyr [rad/s], acc [m/s^2], mag [uT]; dt [s]. */
IMU_HIDDEN void ImuAttitudeEulerUpdate(ImuAttitude *a, const double gyr[3], const double acc[3],
                                       const double mag[3], double dt);
/** @brief Quaternion mode: one sample of bias-corrected gyr [rad/s], acc [m/s^2], mag [uT]; dt [s]. */
IMU_HIDDEN void ImuAttitudeQuaternionUpdate(ImuAttitude *a, const double gyr[3], const double acc[3],
                                            const double mag[3], double dt);

#endif
