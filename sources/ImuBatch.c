/**
 * @file ImuBatch.c
 * @brief Batch entry points of the runtime shared library (the pipeline lives on the stack).
 */
#include "ImuBatch.h"
#include "ImuGuard.h"
#include "ImuPipeline.h"

/** @brief Unpack and check coefficients [layout ImuLayout.h]; ImuBatchOk or a negative code. */
static int ImuBatchCoefficients(ImuCoefficients *c, const double *coefficients, size_t n)
{
    if (coefficients == NULL) {
        return ImuBatchNullPointer;
    }
    if (n != IMU_COEFFICIENT_COUNT) {
        return ImuBatchBadCoefficientCount;
    }
    if (coefficients[0] != IMU_LAYOUT_VERSION) {
        return ImuBatchBadLayoutVersion;
    }
    return ImuCoefficientsFromArray(c, coefficients, n) == 0 ? ImuBatchOk : ImuBatchBadCoefficients;
}

/** @brief Unpack and check settings (user units); ImuBatchOk or a negative code. */
static int ImuBatchSettings(ImuPipelineSettings *s, const double *settings, size_t n, const char **message)
{
    *message = NULL;
    if (settings == NULL) {
        return ImuBatchNullPointer;
    }
    if (ImuPipelineSettingsFromArray(s, settings, n) != 0) {
        return ImuBatchBadSettingCount;
    }
    return ImuPipelineSettingsCheck(s, message) == 0 ? ImuBatchOk : ImuBatchBadSettings;
}

/** @brief Check a settings array (user units); *message names a bad setting. */
int ImuBatchCheckSettings(const double *settings, size_t nSettings, const char **message)
{
    ImuPipelineSettings s;
    const char *text = NULL;
    const int result = ImuBatchSettings(&s, settings, nSettings, &text);
    if (message != NULL) {
        *message = text;
    }
    return result;
}

/** @brief Run the guarded pipeline (ImuGuard.h, as in the FMU) over nSamples samples (times t [s],
 *         inputs/outputs row-major). Sample k comes t[k] - t[k-1] after the previous one: the step
 *         size of the FMU's previous doStep (fmu/cosim.py: h = diff(t)), so both give the same bits.
 *         A time that does not increase is an ImuGuardIssueOrder sample; the next step counts from
 *         the last time that did. */
int ImuBatchRun(const double *coefficients, size_t nCoefficients, const double *settings,
                size_t nSettings, size_t nSamples, const double *t, const double *inputs,
                double *outputs)
{
    ImuPipeline pipeline;
    ImuGuard guard;
    ImuCoefficients c;
    ImuPipelineSettings s;
    const char *message;
    double last = 0.0; /* s, time of the last sample whose time increased */
    size_t k;
    int result = ImuBatchCoefficients(&c, coefficients, nCoefficients);
    if (result == ImuBatchOk) {
        result = ImuBatchSettings(&s, settings, nSettings, &message);
    }
    if (result == ImuBatchOk && nSamples > 0 && (t == NULL || inputs == NULL || outputs == NULL)) {
        result = ImuBatchNullPointer;
    }
    if (result != ImuBatchOk) {
        return result;
    }
    ImuPipelineInitialise(&pipeline, &s, &c);
    ImuGuardReset(&guard, settings[ImuSetDeclination]);
    for (k = 0; k < nSamples; k++) {
        const double step = k > 0 ? t[k] - last : 0.0;
        (void)ImuGuardStep(&guard, &pipeline, step, inputs + k * IMU_INPUT_COUNT, outputs + k * IMU_OUTPUT_COUNT);
        if (k == 0 || step > 0.0) { /* a time that does not increase is not a sample time to step from */
            last = t[k];
        }
    }
    return ImuBatchOk;
}

/** @brief Layout version and the lengths of the coefficient, settings, input and output arrays. */
void ImuBatchLayout(int *version, int *nCoefficients, int *nSettings, int *nInputs, int *nOutputs)
{
    *version = IMU_LAYOUT_VERSION;
    *nCoefficients = IMU_COEFFICIENT_COUNT;
    *nSettings = IMU_SETTING_COUNT;
    *nInputs = IMU_INPUT_COUNT;
    *nOutputs = IMU_OUTPUT_COUNT;
}

void ImuBatchTermSignals(size_t nSamples, const double *t, const double *components,
                         const double *temperature, const double *aux, double *signals)
{
    ImuTermsState state;
    size_t k;
    ImuTermsReset(&state);
    for (k = 0; k < nSamples; k++) {
        ImuTermsSignals(&state, t[k], components + 9 * k, temperature[k], aux + IMU_TERMS_AUX_COUNT * k,
                        signals + IMU_TERM_SIGNAL_COUNT * k);
    }
}
