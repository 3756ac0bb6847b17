/**
 * @file ImuBatchMagPf.c
 * @brief Batch entry points of the magnetometer particle filter and its generator (Python only).
 *
 * Flat settings array (user units, order of training/models/magpf.py SETTINGS):
 *  0 particleCount, 1 highThreshold, 2 lowThreshold, 3 measurementNoise [uT],
 *  4 processNoiseHard [uT/update], 5 processNoiseSoft [1/update], 6 priorSpreadHard [uT],
 *  7 priorSpreadSoft [1], 8-10 priorHardIron [uT], 11-16 priorSoftIron [1], 17 roughening,
 *  18 innovationTimeConstant [updates], 19 maxInflation, 20 decimation, 21 hiddenUnits,
 *  22 trainingEpochs, 23 learningRate, 24 maxTries, 25 enableSplitting, 26 seed, 27 fieldNorm [uT],
 *  28 minRotation [deg], 29 sphereBins, 30 changeThreshold, 31 changeSpreadHard [uT],
 *  32 changeSpreadSoft, 33 enableMove, 34 raoBlackwell, 35 holdPrior, 36 normTimeConstant [updates],
 *  37 settleSpread [uT].
 * Outputs per sample (14): compensated field [uT] (3), hard iron [uT] (3), soft iron b11 b12 b13
 * b22 b23 b33 (6), N_eff (1), changes declared so far (1).
 */
#include <math.h>
#include <stddef.h>
#include "ImuMagPf.h"

#define IMU_BATCH_MAG_PF_SETTINGS 38
#define IMU_BATCH_MAG_PF_OUTPUTS 14
#define IMU_BATCH_MAG_PF_MAX_SEED 9007199254740992.0 /* 2^53: seeds are exact integers as double */

/** @brief Exported prototypes (declared here: only Python calls them). */
IMU_EXPORT int ImuBatchMagPfCheckSettings(const double *settings, size_t nSettings, const char **message);
IMU_EXPORT int ImuBatchMagPfRun(const double *settings, size_t nSettings, size_t nSamples, const double *mag,
                                double *outputs);
IMU_EXPORT int ImuBatchRngDraw(double seed, double stream, int kind, size_t n, double *out);

/** @brief 1 if value is an integer in [low, high]. */
static int ImuBatchMagPfIsInteger(double value, double low, double high)
{
    return value >= low && value <= high && value == floor(value);
}

/** @brief Unpack the flat settings array; 0, or -1 with *message if it cannot be unpacked. */
static int ImuBatchMagPfUnpack(ImuMagPfSettings *s, const double *a, size_t n, const char **message)
{
    int j;
    if (a == NULL || n != IMU_BATCH_MAG_PF_SETTINGS) {
        *message = "settings array is NULL or not of length 38";
        return -1;
    }
    if (!ImuBatchMagPfIsInteger(a[0], 0.0, 1e6) || !ImuBatchMagPfIsInteger(a[20], 0.0, 1e6) ||
        !ImuBatchMagPfIsInteger(a[21], 0.0, 1e6) || !ImuBatchMagPfIsInteger(a[22], 0.0, 1e6) ||
        !ImuBatchMagPfIsInteger(a[24], 0.0, 1e6) || !ImuBatchMagPfIsInteger(a[25], 0.0, 1e6) ||
        !ImuBatchMagPfIsInteger(a[29], 0.0, 1e6) || !ImuBatchMagPfIsInteger(a[33], 0.0, 1e6) ||
        !ImuBatchMagPfIsInteger(a[34], 0.0, 1e6) || !ImuBatchMagPfIsInteger(a[35], 0.0, 1e6)) {
        *message = "particleCount, decimation, hiddenUnits, trainingEpochs, maxTries, enableSplitting, "
                   "sphereBins, enableMove, raoBlackwell and holdPrior must be non-negative integers";
        return -1;
    }
    if (!ImuBatchMagPfIsInteger(a[26], 0.0, IMU_BATCH_MAG_PF_MAX_SEED)) {
        *message = "seed must be an integer in 0..2^53";
        return -1;
    }
    s->particleCount = (int)a[0];
    s->highThreshold = a[1];
    s->lowThreshold = a[2];
    s->measurementNoise = a[3];
    s->processNoiseHard = a[4];
    s->processNoiseSoft = a[5];
    s->priorSpreadHard = a[6];
    s->priorSpreadSoft = a[7];
    for (j = 0; j < 3; j++) {
        s->priorHardIron[j] = a[8 + j];
    }
    for (j = 0; j < 6; j++) {
        s->priorSoftIron[j] = a[11 + j];
    }
    s->roughening = a[17];
    s->innovationTimeConstant = a[18];
    s->maxInflation = a[19];
    s->decimation = (int)a[20];
    s->hiddenUnits = (int)a[21];
    s->trainingEpochs = (int)a[22];
    s->learningRate = a[23];
    s->maxTries = (int)a[24];
    s->enableSplitting = (int)a[25];
    s->seed = (uint64_t)a[26];
    s->fieldNorm = a[27];
    s->minRotation = a[28];
    s->sphereBins = (int)a[29];
    s->changeThreshold = a[30];
    s->changeSpreadHard = a[31];
    s->changeSpreadSoft = a[32];
    s->enableMove = (int)a[33];
    s->raoBlackwell = (int)a[34];
    s->holdPrior = (int)a[35];
    s->normTimeConstant = a[36];
    s->settleSpread = a[37];
    return 0;
}

/** @brief Check a flat settings array; 0, or -1 with *message naming the bad setting. */
int ImuBatchMagPfCheckSettings(const double *settings, size_t nSettings, const char **message)
{
    ImuMagPfSettings s;
    const char *text = NULL;
    int result = ImuBatchMagPfUnpack(&s, settings, nSettings, &text);
    if (result == 0) {
        result = ImuMagPfSettingsCheck(&s, &text);
    }
    if (message != NULL) {
        *message = text;
    }
    return result;
}

/** @brief Run the filter over nSamples field samples mag [uT] (row-major (N, 3)) into outputs (N, 14). */
int ImuBatchMagPfRun(const double *settings, size_t nSettings, size_t nSamples, const double *mag,
                     double *outputs)
{
    ImuMagPf pf; /* ~90 kB on the stack; ImuMagPfInitialise clears it */
    ImuMagPfSettings s;
    const char *message;
    size_t k;
    if (mag == NULL || outputs == NULL || ImuBatchMagPfUnpack(&s, settings, nSettings, &message) != 0 ||
        ImuMagPfInitialise(&pf, &s) != 0) {
        return -1;
    }
    for (k = 0; k < nSamples; k++) {
        double *row = outputs + IMU_BATCH_MAG_PF_OUTPUTS * k;
        (void)ImuMagPfUpdate(&pf, mag + 3 * k);
        ImuMagPfCompensate(&pf, mag + 3 * k, row);
        ImuMagPfGetHardIron(&pf, row + 3);
        ImuMagPfGetSoftIron(&pf, row + 6);
        row[12] = ImuMagPfGetEffectiveSampleSize(&pf);
        row[13] = (double)ImuMagPfGetChangeCount(&pf);
    }
    return 0;
}

/** @brief n draws of a PCG32 stream: kind 0 uint32 outputs, 1 uniforms, 2 standard normals. */
int ImuBatchRngDraw(double seed, double stream, int kind, size_t n, double *out)
{
    ImuRng rng;
    size_t k;
    if (out == NULL || kind < 0 || kind > 2 || !ImuBatchMagPfIsInteger(seed, 0.0, IMU_BATCH_MAG_PF_MAX_SEED) ||
        !ImuBatchMagPfIsInteger(stream, 0.0, IMU_BATCH_MAG_PF_MAX_SEED)) {
        return -1;
    }
    ImuRngSeed(&rng, (uint64_t)seed, (uint64_t)stream);
    for (k = 0; k < n; k++) {
        out[k] = kind == 0 ? (double)ImuRngNext(&rng) : (kind == 1 ? ImuRngUniform(&rng) : ImuRngNormal(&rng));
    }
    return 0;
}
