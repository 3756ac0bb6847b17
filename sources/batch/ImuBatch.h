/**
 * @file ImuBatch.h
 * @brief Batch entry points of the runtime shared library (called from Python through ctypes).
 *
 * The same runtime entry as the FMU (ImuRuntime.h), run over a whole recording in one call. These
 * files (sources/batch/) are in the batch library only, never in an FMU.
 */
#ifndef IMU_BATCH_H
#define IMU_BATCH_H

#include <stddef.h>
#include "ImuCommon.h"

/**
 * @brief Run the pipeline over nSamples samples behind the FMU's input/time/output guard
 *        (ImuGuard.h), so the outputs equal the FMU's on any input (finite, except the
 *        corrected outputs of an absent sensor, which are NaN).
 * @param t nSamples times [s]: only their differences are used (the steps); inputs nSamples x IMU_INPUT_COUNT row-major (rad/s, m/s^2, uT,
 *        degC, auxiliary inputs); outputs nSamples x IMU_OUTPUT_COUNT row-major (ImuLayout.h).
 * @return ImuRuntimeOk, or a negative ImuRuntimeResult (ImuRuntime.h; outputs untouched).
 */
IMU_EXPORT int ImuBatchRun(const double *coefficients, size_t nCoefficients, const double *settings,
                           size_t nSettings, size_t nSamples, const double *t, const double *inputs,
                           double *outputs);
/**
 * @brief ImuBatchRun that also writes the guard's ImuGuardIssue bits (ImuGuard.h) of sample k to
 *        issues[k] (nSamples ints): what the FMU reports as warnings, per sample.
 * @return as ImuBatchRun; ImuRuntimeNullPointer when issues is NULL and nSamples > 0.
 */
IMU_EXPORT int ImuBatchRunIssues(const double *coefficients, size_t nCoefficients, const double *settings,
                                 size_t nSettings, size_t nSamples, const double *t, const double *inputs,
                                 double *outputs, int *issues);
/** @brief Every ImuEulerAddition bit: the largest value of the setting euler_additions (its default). */
IMU_EXPORT int ImuBatchEulerAllAdditions(void);
/**
 * @brief Check a settings array; on ImuRuntimeBadSettings point *message at a static text naming
 *        the setting and its range (else NULL). @return ImuRuntimeOk or a negative ImuRuntimeResult.
 */
IMU_EXPORT int ImuBatchCheckSettings(const double *settings, size_t nSettings, const char **message);
/**
 * @brief The correction-term signals (ImuTerms.h) of a series, exactly as the pipeline forms them.
 * @param t nSamples times [s]; components nSamples x 9 compensated gyr, acc, mag; temperature
 *        nSamples [degC]; aux nSamples x IMU_TERMS_AUX_COUNT auxiliary inputs (their own units);
 *        signals nSamples x IMU_TERM_SIGNAL_COUNT row-major.
 */
IMU_EXPORT void ImuBatchTermSignals(size_t nSamples, const double *t, const double *components,
                                    const double *temperature, const double *aux, double *signals);
/** @brief Layout version and the lengths of the coefficient, settings, input and output arrays. */
IMU_EXPORT void ImuBatchLayout(int *version, int *nCoefficients, int *nSettings, int *nInputs, int *nOutputs);

#endif
