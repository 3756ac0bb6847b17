/**
 * @file ImuThermal.c
 * @brief Gain/bias temperature model of one sensor triad.
 */
#include <math.h>
#include "ImuThermal.h"
#include "ImuMath.h"

/** @brief Check the block header: enabled 0/1; if enabled, integer degree in range and ts > 0. */
static int ImuThermalCheckHeader(const double *block)
{
    const double enabled = block[0], ts = block[2], degree = block[3];
    if (enabled != 0.0 && enabled != 1.0) {
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

/** @brief Compensate one sample x (triad unit) at temperature [degC] (NaN -> Tn = 0) into out. */
void ImuThermalApply(const ImuThermalCoefficients *c, const double x[3], double temperature, double out[3])
{
    const double tn = isnan(temperature) ? 0.0 : (temperature - c->t0) / c->ts;
    double y[3];
    int i, k;
    if (!c->enabled) {
        for (i = 0; i < 3; i++) {
            out[i] = x[i];
        }
        return;
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
}
