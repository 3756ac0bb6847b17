/**
 * @file ImuRuntime.h
 * @brief The one runtime entry of the FMU (model.c) and the batch library (batch/ImuBatch.c):
 *        initialise the guarded pipeline from the flat coefficient and settings arrays, then step it.
 *
 * Both callers go through these verbs and nothing else, so FMU = batch holds by construction: the
 * same unpacking and checks of the arrays, the same guard (ImuGuard.h) around the same pipeline.
 */
#ifndef IMU_RUNTIME_H
#define IMU_RUNTIME_H

#include <stddef.h>
#include "ImuCommon.h"
#include "ImuGuard.h"
#include "ImuPipeline.h"

/** Results of the array checks (the batch library's return codes, training/runtime.py ERROR_CODES). */
typedef enum {
    ImuRuntimeOk = 0,
    ImuRuntimeNullPointer = -1,          /* an array pointer is NULL */
    ImuRuntimeBadCoefficientCount = -2,  /* nCoefficients != IMU_COEFFICIENT_COUNT */
    ImuRuntimeBadLayoutVersion = -3,     /* coefficients[0] != IMU_LAYOUT_VERSION */
    ImuRuntimeBadCoefficients = -4,      /* a block is invalid (ImuCoefficientsFromArray) */
    ImuRuntimeBadSettingCount = -5,      /* nSettings != IMU_SETTING_COUNT */
    ImuRuntimeBadSettings = -6           /* a setting is out of range (ImuPipelineSettingsCheck) */
} ImuRuntimeResult;

/** The guarded pipeline: everything that evolves from sample to sample (part of the FMU state). */
typedef struct {
    ImuGuard guard;       /* input/time/output guard */
    ImuPipeline pipeline; /* the per-sample processing chain */
} ImuRuntime;

/**
 * @brief Unpack and check the settings array (user units, ImuLayout.h order) into *s.
 * @return ImuRuntimeOk, or a negative ImuRuntimeResult with *message pointing at a static text
 *         naming the problem (the setting and its range for ImuRuntimeBadSettings).
 */
IMU_HIDDEN int ImuRuntimeSettings(ImuPipelineSettings *s, const double *settings, size_t nSettings,
                                  const char **message);
/** @brief Unpack and check the coefficient array (ImuLayout.h) into *c; ImuRuntimeOk or negative with *message. */
IMU_HIDDEN int ImuRuntimeCoefficients(ImuCoefficients *c, const double *coefficients, size_t nCoefficients,
                                      const char **message);
/**
 * @brief Check and unpack both arrays, initialise the pipeline and reset the guard (the state right
 *        before the first sample). On a negative result *r is untouched and *message says why.
 */
IMU_HIDDEN int ImuRuntimeInitialise(ImuRuntime *r, const double *coefficients, size_t nCoefficients,
                                    const double *settings, size_t nSettings, const char **message);
/**
 * @brief Like ImuRuntimeInitialise, but keep the evolving state: re-derive what the arrays decide
 *        (ImuPipelineConfigure) for a restored FMU state, whose copies of them are not trusted.
 */
IMU_HIDDEN int ImuRuntimeConfigure(ImuRuntime *r, const double *coefficients, size_t nCoefficients,
                                   const double *settings, size_t nSettings, const char **message);
/**
 * @brief One guarded sample (ImuGuardStep): raw inputs in, outputs out, `step` [s] after the previous
 *        sample. @return the ImuGuardIssue bits of the sample.
 */
IMU_HIDDEN int ImuRuntimeStep(ImuRuntime *r, double step, const double in[IMU_INPUT_COUNT],
                              double out[IMU_OUTPUT_COUNT]);

#endif
