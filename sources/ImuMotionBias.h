/**
 * @file ImuMotionBias.h
 * @brief The gyro bias during motion, from the quaternion filter's inclination correction (the
 *        motion bias estimation of VQF: Laidig & Seel, Information Fusion 91, 2023).
 *
 * A bias b left in the rate turns the strapdown frame by R b per second (R: body -> level frame);
 * the inclination correction undoes it, so its rate c about the level frame's x and y axes,
 * seen through the same low-pass as the specific force, measures the bias: -c + LP(R b_hat)
 * = LP(R) b. A Kalman filter on b takes that measurement with variance W for x and y and a far
 * larger one for the vertical row (nothing measures a vertical bias there: the row only keeps it from
 * wandering), and its covariance P grows by V per second towards IMU_MOTION_BIAS_SIGMA_INIT^2.
 * W = p^2 / V + p makes p = IMU_MOTION_BIAS_SIGMA_MOTION^2 the covariance P settles at under a steady
 * stream of measurements (VQF's parametrisation, its default constants).
 *
 * A linear acceleration the low-pass has not averaged out leaves the low-passed specific force off g
 * by delta and may tilt it by up to about delta / g, which the correction removes over tau_acc: a
 * rate error of up to delta / (g tau_acc) in the measurement. W grows by the factor 1 + (that rate
 * error / IMU_MOTION_BIAS_SIGMA_MOTION)^2, so a measurement is trusted less once the error it may
 * carry reaches the accuracy the estimate aims at. (Simulated hand-held motion without a
 * magnetometer, 60 s: gyro-only yaw drift 6.0 deg without this, 3.6 deg with it, 2.7 deg without the
 * estimate in motion.) delta counts only beyond acc_norm_tolerance g (ImuAttitudeQuaternion.c): the
 * part of the departure the still accelerometer shows too is its own scale error, and an uncalibrated
 * MEMS accelerometer is off by up to about 1 % in every pose (BROAD: 0.1-1.0 % at rest), which would
 * otherwise be taken for linear acceleration all the time (BROAD trained on 01 + 02 without a
 * reference: inclination lower than VQF's on 14 of 20 trials with delta from 0, 16 beyond the
 * tolerance `train` writes; docs/BENCHMARKS.md).
 *
 * One deliberate departure from VQF: rest does not shrink P. At rest the rest detector measures the
 * bias itself (ImuAttitude.c); in motion the rate also carries what the calibration left of the
 * gyro's motion-dependent errors (scale factor, cross-axis, g-sensitivity), which rest cannot see,
 * so the motion estimate keeps its own uncertainty. BROAD, 20 trials, identity calibration, VQF's
 * full Kalman (rest shrinking P): inclination 0.716 deg; this form 0.695 deg; without motion
 * estimation 0.719 deg (docs/BENCHMARKS.md).
 */
#ifndef IMU_MOTION_BIAS_H
#define IMU_MOTION_BIAS_H

#include "ImuCommon.h"
#include "ImuLowPass.h"

/** Evolving state (plain struct: copy = save state). */
typedef struct {
    double covariance[9];       /* (rad/s)^2, P of the bias estimate, row-major */
    ImuLowPass rotation[3];     /* 1, the rows of R (body -> level frame), low-passed with tau_acc */
    ImuLowPass rotatedBias;     /* rad/s, R b_hat low-passed with tau_acc (x and y are used) */
} ImuMotionBias;

/** @brief Forget everything: P = IMU_MOTION_BIAS_SIGMA_INIT^2 I, the low-passes restart. */
IMU_HIDDEN void ImuMotionBiasReset(ImuMotionBias *m);
/** @brief The low-passes restart with the next step (with the inclination correction's low-pass); P is kept. */
IMU_HIDDEN void ImuMotionBiasRestart(ImuMotionBias *m);
/** @brief 1 if every low-pass of m is a reachable state (ImuLowPassStateValid) and P is finite, else 0. */
IMU_HIDDEN int ImuMotionBiasStateValid(const ImuMotionBias *m);
/**
 * @brief One step dt [s] (> 0) after the inclination correction: q6d [w, x, y, z] body -> level
 *        frame after the correction, up [1] the unit low-passed specific force in the level frame
 *        before it (the correction turned it onto (0, 0, -1)), design the specific force's low-pass
 *        coefficients of this step (ImuLowPassDesignStep with tau_acc and dt), rateError [rad/s] the
 *        inclination-rate error an unaveraged linear acceleration may cause (| |f_lp| - g | / (g tau_acc)).
 *        With observe set (in motion, after the correction's first step) the measurement updates
 *        bias [rad/s]; otherwise only the low-passes and P advance.
 */
IMU_HIDDEN void ImuMotionBiasUpdate(ImuMotionBias *m, const double q6d[4], const double up[3], double rateError,
                                    const ImuLowPassDesign *design, double dt, int observe, double bias[3]);

#endif
