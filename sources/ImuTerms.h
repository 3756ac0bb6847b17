/**
 * @file ImuTerms.h
 * @brief Additive correction terms found by `imufmu diagnose`: a general way to carry a new effect.
 *
 * Each term subtracts coefficient * s[a] * s[b] from one compensated sensor component, where s is a
 * fixed vocabulary of per-sample signals (ImuTermSignal): the compensated triads, the temperature
 * and its rate, the time since the first sample, and the time derivatives of the triads. Signal b
 * may be "none" (-1) for a term linear in s[a]. All regressors are computed from the same sample
 * before any correction, so the order of the terms does not matter.
 *
 * Block layout (IMU_TERMS_BLOCK doubles): [count, then IMU_TERMS_MAX x (target, a, b, coefficient)];
 * target is a component index 0..8 (gyr x y z, acc x y z, mag x y z); entries past count are 0.
 */
#ifndef IMU_TERMS_H
#define IMU_TERMS_H

#include "ImuCommon.h"

#define IMU_TERMS_MAX 16
#define IMU_TERMS_BLOCK (1 + 4 * IMU_TERMS_MAX)
/** Time constant [s] of the low-pass on the temperature rate signal. */
#define IMU_TERMS_TEMP_RATE_TAU 10.0

/** The signal vocabulary (training/layout.py TERM_SIGNALS has the same names in the same order). */
typedef enum {
    ImuSigGyrX, ImuSigGyrY, ImuSigGyrZ,   /* rad/s */
    ImuSigAccX, ImuSigAccY, ImuSigAccZ,   /* m/s^2 */
    ImuSigMagX, ImuSigMagY, ImuSigMagZ,   /* uT */
    ImuSigTemp,                           /* degC */
    ImuSigTempRate,                       /* degC/s, low-passed */
    ImuSigTime,                           /* s since the first sample */
    ImuSigDGyrX, ImuSigDGyrY, ImuSigDGyrZ, /* rad/s^2 */
    ImuSigDAccX, ImuSigDAccY, ImuSigDAccZ, /* m/s^3 */
    ImuSigDMagX, ImuSigDMagY, ImuSigDMagZ, /* uT/s */
    IMU_TERM_SIGNAL_COUNT
} ImuTermSignal;

/** Trained terms. */
typedef struct {
    int count;
    int target[IMU_TERMS_MAX];        /* component 0..8 */
    int a[IMU_TERMS_MAX];             /* signal index */
    int b[IMU_TERMS_MAX];             /* signal index or -1 */
    double coefficient[IMU_TERMS_MAX]; /* target unit / (unit of s[a] * unit of s[b]) */
} ImuTermsCoefficients;

/** What the signals need from the previous sample. */
typedef struct {
    int started;          /* 0 before the first sample */
    double firstTime;     /* s */
    double lastTime;      /* s */
    double last[9];       /* previous compensated components (may be NaN) */
    double derivative[9]; /* last finite backward difference per component */
    double lastTemp;      /* degC, last finite temperature (NaN before one) */
    double lastTempTime;  /* s */
    double tempRate;      /* degC/s, low-passed */
} ImuTermsState;

/** @brief Unpack a terms block; 0, or -1 on a bad count, index or non-finite coefficient. */
IMU_HIDDEN int ImuTermsFromBlock(ImuTermsCoefficients *c, const double *block);
/** @brief Forget the previous sample. */
IMU_HIDDEN void ImuTermsReset(ImuTermsState *s);
/**
 * @brief Signals of one sample at time t [s] from the compensated components x[9] and the
 *        temperature [degC]; advances the state. Non-computable signals are NaN.
 */
IMU_HIDDEN void ImuTermsSignals(ImuTermsState *s, double t, const double x[9], double temperature,
                                double signals[IMU_TERM_SIGNAL_COUNT]);
/** @brief Subtract every term from x[9] in place; a term whose regressor is not finite is skipped. */
IMU_HIDDEN void ImuTermsApply(const ImuTermsCoefficients *c, const double signals[IMU_TERM_SIGNAL_COUNT],
                              double x[9]);

#endif
