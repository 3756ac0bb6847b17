/**
 * @file ImuElm.c
 * @brief Extreme learning machine (field form): distorted field -> true field [uT].
 */
#include <math.h>
#include "ImuElm.h"
#include "ImuMath.h"

/** @brief Check the header: enabled 0/1; if enabled, known activation, integer L in range, min < max. */
static int ImuElmCheckHeader(const double *block)
{
    int i;
    if (block[0] != 0.0 && block[0] != 1.0) {
        return -1;
    }
    if (block[0] == 0.0) {
        return 0;
    }
    if ((block[1] != ImuElmTanh && block[1] != ImuElmSigmoid) || !(block[2] >= 1.0) ||
        block[2] > IMU_ELM_MAX_HIDDEN || block[2] != floor(block[2])) {
        return -1;
    }
    for (i = 0; i < 3; i++) {
        if (!(block[3 + i] < block[6 + i]) || !(block[9 + i] < block[12 + i])) {
            return -1;
        }
    }
    return 0;
}

/** @brief Unpack one block (enabled, activation, L, ranges [uT], w, b, beta); 0 or -1 if invalid. */
int ImuElmFromBlock(ImuElm *elm, const double *block)
{
    const double *w = block + IMU_ELM_HEADER;
    const double *b = w + 3 * IMU_ELM_MAX_HIDDEN;
    const double *beta = b + IMU_ELM_MAX_HIDDEN;
    int i, j;
    if (!ImuAllFinite(block, IMU_ELM_BLOCK) || ImuElmCheckHeader(block) != 0) {
        return -1;
    }
    elm->enabled = (int)block[0];
    elm->activation = block[1] == ImuElmSigmoid ? ImuElmSigmoid : ImuElmTanh;
    elm->hidden = elm->enabled ? (int)block[2] : 0;
    for (i = 0; i < 3; i++) {
        elm->inMin[i] = block[3 + i];
        elm->inMax[i] = block[6 + i];
        elm->inScale[i] = elm->enabled ? 2.0 / (block[6 + i] - block[3 + i]) : 0.0;
        elm->outMin[i] = block[9 + i];
        elm->outHalfSpan[i] = 0.5 * (block[12 + i] - block[9 + i]);
    }
    for (j = 0; j < IMU_ELM_MAX_HIDDEN; j++) {
        elm->b[j] = b[j];
        for (i = 0; i < 3; i++) {
            elm->w[j][i] = w[3 * j + i];
            elm->beta[j][i] = beta[3 * j + i];
        }
    }
    return 0;
}

/** @brief Activation g(z) of the hidden nodes (z dimensionless). */
static double ImuElmActivate(ImuElmActivation activation, double z)
{
    return activation == ImuElmSigmoid ? 1.0 / (1.0 + exp(-z)) : tanh(z);
}

/** @brief in [uT] clamped into the calibrated box [inMin, inMax] per axis into clamped; 1 if unchanged. */
static int ImuElmClamp(const ImuElm *elm, const double in[3], double clamped[3])
{
    int i, inside = 1;
    for (i = 0; i < 3; i++) {
        clamped[i] = in[i] < elm->inMin[i] ? elm->inMin[i] : (in[i] > elm->inMax[i] ? elm->inMax[i] : in[i]);
        inside = inside && (clamped[i] == in[i] || isnan(in[i]));
    }
    return inside;
}

/** @brief Map a distorted field in [uT] to the corrected field out [uT] (in and out may alias): the
 *         network's correction at the field clamped into the calibrated box; 1 if it was inside. */
int ImuElmApply(const ImuElm *elm, const double in[3], double out[3])
{
    double x[3], xc[3], y[3] = {0.0, 0.0, 0.0};
    int i, j, inside;
    if (!elm->enabled) {
        for (i = 0; i < 3; i++) {
            out[i] = in[i];
        }
        return 1;
    }
    inside = ImuElmClamp(elm, in, xc);
    for (i = 0; i < 3; i++) {
        x[i] = (xc[i] - elm->inMin[i]) * elm->inScale[i] - 1.0;
    }
    for (j = 0; j < elm->hidden; j++) {
        const double h = ImuElmActivate(elm->activation,
                                        elm->w[j][0] * x[0] + elm->w[j][1] * x[1] + elm->w[j][2] * x[2] + elm->b[j]);
        for (i = 0; i < 3; i++) {
            y[i] += elm->beta[j][i] * h;
        }
    }
    for (i = 0; i < 3; i++) {
        out[i] = elm->outMin[i] + (y[i] + 1.0) * elm->outHalfSpan[i] + (in[i] - xc[i]);
    }
    return inside;
}
