/**
 * @file ImuTerms.c
 * @brief Additive correction terms over a fixed signal vocabulary (see ImuTerms.h).
 */
#include <math.h>
#include "ImuTerms.h"

/** @brief 1 if v is an integer-valued double in [lo, hi]. */
static int ImuTermsIsIndex(double v, int lo, int hi)
{
    return isfinite(v) && v == floor(v) && v >= lo && v <= hi;
}

/** @brief 1 if a block entry (target, a, b, coefficient, lo, hi) is a valid term. */
static int ImuTermsIsValid(const double term[IMU_TERMS_ENTRY])
{
    return ImuTermsIsIndex(term[0], 0, 8) && ImuTermsIsIndex(term[1], 0, IMU_TERM_SIGNAL_COUNT - 1)
           && ImuTermsIsIndex(term[2], -1, IMU_TERM_SIGNAL_COUNT - 1) && isfinite(term[3])
           && isfinite(term[4]) && isfinite(term[5]) && term[4] <= term[5];
}

int ImuTermsFromBlock(ImuTermsCoefficients *c, const double *block)
{
    int k;
    if (!ImuTermsIsIndex(block[0], 0, IMU_TERMS_MAX)) {
        return -1;
    }
    c->count = (int)block[0];
    for (k = 0; k < IMU_TERMS_MAX; k++) {
        const double *term = block + 1 + IMU_TERMS_ENTRY * k;
        if (k >= c->count) {
            c->target[k] = 0;
            c->a[k] = 0;
            c->b[k] = -1;
            c->coefficient[k] = 0.0;
            c->lo[k] = 0.0;
            c->hi[k] = 0.0;
            continue;
        }
        if (!ImuTermsIsValid(term)) {
            return -1;
        }
        c->target[k] = (int)term[0];
        c->a[k] = (int)term[1];
        c->b[k] = (int)term[2];
        c->coefficient[k] = term[3];
        c->lo[k] = term[4];
        c->hi[k] = term[5];
    }
    return 0;
}

void ImuTermsReset(ImuTermsState *s)
{
    int i;
    s->started = 0;
    s->firstTime = 0.0;
    s->lastTime = 0.0;
    for (i = 0; i < 9; i++) {
        s->last[i] = NAN;
        s->derivative[i] = NAN;
    }
    s->lastTemp = NAN;
    s->lastTempTime = 0.0;
    s->tempRate = 0.0;
    s->tempRateFast = 0.0;
}

/** @brief Backward differences [unit/s] of the components over dt [s]; held where not computable. */
static void ImuTermsDerivatives(ImuTermsState *s, double dt, const double x[9])
{
    int i;
    for (i = 0; i < 9; i++) {
        if (dt > 0.0 && isfinite(x[i]) && isfinite(s->last[i])) {
            s->derivative[i] = (x[i] - s->last[i]) / dt;
        }
        s->last[i] = x[i];
    }
}

int ImuTermsStateValid(const ImuTermsState *s, double clock)
{
    return (s->started == 0 || s->started == 1) && s->firstTime >= 0.0 && s->firstTime <= s->lastTime
           && (s->started ? s->lastTime == clock : s->lastTime <= clock) && s->lastTempTime >= 0.0
           && s->lastTempTime <= clock; /* false for NaN */
}

/** @brief Low-passed temperature rates [degC/s] (time constants IMU_TERMS_TEMP_RATE_TAU and
 *         IMU_TERMS_TEMP_RATE_FAST_TAU) at time t [s]. */
static void ImuTermsTemperatureRate(ImuTermsState *s, double t, double temperature)
{
    double dt;
    if (!isfinite(temperature)) {
        return;
    }
    dt = t - s->lastTempTime;
    if (isfinite(s->lastTemp) && dt > 0.0) {
        const double rate = (temperature - s->lastTemp) / dt;
        s->tempRate += dt / (IMU_TERMS_TEMP_RATE_TAU + dt) * (rate - s->tempRate);
        s->tempRateFast += dt / (IMU_TERMS_TEMP_RATE_FAST_TAU + dt) * (rate - s->tempRateFast);
    }
    if (!isfinite(s->lastTemp) || dt > 0.0) {
        s->lastTemp = temperature;
        s->lastTempTime = t;
    }
}

void ImuTermsSignals(ImuTermsState *s, double t, const double x[9], double temperature,
                     const double aux[IMU_TERMS_AUX_COUNT], double signals[IMU_TERM_SIGNAL_COUNT])
{
    int i;
    double dt = 0.0;
    if (!s->started) {
        s->started = 1;
        s->firstTime = t;
        s->lastTime = t;
    } else if (t > s->lastTime) {
        dt = t - s->lastTime;
        s->lastTime = t;
    }
    ImuTermsDerivatives(s, dt, x);
    ImuTermsTemperatureRate(s, t, temperature);
    for (i = 0; i < 9; i++) {
        signals[ImuSigGyrX + i] = x[i];
        signals[ImuSigDGyrX + i] = s->derivative[i];
        signals[ImuSigAbsGyrX + i] = fabs(x[i]);
    }
    signals[ImuSigTemp] = temperature;
    signals[ImuSigTempRate] = isfinite(s->lastTemp) ? s->tempRate : NAN;
    signals[ImuSigTempRateFast] = isfinite(s->lastTemp) ? s->tempRateFast : NAN;
    signals[ImuSigTime] = t - s->firstTime;
    signals[ImuSigOne] = 1.0;
    for (i = 0; i < IMU_TERMS_AUX_COUNT; i++) {
        signals[ImuSigAux1 + i] = aux[i];
    }
}

/** @brief x [any unit] limited to [lo, hi]. */
static double ImuTermsClamp(double x, double lo, double hi)
{
    return x < lo ? lo : (x > hi ? hi : x);
}

int ImuTermsUseSignal(const ImuTermsCoefficients *c, int signal)
{
    int k;
    for (k = 0; k < c->count; k++) {
        if (c->a[k] == signal || c->b[k] == signal) {
            return 1;
        }
    }
    return 0;
}

int ImuTermsApply(const ImuTermsCoefficients *c, const double signals[IMU_TERM_SIGNAL_COUNT], double x[9])
{
    double correction[9] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    int k, i, inside = 1;
    for (k = 0; k < c->count; k++) {
        const double regressor = signals[c->a[k]] * (c->b[k] < 0 ? 1.0 : signals[c->b[k]]);
        if (isfinite(regressor)) {
            const double clamped = ImuTermsClamp(regressor, c->lo[k], c->hi[k]);
            correction[c->target[k]] += c->coefficient[k] * clamped;
            inside = inside && clamped == regressor;
        }
    }
    for (i = 0; i < 9; i++) {
        x[i] -= correction[i];
    }
    return inside;
}
