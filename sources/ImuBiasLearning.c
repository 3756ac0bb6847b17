/**
 * @file ImuBiasLearning.c
 * @brief Online learning of the gyro bias at rests by the adaptive-rate gradient rule (ImuBiasLearning.h).
 */
#include <math.h>
#include "ImuBiasLearning.h"
#include "ImuMath.h"

/** Step growth when successive gradients agree in sign, and shrink when they do not. */
#define IMU_BIAS_LEARNING_GROW 1.2
#define IMU_BIAS_LEARNING_SHRINK 0.5

/** @brief Smallest step [1]: the rate [1/s] times the block [s], at most the largest step. */
static double ImuBiasLearningMinStep(const ImuBiasLearningSettings *s)
{
    return fmin(s->rate * IMU_BIAS_LEARNING_BLOCK, IMU_BIAS_LEARNING_STEP_MAX);
}

/** @brief Empty the current block. */
static void ImuBiasLearningClearBlock(ImuBiasLearning *b)
{
    int i;
    for (i = 0; i < 3; i++) {
        b->sum[i][0] = 0.0;
        b->sum[i][1] = 0.0;
    }
    b->blockTime = 0.0;
    b->blockSamples = 0.0;
}

void ImuBiasLearningReset(ImuBiasLearning *b, const ImuBiasLearningSettings *s)
{
    int i, k;
    for (i = 0; i < 3; i++) {
        for (k = 0; k < 2; k++) {
            b->correction[i][k] = 0.0;
            b->step[i][k] = ImuBiasLearningMinStep(s);
            b->gradient[i][k] = 0.0;
        }
    }
    ImuBiasLearningClearBlock(b);
    ImuRestDetectorReset(&b->rest);
    b->temperature = 0.0;
    b->temperatureRate = 0.0;
    b->temperatureTime = 0.0;
    b->temperatureSeen = 0;
}

void ImuBiasLearningRestart(ImuBiasLearning *b)
{
    ImuBiasLearningClearBlock(b);
    ImuRestDetectorReset(&b->rest);
}

int ImuBiasLearningStateValid(const ImuBiasLearning *b, const ImuBiasLearningSettings *s)
{
    const double minStep = ImuBiasLearningMinStep(s);
    int i, k, valid = b->blockTime >= 0.0 && b->blockSamples >= 0.0 && b->rest.restTime >= 0.0
                      && (b->rest.initialised == 0 || b->rest.initialised == 1)
                      && (b->temperatureSeen == 0 || b->temperatureSeen == 1) && isfinite(b->temperature)
                      && isfinite(b->temperatureRate) && b->temperatureTime >= 0.0;
    for (i = 0; i < 3; i++) {
        for (k = 0; k < 2; k++) {
            valid = valid && fabs(b->correction[i][k]) <= s->limit && b->step[i][k] >= minStep
                    && b->step[i][k] <= IMU_BIAS_LEARNING_STEP_MAX && isfinite(b->gradient[i][k])
                    && isfinite(b->sum[i][k]);
        }
    }
    return valid; /* false for NaN */
}

void ImuBiasLearningCorrect(const ImuBiasLearning *b, const ImuBiasLearningSettings *s, double tn, double rate[3])
{
    int i;
    if (!s->enabled) {
        return;
    }
    for (i = 0; i < 3; i++) {
        rate[i] -= b->correction[i][0] + b->correction[i][1] * tn;
    }
}

/** @brief One gradient step per coefficient from the finished block, the step adapted to the sign agreement. */
static void ImuBiasLearningStep(ImuBiasLearning *b, const ImuBiasLearningSettings *s)
{
    const double minStep = ImuBiasLearningMinStep(s);
    int i, k;
    for (i = 0; i < 3; i++) {
        for (k = 0; k < 2; k++) {
            const double g = b->sum[i][k] / b->blockSamples;
            const double agreement = g * b->gradient[i][k];
            double d;
            if (agreement > 0.0) {
                b->step[i][k] = fmin(b->step[i][k] * IMU_BIAS_LEARNING_GROW, IMU_BIAS_LEARNING_STEP_MAX);
            } else if (agreement < 0.0) {
                b->step[i][k] = fmax(b->step[i][k] * IMU_BIAS_LEARNING_SHRINK, minStep);
            }
            d = b->correction[i][k] + b->step[i][k] * g;
            b->correction[i][k] = fmax(-s->limit, fmin(s->limit, d));
            b->gradient[i][k] = g;
        }
    }
}

/** @brief Follow the temperature rate [degC/s]: the low-passed backward difference (NaN holds it). */
static void ImuBiasLearningTemperature(ImuBiasLearning *b, double temperature, double dt)
{
    if (isnan(temperature) || !isfinite(temperature)) {
        return;
    }
    if (b->temperatureSeen) {
        const double alpha = 1.0 - exp(-dt / IMU_BIAS_LEARNING_RATE_TIME);
        b->temperatureRate += alpha * ((temperature - b->temperature) / dt - b->temperatureRate);
        b->temperatureTime += dt;
    }
    b->temperature = temperature;
    b->temperatureSeen = 1;
}

/** @brief 1 if the temperature is steady enough to learn at (or was never given), else 0. */
static int ImuBiasLearningTemperatureSteady(const ImuBiasLearning *b)
{
    return !b->temperatureSeen || (b->temperatureTime >= IMU_BIAS_LEARNING_RATE_TIME
                                   && fabs(b->temperatureRate) <= IMU_BIAS_LEARNING_MAX_TEMPERATURE_RATE);
}

void ImuBiasLearningUpdate(ImuBiasLearning *b, const ImuBiasLearningSettings *s, double temperature, double tn,
                           const double rate[3], const double acc[3], double dt)
{
    int i;
    if (!s->enabled || !(s->gyroThreshold > 0.0) || !(dt > 0.0) || !ImuAllFinite(rate, 3) || !ImuAllFinite(acc, 3)) {
        return;
    }
    ImuBiasLearningTemperature(b, temperature, dt);
    if (!ImuRestDetectorUpdateBias(&b->rest, rate, acc, dt, s->gyroThreshold, s->gyroThreshold + s->limit,
                                   s->accThreshold)
        || !ImuBiasLearningTemperatureSteady(b)) {
        return;
    }
    for (i = 0; i < 3; i++) {
        b->sum[i][0] += rate[i];
        b->sum[i][1] += rate[i] * tn;
    }
    b->blockTime += dt;
    b->blockSamples += 1.0;
    if (b->blockTime >= IMU_BIAS_LEARNING_BLOCK) {
        ImuBiasLearningStep(b, s);
        ImuBiasLearningClearBlock(b);
    }
}

double ImuBiasLearningShift(const ImuBiasLearning *b, double tn)
{
    double shift[3];
    int i;
    for (i = 0; i < 3; i++) {
        shift[i] = b->correction[i][0] + b->correction[i][1] * tn;
    }
    return sqrt(shift[0] * shift[0] + shift[1] * shift[1] + shift[2] * shift[2]);
}
