/**
 * @file ImuRuntime.c
 * @brief The one runtime entry of the FMU and the batch library (see ImuRuntime.h).
 */
#include "ImuRuntime.h"

int ImuRuntimeSettings(ImuPipelineSettings *s, const double *settings, size_t nSettings, const char **message)
{
    *message = NULL;
    if (settings == NULL) {
        *message = "the settings array is NULL";
        return ImuRuntimeNullPointer;
    }
    if (ImuPipelineSettingsFromArray(s, settings, nSettings) != 0) {
        *message = "the settings array has the wrong size";
        return ImuRuntimeBadSettingCount;
    }
    return ImuPipelineSettingsCheck(s, message) == 0 ? ImuRuntimeOk : ImuRuntimeBadSettings;
}

static const ImuCoefficientBlock coefficientBlocks[IMU_COEFFICIENT_BLOCK_COUNT] = IMU_COEFFICIENT_BLOCKS;

int ImuRuntimeCoefficients(ImuCoefficients *c, const double *coefficients, size_t nCoefficients,
                           const char **message)
{
    int block;
    *message = NULL;
    if (coefficients == NULL) {
        *message = "the coefficient array is NULL";
        return ImuRuntimeNullPointer;
    }
    if (nCoefficients != IMU_COEFFICIENT_COUNT) {
        *message = "the coefficient array has the wrong size";
        return ImuRuntimeBadCoefficientCount;
    }
    if (coefficients[0] != IMU_LAYOUT_VERSION) {
        *message = coefficientBlocks[0].problem;
        return ImuRuntimeBadLayoutVersion;
    }
    block = -2 - ImuCoefficientsFromArray(c, coefficients, nCoefficients);
    if (block >= 0) {
        *message = coefficientBlocks[block < IMU_COEFFICIENT_BLOCK_COUNT ? block : 0].problem;
        return ImuRuntimeBadCoefficients;
    }
    return ImuRuntimeOk;
}

/** @brief Both arrays unpacked and checked into *c and *s; ImuRuntimeOk or negative with *message. */
static int ImuRuntimeArrays(ImuCoefficients *c, ImuPipelineSettings *s, const double *coefficients,
                            size_t nCoefficients, const double *settings, size_t nSettings, const char **message)
{
    const int result = ImuRuntimeCoefficients(c, coefficients, nCoefficients, message);
    return result != ImuRuntimeOk ? result : ImuRuntimeSettings(s, settings, nSettings, message);
}

int ImuRuntimeInitialise(ImuRuntime *r, const double *coefficients, size_t nCoefficients,
                         const double *settings, size_t nSettings, const char **message)
{
    ImuCoefficients c;
    ImuPipelineSettings s;
    const int result = ImuRuntimeArrays(&c, &s, coefficients, nCoefficients, settings, nSettings, message);
    if (result == ImuRuntimeOk) {
        ImuPipelineInitialise(&r->pipeline, &s, &c);
        ImuGuardReset(&r->guard, s.declination, &s.mount);
    }
    return result;
}

int ImuRuntimeConfigure(ImuRuntime *r, const double *coefficients, size_t nCoefficients,
                        const double *settings, size_t nSettings, const char **message)
{
    ImuCoefficients c;
    ImuPipelineSettings s;
    const int result = ImuRuntimeArrays(&c, &s, coefficients, nCoefficients, settings, nSettings, message);
    if (result == ImuRuntimeOk) {
        ImuPipelineConfigure(&r->pipeline, &s, &c);
    }
    return result;
}

int ImuRuntimeStep(ImuRuntime *r, double step, const double in[IMU_INPUT_COUNT], double out[IMU_OUTPUT_COUNT])
{
    return ImuGuardStep(&r->guard, &r->pipeline, step, in, out);
}
