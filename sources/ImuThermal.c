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

/** @brief temperature [degC] clamped to the calibrated range when the model has one and uses it. */
static double ImuThermalClampTemperature(const ImuThermalCoefficients *c, double temperature)
{
    if (!c->hasRange || c->degree == 0 || isnan(temperature)) {
        return temperature;
    }
    return temperature < c->tMin ? c->tMin : (temperature > c->tMax ? c->tMax : temperature);
}

/** @brief Compensate one sample x (triad unit) at temperature [degC] (NaN -> Tn = 0) into out, the
 *         temperature clamped to the calibrated range; 1 if it was inside, 0 if clamped. */
int ImuThermalApply(const ImuThermalCoefficients *c, const double x[3], double temperature, double out[3])
{
    const double clamped = ImuThermalClampTemperature(c, temperature);
    const double tn = isnan(clamped) ? 0.0 : (clamped - c->t0) / c->ts;
    double y[3];
    int i, k;
    if (!c->enabled) {
        for (i = 0; i < 3; i++) {
            out[i] = x[i];
        }
        return 1;
    }
    for (i = 0; i < 3; i++) {
        double gain = 0.0, bias = c->b[i][c->degree];
        for (k = c->degree; k >= 1; k--) { /* Horner, k = P..1, then the constant 1 */
            gain = gain * tn + c->g[i][k - 1];
        }
        gain = gain * tn + 1.0;
        for (k = c->degree - 1; k >= 0; k--) {
            bias = bias * tn + c->b[i][k];
        }
        y[i] = gain * (x[i] - bias);
    }
    for (i = 0; i < 3; i++) {
        out[i] = c->A[i][0] * y[0] + c->A[i][1] * y[1] + c->A[i][2] * y[2];
    }
    return clamped == temperature || isnan(temperature);
}
