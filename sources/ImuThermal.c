/**
 * @file ImuThermal.c
 * @brief Gain/bias temperature model of one sensor triad.
 */
#include <math.h>
#include "ImuThermal.h"
#include "ImuMath.h"

/** Index of hasRange in the block (tMin, tMax follow): after enabled, t0, ts, degree, A, g, b. */
#define IMU_THERMAL_RANGE_INDEX (13 + 3 * IMU_THERMAL_MAX_DEGREE + 3 * (IMU_THERMAL_MAX_DEGREE + 1))
typedef char ImuThermalCheckBlock[(IMU_THERMAL_RANGE_INDEX + 3 == IMU_THERMAL_BLOCK) ? 1 : -1];

/** @brief Check the block header: enabled 0/1; if enabled, integer degree in range and ts > 0;
 *         hasRange 0/1 and, with a range, tMin <= tMax [degC]. */
static int ImuThermalCheckHeader(const double *block)
{
    const double enabled = block[0], ts = block[2], degree = block[3];
    const double *range = block + IMU_THERMAL_RANGE_INDEX;
    if ((enabled != 0.0 && enabled != 1.0) || (range[0] != 0.0 && range[0] != 1.0)
        || (range[0] == 1.0 && !(range[1] <= range[2]))) {
        return -1;
    }
    if (enabled == 1.0 && (!(ts > 0.0) || !(degree >= 0.0) || degree > IMU_THERMAL_MAX_DEGREE ||
                           degree != floor(degree))) {
        return -1;
    }
    return 0;
}

/** @brief Unpack one block (enabled, t0 [degC], ts [degC], degree, A, g, b); 0 or -1 if invalid. */
int ImuThermalFromBlock(ImuThermalCoefficients *c, const double *block)
{
    const double *g = block + 13;
    const double *b = g + 3 * IMU_THERMAL_MAX_DEGREE;
    int i, k;
    if (!ImuAllFinite(block, IMU_THERMAL_BLOCK) || ImuThermalCheckHeader(block) != 0) {
        return -1;
    }
    c->enabled = (int)block[0];
    c->t0 = block[1];
    c->ts = block[2];
    c->degree = (int)block[3];
    c->hasRange = (int)block[IMU_THERMAL_RANGE_INDEX];
    c->tMin = block[IMU_THERMAL_RANGE_INDEX + 1];
    c->tMax = block[IMU_THERMAL_RANGE_INDEX + 2];
    for (i = 0; i < 3; i++) {
        for (k = 0; k < 3; k++) {
            c->A[i][k] = block[4 + 3 * i + k];
        }
        for (k = 0; k < IMU_THERMAL_MAX_DEGREE; k++) {
            c->g[i][k] = g[IMU_THERMAL_MAX_DEGREE * i + k];
        }
        for (k = 0; k <= IMU_THERMAL_MAX_DEGREE; k++) {
            c->b[i][k] = b[(IMU_THERMAL_MAX_DEGREE + 1) * i + k];
        }
    }
    return 0;
}

/** Largest continuation beyond the calibrated range, in calibrated spans (tMax - tMin): the tangent
 *  at the edge is followed for at most one span, then held (docs/fmu.md, "Calibrated range"). */
#define IMU_THERMAL_CONTINUATION_SPANS 1.0

/** @brief temperature [degC] clamped to the calibrated range when the model has one and uses it. */
static double ImuThermalClampTemperature(const ImuThermalCoefficients *c, double temperature)
{
    if (!c->hasRange || c->degree == 0 || isnan(temperature)) {
        return temperature;
    }
    return temperature < c->tMin ? c->tMin : (temperature > c->tMax ? c->tMax : temperature);
}

double ImuThermalNormalisedTemperature(const ImuThermalCoefficients *c, double temperature)
{
    const double clamped = ImuThermalClampTemperature(c, temperature);
    return isnan(clamped) ? 0.0 : (clamped - c->t0) / c->ts;
}

/** @brief Normalised distance [1] the model continues beyond its range edge at temperature [degC]:
 *         (T - edge) / ts, at most IMU_THERMAL_CONTINUATION_SPANS spans; 0 inside, for NaN or when clamping. */
static double ImuThermalContinuation(const ImuThermalCoefficients *c, double temperature, double edge,
                                     int continuation)
{
    const double limit = IMU_THERMAL_CONTINUATION_SPANS * (c->tMax - c->tMin);
    double beyond = temperature - edge;
    if (!continuation || isnan(temperature) || edge == temperature) {
        return 0.0;
    }
    beyond = beyond < -limit ? -limit : (beyond > limit ? limit : beyond);
    return beyond / c->ts;
}

/** @brief Value and slope (d/dTn) at tn of the polynomial sum_{k=0..degree} coef[k] tn^k, Horner's
 *         scheme from k = degree down, the slope by the same recursion. */
static double ImuThermalPolynomial(const double *coef, int degree, double tn, double *slope)
{
    double value = coef[degree], derivative = 0.0;
    int k;
    for (k = degree - 1; k >= 0; k--) {
        derivative = derivative * tn + value;
        value = value * tn + coef[k];
    }
    *slope = derivative;
    return value;
}

/** @brief Compensate one sample x (triad unit) at temperature [degC] (NaN -> Tn = 0) into out. Outside
 *         the calibrated range the polynomials continue along their tangent at the edge (continuation 1,
 *         at most one span) or hold their edge value (0); 1 if the temperature was inside, 0 if not. */
int ImuThermalApply(const ImuThermalCoefficients *c, const double x[3], double temperature, int continuation,
                    double out[3])
{
    const double clamped = ImuThermalClampTemperature(c, temperature);
    const double tn = ImuThermalNormalisedTemperature(c, temperature);
    const double beyond = ImuThermalContinuation(c, temperature, clamped, continuation);
    double y[3];
    int i, k;
    if (!c->enabled) {
        for (i = 0; i < 3; i++) {
            out[i] = x[i];
        }
        return 1;
    }
    for (i = 0; i < 3; i++) {
        double gain, bias, gainSlope, biasSlope, gainCoef[IMU_THERMAL_MAX_DEGREE + 1];
        gainCoef[0] = 1.0;
        for (k = 1; k <= c->degree; k++) {
            gainCoef[k] = c->g[i][k - 1];
        }
        gain = ImuThermalPolynomial(gainCoef, c->degree, tn, &gainSlope);
        bias = ImuThermalPolynomial(c->b[i], c->degree, tn, &biasSlope);
        if (beyond != 0.0) {
            gain += gainSlope * beyond;
            bias += biasSlope * beyond;
        }
        y[i] = gain * (x[i] - bias);
    }
    for (i = 0; i < 3; i++) {
        out[i] = c->A[i][0] * y[0] + c->A[i][1] * y[1] + c->A[i][2] * y[2];
    }
    return clamped == temperature || isnan(temperature);
}
