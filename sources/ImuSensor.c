/**
 * @file ImuSensor.c
 * @brief The virtual sensor: the trained corrections run backwards plus the characterised noise (ImuSensor.h).
 */
#include "ImuSensor.h"

#include <math.h>
#include <string.h>

#include "ImuMath.h"

/** Iterations of the ELM (fixed point) and correction-term (Newton) inverses, and when they stop early: the
 *  last step or residual below IMU_SENSOR_TOLERANCE of the value (relative, plus the same absolute). */
#define IMU_SENSOR_ITERATIONS 60
#define IMU_SENSOR_TOLERANCE 1e-13
/** Stream of the noise generator (any odd selector; the seed is the parameter). */
#define IMU_SENSOR_STREAM 0x5E115011u

void ImuSensorInitialise(ImuSensor *s, const ImuPipelineSettings *settings, const ImuCoefficients *c,
                         const ImuSensorNoise *noise)
{
    int i;
    memset(s, 0, sizeof *s); /* padding too: the sensor is part of the checksummed FMU state */
    s->settings = *settings;
    s->coefficients = *c;
    s->noise = *noise;
    for (i = 0; i < 3; i++) {
        s->delay.lag[i] = -settings->align.lag[i];
    }
    ImuSensorReset(s);
}

void ImuSensorReset(ImuSensor *s)
{
    ImuAlignReset(&s->align);
    ImuTermsReset(&s->terms);
    ImuPsoBpInitialise(&s->psobp, &s->coefficients.psobp);
    memset(&s->noiseState, 0, sizeof s->noiseState);
    ImuRngSeed(&s->noiseState.rng, (uint64_t)(unsigned int)s->noise.seed, IMU_SENSOR_STREAM);
    s->hasSample = 0;
    s->clock = 0.0;
}

const char *ImuSensorNoiseProblem(const ImuSensorNoise *noise)
{
    int i, a;
    for (i = 0; i < 3; i++) {
        for (a = 0; a < 3; a++) {
            if (!(noise->density[i][a] >= 0.0) || !isfinite(noise->density[i][a])) {
                return "a noise density is not finite and >= 0";
            }
            if (!(noise->instability[i][a] >= 0.0) || !isfinite(noise->instability[i][a])) {
                return "a bias instability is not finite and >= 0";
            }
            if (!(noise->walk[i][a] >= 0.0) || !isfinite(noise->walk[i][a])) {
                return "a random walk is not finite and >= 0";
            }
        }
        if (!(noise->lsb[i] >= 0.0) || !isfinite(noise->lsb[i]) || !(noise->fullScale[i] >= 0.0)
            || !isfinite(noise->fullScale[i])) {
            return "an LSB or full scale is not finite and >= 0";
        }
    }
    return NULL;
}

const char *ImuSensorStateProblem(const ImuSensor *s, double clock)
{
    int i, a;
    if (s->hasSample != 0 && s->hasSample != 1) {
        return "the virtual sensor's sample flag is not 0 or 1";
    }
    if (!isfinite(s->clock) || s->clock > clock) {
        return "the virtual sensor's clock is not finite and no later than the FMU's time";
    }
    if (!ImuAlignStateValid(&s->align, s->clock)) {
        return "the delay buffer's count or head is outside 0..63, or its times are not finite and increasing";
    }
    if (!ImuTermsStateValid(&s->terms, s->clock) || !ImuPsoBpStateValid(&s->psobp, s->clock)) {
        return "the correction terms' or PSO-BP stage's times are not finite and no later than the sensor's clock";
    }
    for (i = 0; i < 3; i++) {
        for (a = 0; a < 3; a++) {
            if (!isfinite(s->noiseState.walk[i][a]) || !ImuAllFinite(s->noiseState.flicker[i][a], IMU_SENSOR_FLICKER_POLES)) {
                return "a random-walk or flicker bias of the noise is not finite";
            }
        }
    }
    if (s->noiseState.rng.hasSpare != 0 && s->noiseState.rng.hasSpare != 1) {
        return "the noise generator's spare flag is not 0 or 1";
    }
    return NULL;
}

/** @brief x = m^-1 y for the 3 x 3 row-major m (cofactors; m is a calibration's near-identity response). */
static void ImuSensorSolve3(const double m[9], const double y[3], double x[3])
{
    const double c00 = m[4] * m[8] - m[5] * m[7], c01 = m[5] * m[6] - m[3] * m[8], c02 = m[3] * m[7] - m[4] * m[6];
    const double det = m[0] * c00 + m[1] * c01 + m[2] * c02;
    const double inv[9] = {c00, m[2] * m[7] - m[1] * m[8], m[1] * m[5] - m[2] * m[4],
                           c01, m[0] * m[8] - m[2] * m[6], m[2] * m[3] - m[0] * m[5],
                           c02, m[1] * m[6] - m[0] * m[7], m[0] * m[4] - m[1] * m[3]};
    int i;
    for (i = 0; i < 3; i++) {
        x[i] = (inv[3 * i] * y[0] + inv[3 * i + 1] * y[1] + inv[3 * i + 2] * y[2]) / det;
    }
}

/** @brief The raw triad x whose gain/bias(T) compensation is y: the map is affine in the triad at a given
 *         temperature, so three probes of ImuThermalApply give it exactly (the same tangent continuation
 *         beyond the calibrated range as the corrector's). */
static void ImuSensorThermalInverse(const ImuThermalCoefficients *c, double temperature, int continuation,
                                    const double y[3], double x[3])
{
    static const double zero[3] = {0.0, 0.0, 0.0};
    double offset[3], probe[3], response[9], shifted[3];
    int i, j;
    (void)ImuThermalApply(c, zero, temperature, continuation, offset);
    for (j = 0; j < 3; j++) {
        double unit[3] = {0.0, 0.0, 0.0};
        unit[j] = 1.0;
        (void)ImuThermalApply(c, unit, temperature, continuation, probe);
        for (i = 0; i < 3; i++) {
            response[3 * i + j] = probe[i] - offset[i];
        }
    }
    for (i = 0; i < 3; i++) {
        shifted[i] = y[i] - offset[i];
    }
    ImuSensorSolve3(response, shifted, x);
}

/** @brief 1 once the fixed-point step d[n] is below the tolerance of the values v[n]. */
static int ImuSensorConverged(const double *d, const double *v, int n)
{
    int i;
    for (i = 0; i < n; i++) {
        if (!(fabs(d[i]) <= IMU_SENSOR_TOLERANCE * (1.0 + fabs(v[i])))) {
            return 0;
        }
    }
    return 1;
}

/** @brief The distorted field whose ELM correction is the field f[3], in place: x <- x + (f - ELM(x)). */
static void ImuSensorElmInverse(const ImuElm *elm, double f[3])
{
    const double target[3] = {f[0], f[1], f[2]};
    double mapped[3], step[3];
    int k, i;
    for (k = 0; k < IMU_SENSOR_ITERATIONS; k++) {
        (void)ImuElmApply(elm, f, mapped);
        for (i = 0; i < 3; i++) {
            step[i] = target[i] - mapped[i];
            f[i] += step[i];
        }
        if (ImuSensorConverged(step, f, 3)) {
            return;
        }
    }
}

/** @brief Solve a x = b (n <= 9 unknowns, a row-major n x n, both overwritten) by Gaussian elimination with
 *         partial pivoting; 0 when a is singular (x untouched). */
static int ImuSensorSolve(int n, double a[81], double b[9], double x[9])
{
    int i, j, k;
    for (k = 0; k < n; k++) {
        int pivot = k;
        for (i = k + 1; i < n; i++) {
            if (fabs(a[i * n + k]) > fabs(a[pivot * n + k])) {
                pivot = i;
            }
        }
        if (!(fabs(a[pivot * n + k]) > 0.0)) {
            return 0;
        }
        if (pivot != k) {
            for (j = 0; j < n; j++) {
                const double swap = a[k * n + j];
                a[k * n + j] = a[pivot * n + j];
                a[pivot * n + j] = swap;
            }
            {
                const double swap = b[k];
                b[k] = b[pivot];
                b[pivot] = swap;
            }
        }
        for (i = k + 1; i < n; i++) {
            const double f = a[i * n + k] / a[k * n + k];
            for (j = k; j < n; j++) {
                a[i * n + j] -= f * a[k * n + j];
            }
            b[i] -= f * b[k];
        }
    }
    for (i = n - 1; i >= 0; i--) {
        double sum = b[i];
        for (j = i + 1; j < n; j++) {
            sum -= a[i * n + j] * x[j];
        }
        x[i] = sum / a[i * n + i];
    }
    return 1;
}

/** @brief What the correction terms make of the triads x[9] before them at time t (the corrector's
 *         ImuTermsSignals then ImuTermsApply), on a copy of the terms' state. */
static void ImuSensorTermsForward(const ImuSensor *s, double t, double temperature,
                                  const double aux[IMU_TERMS_AUX_COUNT], const double x[9], double y[9])
{
    double signals[IMU_TERM_SIGNAL_COUNT];
    ImuTermsState copy = s->terms;
    ImuTermsSignals(&copy, t, x, temperature, aux, signals);
    memcpy(y, x, 9 * sizeof x[0]);
    (void)ImuTermsApply(&s->coefficients.terms, signals, y);
}

/** @brief The triads x[9] before the correction terms whose corrected values are x (in place), by Newton's
 *         method on the terms' forward map with a forward-difference Jacobian (the terms are products of at
 *         most two signals, and a time-derivative signal can weigh more than the triad itself: a plain
 *         fixed point would diverge for a lag term longer than the sample interval); the terms' state then
 *         advances with the solution, as the corrector's does with its input. */
static void ImuSensorTermsInverse(ImuSensor *s, double t, double temperature, const double aux[IMU_TERMS_AUX_COUNT],
                                  double x[9])
{
    double target[9], y[9], probe[9], moved[9], jacobian[81], residual[9], step[9], signals[IMU_TERM_SIGNAL_COUNT];
    int k, i, j;
    if (s->coefficients.terms.count == 0) {
        return; /* as the corrector: a model without terms computes no signals */
    }
    memcpy(target, x, sizeof target);
    for (k = 0; k < IMU_SENSOR_ITERATIONS; k++) {
        ImuSensorTermsForward(s, t, temperature, aux, x, y);
        for (i = 0; i < 9; i++) {
            residual[i] = target[i] - y[i];
        }
        if (ImuSensorConverged(residual, target, 9) || !ImuAllFinite(residual, 9)) {
            break;
        }
        for (j = 0; j < 9; j++) {
            const double delta = 1e-6 * (1.0 + fabs(x[j]));
            memcpy(probe, x, sizeof probe);
            probe[j] += delta;
            ImuSensorTermsForward(s, t, temperature, aux, probe, moved);
            for (i = 0; i < 9; i++) {
                jacobian[i * 9 + j] = (moved[i] - y[i]) / delta;
            }
        }
        if (!ImuSensorSolve(9, jacobian, residual, step)) {
            break;
        }
        for (i = 0; i < 9; i++) {
            x[i] += step[i];
        }
    }
    ImuTermsSignals(&s->terms, t, x, temperature, aux, signals);
}

/** @brief Add the noise of one sample h [s] after the previous one to the raw triads (sensor axes), then
 *         saturate and quantise: each bias as it stands, then its step to the next sample. */
static void ImuSensorAddNoise(ImuSensor *s, double h, double raw[9])
{
    const ImuSensorNoise *n = &s->noise;
    ImuSensorNoiseState *state = &s->noiseState;
    int i, a, k;
    for (i = 0; i < 3; i++) {
        for (a = 0; a < 3; a++) {
            double *v = &raw[3 * i + a];
            if (n->density[i][a] > 0.0) {
                *v += n->density[i][a] / sqrt(h) * ImuRngNormal(&state->rng);
            }
            if (n->walk[i][a] > 0.0) {
                *v += state->walk[i][a];
                state->walk[i][a] += n->walk[i][a] * sqrt(h) * ImuRngNormal(&state->rng);
            }
            if (n->instability[i][a] > 0.0) {
                const double sigma = IMU_SENSOR_FLICKER_GAIN * n->instability[i][a];
                for (k = 0; k < IMU_SENSOR_FLICKER_POLES; k++) {
                    const double decay = exp(-h / pow(10.0, 0.5 * k));
                    *v += state->flicker[i][a][k];
                    state->flicker[i][a][k] = decay * state->flicker[i][a][k]
                                              + sigma * sqrt(1.0 - decay * decay) * ImuRngNormal(&state->rng);
                }
            }
            if (n->fullScale[i] > 0.0) {
                *v = *v > n->fullScale[i] ? n->fullScale[i] : (*v < -n->fullScale[i] ? -n->fullScale[i] : *v);
            }
            if (n->lsb[i] > 0.0) {
                *v = n->lsb[i] * floor(*v / n->lsb[i] + 0.5);
            }
        }
    }
}

void ImuSensorUpdate(ImuSensor *s, double t, double h, const double truth[9], double temperature,
                     const double aux[IMU_TERMS_AUX_COUNT], double raw[9])
{
    const ImuCoefficients *c = &s->coefficients;
    double x[9];
    int i;
    memcpy(x, truth, sizeof x);
    for (i = 0; i < 3; i++) {
        ImuMountVectorInverse(&s->settings.mount, &x[3 * i]);
    }
    if (s->settings.enableElm) {
        ImuSensorElmInverse(&c->elm, &x[6]);
    }
    ImuSensorTermsInverse(s, t, temperature, aux, x);
    (void)ImuAlignUpdate(&s->align, &s->delay, t, x);
    ImuPsoBpUpdate(&s->psobp, t, temperature);
    if (s->settings.enablePsoBp) {
        double bias[3];
        (void)ImuPsoBpBias(&c->psobp, &s->psobp, s->settings.psobpClamp, bias);
        for (i = 0; i < 3; i++) {
            x[i] += bias[i];
        }
    }
    for (i = 0; i < 3; i++) {
        if (s->settings.enableThermal) {
            ImuSensorThermalInverse(&c->thermal[i], temperature, s->settings.thermalContinuation, &x[3 * i], &raw[3 * i]);
        } else {
            memcpy(&raw[3 * i], &x[3 * i], 3 * sizeof x[0]);
        }
    }
    if (s->noise.enabled) {
        ImuSensorAddNoise(s, h, raw);
    }
    s->hasSample = 1;
    s->clock = t;
}
