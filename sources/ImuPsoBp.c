/**
 * @file ImuPsoBp.c
 * @brief PSO-BP gyro bias model and causal temperature-rate estimator (see ImuPsoBp.h).
 */
#include <math.h>
#include <string.h>
#include "ImuPsoBp.h"

/** @brief 1 if every one of the n entries is finite. */
static int ImuPsoBpAllFinite(const double *v, size_t n)
{
    size_t k;
    for (k = 0; k < n; k++) {
        if (!isfinite(v[k])) {
            return 0;
        }
    }
    return 1;
}

/** @brief 0 if the header (mode, H, tau [s], ranges [degC, degC/s]) is valid, else -1. */
static int ImuPsoBpCheckHeader(const double *h)
{
    if ((h[0] != ImuPsoBpModeOff && h[0] != ImuPsoBpModeFull && h[0] != ImuPsoBpModeResidual)
        || h[1] != floor(h[1]) || h[1] < 1.0
        || h[1] > IMU_PSOBP_MAX_HIDDEN || !(h[2] > 0.0) || !(h[3] < h[4]) || !(h[5] < h[6])) {
        return -1;
    }
    return 0;
}

/** @brief Unpack the weights of one axis (block part of IMU_PSOBP_AXIS_BLOCK); -1 if padding is not 0. */
static int ImuPsoBpUnpackAxis(ImuPsoBpCoefficients *c, int axis, const double *v)
{
    const double *b1 = v + 2 * IMU_PSOBP_MAX_HIDDEN;
    const double *w2 = b1 + IMU_PSOBP_MAX_HIDDEN;
    int j;
    for (j = 0; j < IMU_PSOBP_MAX_HIDDEN; j++) {
        if (j >= c->hidden && (v[2 * j] != 0.0 || v[2 * j + 1] != 0.0 || b1[j] != 0.0 || w2[j] != 0.0)) {
            return -1;
        }
        c->w1[axis][j][0] = v[2 * j];
        c->w1[axis][j][1] = v[2 * j + 1];
        c->b1[axis][j] = b1[j];
        c->w2[axis][j] = w2[j];
    }
    c->b2[axis] = w2[IMU_PSOBP_MAX_HIDDEN];
    return 0;
}

int ImuPsoBpFromBlock(ImuPsoBpCoefficients *c, const double *block, size_t n)
{
    int axis;
    if (n != IMU_PSOBP_BLOCK || !ImuPsoBpAllFinite(block, n)) {
        return -1;
    }
    if (block[0] == ImuPsoBpModeOff) { /* an untrained model: zero bias, whatever the rest holds */
        memset(c, 0, sizeof(*c));
        c->mode = ImuPsoBpModeOff;
        c->tau = 1.0;
        return 0;
    }
    if (ImuPsoBpCheckHeader(block) != 0) {
        return -1;
    }
    c->mode = (ImuPsoBpMode) (int) block[0];
    c->hidden = (int) block[1];
    c->tau = block[2];
    c->tMin = block[3];
    c->tMax = block[4];
    c->rMin = block[5];
    c->rMax = block[6];
    for (axis = 0; axis < 3; axis++) {
        if (ImuPsoBpUnpackAxis(c, axis, block + IMU_PSOBP_HEADER + axis * IMU_PSOBP_AXIS_BLOCK) != 0) {
            return -1;
        }
    }
    return 0;
}

int ImuPsoBpStateValid(const ImuPsoBpState *s, double clock)
{
    return (s->started == 0 || s->started == 1) && s->time >= 0.0 && s->time <= clock; /* false for NaN */
}

void ImuPsoBpInitialise(ImuPsoBpState *s, const ImuPsoBpCoefficients *c)
{
    s->started = 0;
    s->tau = c->tau;
    s->time = 0.0;
    s->temperature = 0.5 * (c->tMin + c->tMax);
    s->rate = 0.0;
}

void ImuPsoBpUpdate(ImuPsoBpState *s, double t, double temperature)
{
    double dt, alpha;
    if (isnan(temperature)) {
        return;
    }
    if (!s->started) {
        s->started = 1;
        s->time = t;
        s->temperature = temperature;
        s->rate = 0.0;
        return;
    }
    dt = t - s->time;
    if (!(dt > 0.0)) {
        return;
    }
    alpha = 1.0 - exp(-dt / s->tau);
    s->rate += alpha * ((temperature - s->temperature) / dt - s->rate);
    s->time = t;
    s->temperature = temperature;
}

/** @brief x limited to [lo, hi] (x's unit). */
static double ImuPsoBpClamp(double x, double lo, double hi)
{
    return x < lo ? lo : (x > hi ? hi : x);
}

int ImuPsoBpEvaluate(const ImuPsoBpCoefficients *c, double temperature, double rate, int clamp, double bias[3])
{
    const double tc = ImuPsoBpClamp(temperature, c->tMin, c->tMax);
    const double rc = ImuPsoBpClamp(rate, c->rMin, c->rMax);
    const double u0 = 2.0 * ((clamp ? tc : temperature) - c->tMin) / (c->tMax - c->tMin) - 1.0;
    const double u1 = 2.0 * ((clamp ? rc : rate) - c->rMin) / (c->rMax - c->rMin) - 1.0;
    int axis, j;
    for (axis = 0; axis < 3; axis++) {
        double sum = c->b2[axis];
        for (j = 0; j < c->hidden; j++) {
            sum += c->w2[axis][j] * tanh(c->w1[axis][j][0] * u0 + c->w1[axis][j][1] * u1 + c->b1[axis][j]);
        }
        bias[axis] = c->mode != ImuPsoBpModeOff ? sum : 0.0;
    }
    return c->mode == ImuPsoBpModeOff || (tc == temperature && rc == rate);
}

int ImuPsoBpBias(const ImuPsoBpCoefficients *c, const ImuPsoBpState *s, int clamp, double bias[3])
{
    return ImuPsoBpEvaluate(c, s->temperature, s->rate, clamp, bias);
}

int ImuPsoBpCorrect(const ImuPsoBpCoefficients *c, const ImuPsoBpState *s, int clamp, double gyr[3])
{
    double bias[3];
    int axis;
    const int inside = ImuPsoBpBias(c, s, clamp, bias);
    for (axis = 0; axis < 3; axis++) {
        gyr[axis] -= bias[axis];
    }
    return inside;
}
