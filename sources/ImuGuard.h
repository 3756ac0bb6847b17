/**
 * @file ImuGuard.h
 * @brief Input, time and output guard around ImuPipelineUpdate, shared by the FMU and the batch library.
 *
 * Bad triads become NaN (the pipeline skips them), a bad temperature becomes the last valid one,
 * a non-increasing sample time is flagged and gaps beyond IMU_GUARD_MAX_GAP are cut to it, and
 * non-finite outputs hold their last finite values. The state is one plain struct (no pointers),
 * so it can be copied with the FMU state. Knows nothing of FMI and logs nothing.
 */
#ifndef IMU_GUARD_H
#define IMU_GUARD_H

#include "ImuCommon.h"
#include "ImuLayout.h"

/* Plausibility limits of the raw inputs: beyond them a sensor is saturated, broken or the input
 * is not in the documented unit. The magnetometer limits scale with the field_norm setting. */
#define IMU_GUARD_GYR_LIMIT 100.0      /* rad/s: beyond any MEMS gyro's full scale (about 70 rad/s) */
#define IMU_GUARD_ACC_LIMIT 2000.0     /* m/s^2: about 200 g */
#define IMU_GUARD_MAG_SATURATION 20.0  /* x field_norm: an axis at or beyond it is saturated */
#define IMU_GUARD_MAG_MINIMUM 0.02     /* x field_norm: a smaller field magnitude means no field */
#define IMU_GUARD_TEMP_MIN (-60.0)     /* degC, lower end of the valid temperature range */
#define IMU_GUARD_TEMP_MAX 125.0       /* degC, upper end of the valid temperature range */
#define IMU_GUARD_MAX_GAP 1.0e6        /* s: larger jumps of the sample time are integrated as this */

/** Kinds of bad input found by the guard (one bit each). */
typedef enum {
    ImuGuardIssueGyr = 1 << 0,     /* gyroscope not finite or beyond IMU_GUARD_GYR_LIMIT */
    ImuGuardIssueAcc = 1 << 1,     /* accelerometer not finite or beyond IMU_GUARD_ACC_LIMIT */
    ImuGuardIssueMag = 1 << 2,     /* magnetometer not finite or an axis saturated */
    ImuGuardIssueMagZero = 1 << 3, /* magnetometer reads (almost) no field */
    ImuGuardIssueTemp = 1 << 4,    /* temperature not finite or outside the valid range */
    ImuGuardIssueOrder = 1 << 5,   /* sample time does not increase */
    ImuGuardIssueGap = 1 << 6      /* sample time jumps by more than IMU_GUARD_MAX_GAP */
} ImuGuardIssue;

/** State of the guard: plain values only, so a copy is a snapshot. */
typedef struct {
    double lastValidTemp;               /* degC, last valid temperature (NaN before the first) */
    double lastSampleTime;              /* s, latest sample time consumed */
    double timeShift;                   /* s, sum of the gap excess cut from the pipeline's time */
    double held[IMU_OUTPUT_COUNT];      /* last finite outputs (initial outputs before the first) */
    int hasSample;                      /* 1 once a sample was consumed */
} ImuGuard;

/** @brief Outputs before the first sample: level, north-facing, zero signals, heading = declination [rad]. */
IMU_HIDDEN void ImuGuardInitialOutputs(double declination, double out[IMU_OUTPUT_COUNT]);
/** @brief Back to no sample seen; the held outputs become the initial ones (declination [rad]). */
IMU_HIDDEN void ImuGuardReset(ImuGuard *g, double declination);
/**
 * @brief Sanitise the sample raw (rad/s, m/s^2, uT, degC) taken at t [s] into in (bad triads NaN,
 *        bad temperature the last valid one) and *tPipeline [s] (gaps cut); fieldNorm [uT] scales
 *        the magnetometer limits. Returns the ImuGuardIssue bits found.
 */
IMU_HIDDEN int ImuGuardInputs(ImuGuard *g, double fieldNorm, double t, const double raw[IMU_INPUT_COUNT],
                              double in[IMU_INPUT_COUNT], double *tPipeline);
/** @brief Replace non-finite entries of out (ImuLayout.h units) by the last finite ones and remember
 *         out; returns 1 if any entry was not finite, else 0. */
IMU_HIDDEN int ImuGuardOutputs(ImuGuard *g, double out[IMU_OUTPUT_COUNT]);

#endif
