/**
 * @file ImuBatchMagPf.c
 * @brief Batch entry points of the magnetometer particle filter and its generator (Python only).
 *
 * Settings: the FMU settings array (contract.layout SETTINGS order, the array ImuBatchRun takes),
 * unpacked and checked by ImuRuntimeSettings as in the FMU (field_norm and the pf_* parameters
 * feed the filter), and a second array of the IMU_MAG_PF_INTERNAL_COUNT internal settings in the
 * order of ImuMagPf.c ImuMagPfInternal, which ImuBatchMagPfInternal names with unit and default.
 * Outputs per sample (14): compensated field [uT] (3), hard iron [uT] (3), soft iron b11 b12 b13
 * b22 b23 b33 (6), N_eff (1), changes declared so far (1).
 */
#include <math.h>
#include <stddef.h>
#include "ImuMagPf.h"
#include "ImuRuntime.h"

#define IMU_BATCH_MAG_PF_OUTPUTS 14
#define IMU_BATCH_MAG_PF_MAX_SEED 9007199254740992.0 /* 2^53: seeds are exact integers as double */

/** @brief Exported prototypes (declared here: only Python calls them). */
IMU_EXPORT int ImuBatchMagPfInternal(size_t index, const char **name, const char **unit, double *value,
                                     double *source);
IMU_EXPORT int ImuBatchMagPfCheckSettings(const double *settings, size_t nSettings, const double *internal,
                                          size_t nInternal, const char **message);
IMU_EXPORT int ImuBatchMagPfRun(const double *settings, size_t nSettings, const double *internal, size_t nInternal,
                                size_t nSamples, const double *mag, double *outputs);
IMU_EXPORT int ImuBatchRngDraw(double seed, double stream, int kind, size_t n, double *out);

/** @brief Name, unit, default and source-method value (pf_additions = 0) of internal setting index; 0, or -1
 *         past the end. */
int ImuBatchMagPfInternal(size_t index, const char **name, const char **unit, double *value, double *source)
{
    return ImuMagPfInternalInfo(index, name, unit, value, source);
}

/** @brief Filter settings from the FMU settings array and the internal settings; 0, or -1 with
 *         *message naming the array or the setting that is wrong. */
static int ImuBatchMagPfSettings(ImuMagPfSettings *s, const double *settings, size_t nSettings,
                                 const double *internal, size_t nInternal, const char **message)
{
    ImuPipelineSettings pipeline;
    size_t i;
    if (ImuRuntimeSettings(&pipeline, settings, nSettings, message) != ImuRuntimeOk) {
        return -1;
    }
    if (internal == NULL || nInternal != IMU_MAG_PF_INTERNAL_COUNT) {
        *message = "internal settings array is NULL or not of length IMU_MAG_PF_INTERNAL_COUNT";
        return -1;
    }
    *s = pipeline.pf;
    for (i = 0; i < nInternal; i++) {
        ImuMagPfSetInternal(s, i, internal[i]);
    }
    return ImuMagPfSettingsCheck(s, message);
}

/** @brief Check the two settings arrays; 0, or -1 with *message naming the bad setting. */
int ImuBatchMagPfCheckSettings(const double *settings, size_t nSettings, const double *internal,
                               size_t nInternal, const char **message)
{
    ImuMagPfSettings s;
    const char *text = NULL;
    const int result = ImuBatchMagPfSettings(&s, settings, nSettings, internal, nInternal, &text);
    if (message != NULL) {
        *message = text;
    }
    return result;
}

/** @brief Run the filter over nSamples field samples mag [uT] (row-major (N, 3)) into outputs (N, 14). */
int ImuBatchMagPfRun(const double *settings, size_t nSettings, const double *internal, size_t nInternal,
                     size_t nSamples, const double *mag, double *outputs)
{
    ImuMagPf pf; /* ~90 kB on the stack; ImuMagPfInitialise clears it */
    ImuMagPfSettings s;
    const char *message;
    size_t k;
    if (mag == NULL || outputs == NULL ||
        ImuBatchMagPfSettings(&s, settings, nSettings, internal, nInternal, &message) != 0 ||
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

/** @brief 1 if value is an integer in [low, high]. */
static int ImuBatchMagPfIsInteger(double value, double low, double high)
{
    return value >= low && value <= high && value == floor(value);
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
