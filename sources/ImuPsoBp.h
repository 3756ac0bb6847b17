/**
 * @file ImuPsoBp.h
 * @brief PSO-BP gyro bias model b(T, dT/dt): three 2-H-1 tansig networks, one per axis, and the
 *        causal temperature-rate estimator that feeds them.
 *
 * Per axis i (training/models/psobp.py trains it; this file evaluates it in the same operation order):
 *     u0 = 2 (T - tMin) / (tMax - tMin) - 1            min-max normalised temperature
 *     u1 = 2 (r - rMin) / (rMax - rMin) - 1            min-max normalised rate r = dT/dt
 *     h_j = tanh(w1[i][j][0] u0 + w1[i][j][1] u1 + b1[i][j]),  j = 0..H-1
 *     b_i = b2[i] + sum_j w2[i][j] h_j                  [rad/s] (output scale folded in)
 *
 * Calibrated range: T and r are clamped (setting psobp_clamp) to [tMin, tMax] and [rMin, rMax] (the ranges of the training
 * windows) before they are normalised, so the networks are never evaluated outside what they were
 * fitted on; the evaluation reports whether it had to clamp.
 *
 * Rate estimator (first-order low-pass of the backward difference, exact for variable steps):
 *     d = (T_k - T_prev) / (t_k - t_prev),  a = 1 - exp(-(t_k - t_prev) / tau),  r += a (d - r)
 * A NaN temperature (or a non-increasing time) leaves the state unchanged; before the first
 * finite temperature T is the centre of the training range and r = 0.
 *
 * Modes (block entry 0; the network and its inputs are the same in both):
 *     ImuPsoBpModeFull      the paper's model: b is the whole gyro bias; ImuPsoBpCorrect acts on
 *                           the raw gyro (the gyro gain/bias stage must then be off).
 *     ImuPsoBpModeResidual  the hybrid: b is the bias left after the gain/bias polynomial B(T);
 *                           ImuPsoBpCorrect acts on the thermally compensated gyro, i.e. it runs
 *                           after ImuThermal, so the network output adds to the polynomial bias.
 * Per sample: ImuPsoBpUpdate(s, t, T), then ImuPsoBpCorrect(c, s, gyr): two calls.
 *
 * Block layout (IMU_PSOBP_BLOCK doubles, weights zero-padded to IMU_PSOBP_MAX_HIDDEN):
 *     [0] ImuPsoBpMode: 0 off, 1 full, 2 residual (was "enabled 0/1"; 1 keeps its meaning)
 *     [1] H (1..IMU_PSOBP_MAX_HIDDEN)   [2] tau [s] (> 0)
 *     [3] tMin [degC]  [4] tMax [degC]  [5] rMin [degC/s]  [6] rMax [degC/s]   (min < max)
 *     then for axis i = 0, 1, 2 (IMU_PSOBP_AXIS_BLOCK doubles each):
 *         w1[j][0], w1[j][1] for j = 0..MAX-1   (2 MAX, row-major)
 *         b1[j]                                 (MAX)
 *         w2[j]                                 (MAX, rad/s)
 *         b2                                    (1, rad/s)
 */
#ifndef IMU_PSOBP_H
#define IMU_PSOBP_H

#include <stddef.h>
#include "ImuCommon.h"

#define IMU_PSOBP_MAX_HIDDEN 16
#define IMU_PSOBP_HEADER 7
#define IMU_PSOBP_AXIS_BLOCK (4 * IMU_PSOBP_MAX_HIDDEN + 1)
#define IMU_PSOBP_BLOCK (IMU_PSOBP_HEADER + 3 * IMU_PSOBP_AXIS_BLOCK)

/** Block entry 0: what the network output is (see the file comment). */
typedef enum {
    ImuPsoBpModeOff = 0,                           /* the bias is zero */
    ImuPsoBpModeFull = 1,                          /* whole gyro bias, subtract from the raw gyro */
    ImuPsoBpModeResidual = 2                       /* residual after B(T), subtract after ImuThermal */
} ImuPsoBpMode;

/** Trained coefficients (degC, degC/s, rad/s). */
typedef struct {
    ImuPsoBpMode mode;                             /* ImuPsoBpModeOff: the bias is zero */
    int hidden;                                    /* H, 1..IMU_PSOBP_MAX_HIDDEN */
    double tau;                                    /* s, rate low-pass time constant */
    double tMin, tMax;                             /* degC, training temperature range */
    double rMin, rMax;                             /* degC/s, training rate range */
    double w1[3][IMU_PSOBP_MAX_HIDDEN][2];         /* 1, input weights */
    double b1[3][IMU_PSOBP_MAX_HIDDEN];            /* 1, hidden thresholds */
    double w2[3][IMU_PSOBP_MAX_HIDDEN];            /* rad/s, output weights */
    double b2[3];                                  /* rad/s, output thresholds */
} ImuPsoBpCoefficients;

/** Rate-estimator state. */
typedef struct {
    int started;                                   /* 1 after the first finite temperature */
    double tau;                                    /* s, copied from the coefficients */
    double time;                                   /* s, time of the last finite temperature */
    double temperature;                            /* degC, last finite temperature */
    double rate;                                   /* degC/s, filtered temperature rate */
} ImuPsoBpState;

/** @brief Unpack an IMU_PSOBP_BLOCK-long block; 0, or -1 if n is wrong or an entry is invalid. */
IMU_HIDDEN int ImuPsoBpFromBlock(ImuPsoBpCoefficients *c, const double *block, size_t n);
/** @brief Reset the estimator: T = centre of [tMin, tMax] degC, rate 0 degC/s, not started. */
IMU_HIDDEN void ImuPsoBpInitialise(ImuPsoBpState *s, const ImuPsoBpCoefficients *c);
/** @brief 1 if s is a state the stage can reach by clock [s] (a restored FMU state): started 0 or 1,
 *         its time finite, >= 0 and no later than clock; else 0. */
IMU_HIDDEN int ImuPsoBpStateValid(const ImuPsoBpState *s, double clock);
/** @brief Feed one sample: time t [s], temperature [degC] (NaN: state unchanged). */
IMU_HIDDEN void ImuPsoBpUpdate(ImuPsoBpState *s, double t, double temperature);
/** @brief Gyro bias [rad/s] at temperature [degC] and rate [degC/s], both clamped to the training
 *         ranges when clamp is 1 (0: the source's network, evaluated outside them too); zero when
 *         disabled. @return 1 if both were inside their ranges (or the mode is off), else 0. */
IMU_HIDDEN int ImuPsoBpEvaluate(const ImuPsoBpCoefficients *c, double temperature, double rate, int clamp,
                                double bias[3]);
/** @brief Gyro bias [rad/s] at the estimator's current temperature and rate; as ImuPsoBpEvaluate. */
IMU_HIDDEN int ImuPsoBpBias(const ImuPsoBpCoefficients *c, const ImuPsoBpState *s, int clamp, double bias[3]);
/** @brief Subtract the current bias from gyr [rad/s] in place (raw gyro in full mode, thermally
 *         compensated gyro in residual mode); unchanged when the mode is off. Return as ImuPsoBpEvaluate. */
IMU_HIDDEN int ImuPsoBpCorrect(const ImuPsoBpCoefficients *c, const ImuPsoBpState *s, int clamp, double gyr[3]);

#endif
