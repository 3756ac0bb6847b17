/**
 * @file ImuBatch.c
 * @brief Batch entry points of the runtime shared library (the runtime lives on the stack): the
 *        FMU's runtime entry (ImuRuntime.h) over a whole recording.
 */
#include "ImuBatch.h"
#include "ImuRuntime.h"

/** @brief Check a settings array (user units); *message names a bad setting. */
int ImuBatchCheckSettings(const double *settings, size_t nSettings, const char **message)
{
    ImuPipelineSettings s;
    const char *text = NULL;
    const int result = ImuRuntimeSettings(&s, settings, nSettings, &text);
    if (message != NULL) {
        *message = result == ImuRuntimeBadSettings ? text : NULL;
    }
    return result;
}

/** @brief ImuBatchRun; the guard's issue bits of sample k go to issues[k] unless issues is NULL. */
static int ImuBatchRunWith(const double *coefficients, size_t nCoefficients, const double *settings,
                           size_t nSettings, size_t nSamples, const double *t, const double *inputs,
                           double *outputs, int *issues)
{
    ImuRuntime runtime;
    const char *message;
    double last = 0.0; /* s, time of the last sample whose time increased */
    size_t k;
    int result = ImuRuntimeInitialise(&runtime, coefficients, nCoefficients, settings, nSettings, &message);
    if (result == ImuRuntimeOk && nSamples > 0 && (t == NULL || inputs == NULL || outputs == NULL)) {
        result = ImuRuntimeNullPointer;
    }
    if (result != ImuRuntimeOk) {
        return result;
    }
    for (k = 0; k < nSamples; k++) {
        const double step = k > 0 ? t[k] - last : 0.0;
        const int found = ImuRuntimeStep(&runtime, step, inputs + k * IMU_INPUT_COUNT, outputs + k * IMU_OUTPUT_COUNT);
        if (issues != NULL) {
            issues[k] = found;
        }
        if (k == 0 || step > 0.0) { /* a time that does not increase is not a sample time to step from */
            last = t[k];
        }
    }
    return ImuRuntimeOk;
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
    return ImuBatchRunWith(coefficients, nCoefficients, settings, nSettings, nSamples, t, inputs, outputs, NULL);
}

int ImuBatchRunIssues(const double *coefficients, size_t nCoefficients, const double *settings,
                      size_t nSettings, size_t nSamples, const double *t, const double *inputs,
                      double *outputs, int *issues)
{
    if (nSamples > 0 && issues == NULL) {
        return ImuRuntimeNullPointer;
    }
    return ImuBatchRunWith(coefficients, nCoefficients, settings, nSettings, nSamples, t, inputs, outputs, issues);
}

/** @brief The Euler fusion's additions that the FMU uses (every ImuEulerAddition bit). */
int ImuBatchEulerAllAdditions(void)
{
    return IMU_EULER_ALL_ADDITIONS;
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
