/**
 * @file ImuTerms.h
 * @brief Additive correction terms found by `imufmu diagnose`: a general way to carry a new effect.
 *
 * Each term subtracts coefficient * clamp(s[a] * s[b], lo, hi) from one compensated sensor
 * component, where s is a fixed vocabulary of per-sample signals (ImuTermSignal): the compensated
 * triads, the temperature and its rate, the time since the first sample, the time derivatives and
 * the absolute values of the triads, the constant 1 and the auxiliary inputs. Signal b may be
 * "none" (-1) for a term linear in s[a]. The bounds [lo, hi] are the regressor range the term was
 * fitted on: the runtime never extrapolates a term beyond them. A regressor that is not finite
 * skips the term. All regressors are computed from the same sample before any correction, so the
 * order of the terms does not matter.
 *
 * Block layout (IMU_TERMS_BLOCK doubles): [count, then IMU_TERMS_MAX x (target, a, b, coefficient,
 * lo, hi)]; target is a component index 0..8 (gyr x y z, acc x y z, mag x y z); entries past count
 * are 0.
 */
#ifndef IMU_TERMS_H
#define IMU_TERMS_H

#include "ImuCommon.h"

#define IMU_TERMS_MAX 64
/** Doubles per term in the block: target, a, b, coefficient, lo, hi. */
#define IMU_TERMS_ENTRY 6
#define IMU_TERMS_BLOCK (1 + IMU_TERMS_ENTRY * IMU_TERMS_MAX)
/** Auxiliary inputs of a sample (ImuLayout.h ImuInAux1.., signals ImuSigAux1..). */
#define IMU_TERMS_AUX_COUNT 4
/** Time constants [s] of the low-passes on the two temperature rate signals: a thermal gradient
 *  inside a package builds up over seconds to a minute, so the data chooses between a slow and a
 *  fast one (a raw difference of a quantised temperature would be noise). */
#define IMU_TERMS_TEMP_RATE_TAU 10.0
#define IMU_TERMS_TEMP_RATE_FAST_TAU 1.0

/** The signal vocabulary (contract/layout.py TERM_SIGNALS has the same names in the same order). */
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
    ImuSigAbsGyrX, ImuSigAbsGyrY, ImuSigAbsGyrZ, /* rad/s, |compensated gyro| */
    ImuSigAbsAccX, ImuSigAbsAccY, ImuSigAbsAccZ, /* m/s^2 */
    ImuSigAbsMagX, ImuSigAbsMagY, ImuSigAbsMagZ, /* uT */
    ImuSigOne,                            /* 1: a term on it alone is an offset */
    ImuSigAux1, ImuSigAux2, ImuSigAux3, ImuSigAux4, /* raw auxiliary inputs, their own units */
    ImuSigTempRateFast,                   /* degC/s, low-passed with IMU_TERMS_TEMP_RATE_FAST_TAU */
    IMU_TERM_SIGNAL_COUNT
} ImuTermSignal;

/** Trained terms. */
typedef struct {
    int count;
    int target[IMU_TERMS_MAX];        /* component 0..8 */
    int a[IMU_TERMS_MAX];             /* signal index */
    int b[IMU_TERMS_MAX];             /* signal index or -1 */
    double coefficient[IMU_TERMS_MAX]; /* target unit / (unit of s[a] * unit of s[b]) */
    double lo[IMU_TERMS_MAX];          /* unit of s[a] * s[b]: the regressor is clamped to [lo, hi] */
    double hi[IMU_TERMS_MAX];
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
    double tempRate;      /* degC/s, low-passed (IMU_TERMS_TEMP_RATE_TAU) */
    double tempRateFast;  /* degC/s, low-passed (IMU_TERMS_TEMP_RATE_FAST_TAU) */
} ImuTermsState;

/** @brief Unpack a terms block; 0, or -1 on a bad count or index, a non-finite coefficient or bound, or lo > hi. */
IMU_HIDDEN int ImuTermsFromBlock(ImuTermsCoefficients *c, const double *block);
/** @brief Forget the previous sample. */
IMU_HIDDEN void ImuTermsReset(ImuTermsState *s);
/** @brief 1 if s is a state the terms can reach by clock [s] (the pipeline's time of the last sample;
 *         a restored FMU state): started 0 or 1, its times finite, >= 0 and no later than clock, the
 *         first no later than the last, the last equal to clock once started (every sample passes
 *         its time); else 0. */
IMU_HIDDEN int ImuTermsStateValid(const ImuTermsState *s, double clock);
/**
 * @brief Signals of one sample at time t [s] from the compensated components x[9], the
 *        temperature [degC] and the auxiliary inputs aux (their own units); advances the state.
 *        Non-computable signals are NaN.
 */
IMU_HIDDEN void ImuTermsSignals(ImuTermsState *s, double t, const double x[9], double temperature,
                                const double aux[IMU_TERMS_AUX_COUNT], double signals[IMU_TERM_SIGNAL_COUNT]);
/** @brief 1 if a term of c has `signal` (an ImuTermSignal) as a factor of its regressor, else 0. */
IMU_HIDDEN int ImuTermsUseSignal(const ImuTermsCoefficients *c, int signal);
/** @brief Subtract every term from x[9] in place: coefficient times the regressor clamped to
 *         [lo, hi]; a term whose regressor is not finite is skipped.
 *  @return 1 if every finite regressor was inside its [lo, hi], 0 if one was clamped. */
IMU_HIDDEN int ImuTermsApply(const ImuTermsCoefficients *c, const double signals[IMU_TERM_SIGNAL_COUNT],
                              double x[9]);

#endif
