/**
 * @file ImuBiasLearning.h
 * @brief Online learning of the gyro gain/bias(T) model's bias at rests (issue 33 item 3).
 *
 * The gain/bias source fits its coefficients by an adaptive-rate gradient descent and says that the
 * rule can learn online. Here it does, on the one signal whose truth is known in use: at a rest the
 * true rate is zero, so the corrected rate is the error of the bias model. The learnt correction is
 * the bias polynomial's constant and linear coefficients, in the corrected axes (A G of the model is
 * the identity to ~1e-2, so b_k += (A G)^-1 d_k; carried as d_k):
 *     rate -= d0 + d1 Tn                    Tn = (T - t0) / ts of the gyro model, T clamped to its
 *                                           calibrated range (NaN -> Tn = 0)
 * Rests: a rest detector (ImuRestDetector.h) on the corrected rate and specific force, with the
 * rest_gyro_threshold for the samples and that threshold plus the limit L for the low-passed rate
 * (a power-up bias up to L must still count as a rest). Each IMU_BIAS_LEARNING_BLOCK seconds of rest
 * (summed over rests: a hand-held rest of 3 s holds ~1 s past the detector's settling) give one
 * gradient step on the block means:
 *     g_k = mean(rate Tn^k)                 gradient of 1/2 |rate|^2 at the block, k = 0, 1
 *     s_k = s_k * 1.2 if g_k agrees in sign with the previous g_k, * 0.5 if not, in [sMin, 0.5]
 *     d_k = clip(d_k + s_k g_k, -L, L)      L = bias_learning_limit [rad/s]
 * Rests while |dT/dt| > IMU_BIAS_LEARNING_MAX_TEMPERATURE_RATE, or before the rate estimate has
 * IMU_BIAS_LEARNING_RATE_TIME of temperature behind it, do not count (a warm-up bias is no error of B(T));
 * without any temperature input the gate does not apply. sMin = bias_learning_rate [1/s] * block: while the residual is noise its sign alternates and
 * the step stays at sMin (an average over ~1 / bias_learning_rate seconds of rest); a bias change
 * keeps the sign and the step grows to 0.5 within ~25 blocks, then shrinks again once it is learnt.
 */
#ifndef IMU_BIAS_LEARNING_H
#define IMU_BIAS_LEARNING_H

#include "ImuCommon.h"
#include "ImuRestDetector.h"

/** Duration [s] of rest behind one gradient step. */
#define IMU_BIAS_LEARNING_BLOCK 1.0
/** Largest adaptive step [1]: the fraction of a block's mean residual one step may remove. */
#define IMU_BIAS_LEARNING_STEP_MAX 0.5
/** Largest |dT/dt| [degC/s] (5 degC/min) at which a rest teaches: while the temperature changes faster the
 *  gyro carries a warm-up bias the gain/bias(T) model does not describe (the PSO-BP network's dT/dt term). */
#define IMU_BIAS_LEARNING_MAX_TEMPERATURE_RATE (5.0 / 60.0)
/** Time constant [s] of the temperature-rate estimate (the PSO-BP stage's default). */
#define IMU_BIAS_LEARNING_RATE_TIME 10.0

/** Settings (FMU parameters bias_learning, bias_learning_rate, bias_learning_limit, rest_*_threshold). */
typedef struct {
    int enabled;           /* 0 or 1 */
    double rate;           /* 1/s, smallest adaptation rate (> 0) */
    double limit;          /* rad/s, largest |d_k| */
    double gyroThreshold;  /* rad/s, rest detector (0: no rests, no learning) */
    double accThreshold;   /* m/s^2, rest detector */
} ImuBiasLearningSettings;

/** Evolving state (plain struct; part of the FMU state). */
typedef struct {
    double correction[3][2]; /* rad/s: d0, d1 per axis */
    double step[3][2];       /* 1: adaptive step per coefficient */
    double gradient[3][2];   /* rad/s: the previous block's gradient */
    double sum[3][2];        /* rad/s: sums of rate Tn^k over the current block */
    double blockTime;        /* s of rest in the current block */
    double blockSamples;     /* samples in the current block */
    double temperature;      /* degC: the last finite temperature (valid when temperatureSeen) */
    double temperatureRate;  /* degC/s: low-passed backward difference */
    double temperatureTime;  /* s of finite temperature behind the rate (it counts from IMU_BIAS_LEARNING_RATE_TIME) */
    int temperatureSeen;     /* 0 or 1 */
    ImuRestDetector rest;
} ImuBiasLearning;

/** @brief No correction, steps at their smallest, no block, not at rest. */
IMU_HIDDEN void ImuBiasLearningReset(ImuBiasLearning *b, const ImuBiasLearningSettings *s);
/** @brief After a gap: forget the rest and the current block, keep what was learnt. */
IMU_HIDDEN void ImuBiasLearningRestart(ImuBiasLearning *b);
/** @brief 1 if a restored state is usable: finite, |d| <= limit, steps in range, counts >= 0. */
IMU_HIDDEN int ImuBiasLearningStateValid(const ImuBiasLearning *b, const ImuBiasLearningSettings *s);
/** @brief Subtract the learnt correction at normalised temperature tn from rate [rad/s] (no-op when off). */
IMU_HIDDEN void ImuBiasLearningCorrect(const ImuBiasLearning *b, const ImuBiasLearningSettings *s, double tn,
                                       double rate[3]);
/** @brief Learn from one corrected sample rate [rad/s], acc [m/s^2] after dt [s] at temperature [degC]
 *         (NaN: its rate held), tn (no-op when off). */
IMU_HIDDEN void ImuBiasLearningUpdate(ImuBiasLearning *b, const ImuBiasLearningSettings *s, double temperature,
                                      double tn, const double rate[3], const double acc[3], double dt);
/** @brief |d0 + d1 tn| [rad/s]: how far the learnt bias is from the trained one at tn. */
IMU_HIDDEN double ImuBiasLearningShift(const ImuBiasLearning *b, double tn);

#endif
