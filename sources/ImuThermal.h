/**
 * @file ImuThermal.h
 * @brief Gain/bias temperature model of one sensor triad: x_c = A (G(Tn) .* (x - B(Tn))).
 *
 * Tn = (T - t0) / ts (0 if T is NaN), G_i = 1 + sum_{k=1..P} g[i][k-1] Tn^k,
 * B_i = sum_{k=0..P} b[i][k] Tn^k, A constant symmetric 3x3. Block layout: ImuLayout.h.
 *
 * Calibrated range (layout version 4): when the block carries the temperature range [tMin, tMax]
 * [degC] the model was fitted on, G and B are never evaluated as polynomials outside it (a polynomial
 * fitted on 13-48 degC evaluated at -30 degC is arbitrary): beyond an edge they continue along their
 * tangent at that edge, for at most one span (tMax - tMin), then hold (setting thermal_continuation 1,
 * the default), or hold their edge value (0); ImuThermalApply reports the excursion either way.
 */
#ifndef IMU_THERMAL_H
#define IMU_THERMAL_H

#include "ImuCommon.h"
#include "ImuLayout.h"

/** Trained coefficients of one triad (units of the triad: rad/s, m/s^2 or uT; degC). */
typedef struct {
    int enabled;                                    /* 0: the triad passes through unchanged */
    double t0;                                      /* degC, reference temperature */
    double ts;                                      /* degC, temperature scale (> 0) */
    int degree;                                     /* P, 0..IMU_THERMAL_MAX_DEGREE */
    double A[3][3];                                 /* 1, constant misalignment/scale matrix */
    double g[3][IMU_THERMAL_MAX_DEGREE];            /* 1, gain polynomial, g[axis][k-1] */
    double b[3][IMU_THERMAL_MAX_DEGREE + 1];        /* triad unit, bias polynomial, b[axis][k] */
    int hasRange;                                   /* 1: clamp T to [tMin, tMax]; 0: no range known */
    double tMin, tMax;                              /* degC, temperature range of the calibration data */
} ImuThermalCoefficients;

/**
 * @brief Unpack one IMU_THERMAL_BLOCK-long block (enabled, t0 [degC], ts [degC], degree, A, g, b,
 *        hasRange, tMin [degC], tMax [degC]).
 * @return 0, or -1 if enabled or hasRange is not 0/1, an entry is not finite, (when enabled) the
 *         degree is not an integer in 0..IMU_THERMAL_MAX_DEGREE or ts <= 0, or (with a range)
 *         tMin > tMax.
 */
IMU_HIDDEN int ImuThermalFromBlock(ImuThermalCoefficients *c, const double *block);
/** @brief Tn = (T - t0) / ts [1] with T clamped to the calibrated range (NaN -> 0). */
IMU_HIDDEN double ImuThermalNormalisedTemperature(const ImuThermalCoefficients *c, double temperature);
/**
 * @brief Compensate one sample x (triad unit) at temperature [degC] (NaN -> Tn = 0) into out; outside
 *        the calibrated range the polynomials continue along their edge tangent (continuation 1, at
 *        most one span beyond the edge) or hold their edge value (continuation 0).
 * @return 1 if the model's input is inside its calibrated range (or the model does not depend on
 *         the temperature: disabled, degree 0, no range known, NaN temperature), 0 if it was outside.
 */
IMU_HIDDEN int ImuThermalApply(const ImuThermalCoefficients *c, const double x[3], double temperature,
                                int continuation, double out[3]);

#endif
