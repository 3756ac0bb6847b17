/**
 * @file ImuGuard.h
 * @brief Input, time and output guard around ImuPipelineUpdate, shared by the FMU and the batch library.
 *
 * Bad triads become NaN (the pipeline skips them), a bad temperature becomes the last valid one,
 * and non-finite outputs hold their last finite values. A sensor that has not yet delivered one
 * valid sample and reads NaN is absent, not bad (imu-csv/1: a sensor that was not recorded is
 * all-NaN): no issue bit, and its corrected outputs are NaN. Time comes as step sizes (the time
 * since the previous sample), never as absolute times: the pipeline's clock is the time since the
 * first sample summed from them, so an importer's clock at 1e14 s loses nothing. A step longer
 * than IMU_GUARD_GAP_STEPS nominal steps is a gap: the pipeline re-initialises what cannot be
 * integrated across it (ImuPipelineGap). The state is one plain struct (no pointers), so it can be
 * copied with the FMU state. Knows nothing of FMI and logs nothing.
 */
#ifndef IMU_GUARD_H
#define IMU_GUARD_H

#include "ImuCommon.h"
#include "ImuLayout.h"
#include "ImuPipeline.h"

/* Plausibility limits of the raw inputs: beyond them a sensor is saturated, broken or the input
 * is not in the documented unit. The magnetometer limits scale with the field_norm setting. */
#define IMU_GUARD_GYR_LIMIT 100.0      /* rad/s: beyond any MEMS gyro's full scale (about 70 rad/s) */
#define IMU_GUARD_ACC_LIMIT 2000.0     /* m/s^2: about 200 g */
#define IMU_GUARD_MAG_SATURATION 20.0  /* x field_norm: an axis at or beyond it is saturated */
#define IMU_GUARD_MAG_MINIMUM 0.02     /* x field_norm: a smaller field magnitude means no field */
#define IMU_GUARD_TEMP_MIN (-60.0)     /* degC, lower end of the valid temperature range */
#define IMU_GUARD_TEMP_MAX 125.0       /* degC, upper end of the valid temperature range */
/* Steps that set the nominal step: it is the median of the last this many steps that were finite and
 * > 0, gaps included (the upper one of the middle two while fewer than this have been seen). One short
 * step (a duplicated time stamp 10 us apart) or one gap cannot move it; a change of the sampling rate
 * moves it after 3 steps at the new rate. */
#define IMU_GUARD_STEP_HISTORY 5
/* A step longer than this many nominal steps (ImuGuardNominalStep) is a gap: 1 s at
 * 100 Hz, in which handheld motion turns by up to about 1 rad, so nothing integrated across it is
 * worth keeping. Shorter losses of samples are left to the attitude filters, which count the lost
 * time as unmeasured motion (ImuAttitude.c, IMU_ATTITUDE_MISSING_STEPS). */
#define IMU_GUARD_GAP_STEPS 100.0
/* s: a step longer than this is a gap even before a nominal step is known (the second sample);
 * the pipeline's clock advances by at most this much per step, so it stays fine-grained. */
#define IMU_GUARD_MAX_STEP 1.0e6

/** Kinds of bad input found by the guard (one bit each). */
typedef enum {
    ImuGuardIssueGyr = 1 << 0,     /* gyroscope not finite or beyond IMU_GUARD_GYR_LIMIT */
    ImuGuardIssueAcc = 1 << 1,     /* accelerometer not finite or beyond IMU_GUARD_ACC_LIMIT */
    ImuGuardIssueMag = 1 << 2,     /* magnetometer not finite or an axis saturated */
    ImuGuardIssueMagZero = 1 << 3, /* magnetometer reads (almost) no field */
    ImuGuardIssueTemp = 1 << 4,    /* temperature not finite or outside the valid range */
    ImuGuardIssueOrder = 1 << 5,   /* step since the previous sample not finite and > 0 */
    ImuGuardIssueGap = 1 << 6,     /* step longer than IMU_GUARD_GAP_STEPS nominal steps (or IMU_GUARD_MAX_STEP) */
    ImuGuardIssueOutput = 1 << 8,  /* an output was not finite although the inputs were valid: held */
    ImuGuardIssueAux = 1 << 9      /* an auxiliary input a correction term uses is not finite: held */
} ImuGuardIssue;

/** The sensors, as the ImuGuardIssue bit of their bad input (ImuGuard.present). */
#define IMU_GUARD_SENSORS (ImuGuardIssueGyr | ImuGuardIssueAcc | ImuGuardIssueMag | ImuGuardIssueTemp)

/** State of the guard: plain values only, so a copy is a snapshot. */
typedef struct {
    double lastValidTemp;               /* degC, last valid temperature (NaN before the first) */
    double lastValidAux[IMU_TERMS_AUX_COUNT]; /* their units, last finite auxiliary inputs (NaN before the first) */
    double clock;                       /* s since the first sample, summed from the steps */
    double steps[IMU_GUARD_STEP_HISTORY]; /* s, the last steps that were finite and > 0, a ring */
    int stepCount;                      /* entries of steps in use, 0..IMU_GUARD_STEP_HISTORY */
    int stepHead;                       /* index of steps the next step is written to, 0..IMU_GUARD_STEP_HISTORY - 1 */
    double held[IMU_OUTPUT_COUNT];      /* last finite outputs (initial outputs before the first) */
    int hasSample;                      /* 1 once a sample was consumed */
    int present;                        /* IMU_GUARD_SENSORS bits of the sensors that delivered a valid sample */
} ImuGuard;

/** @brief Outputs before the first sample: level, north-facing, zero signals, heading = declination [rad];
 *         the sensor axes' attitude is the mounting's turn (mount: the body axes, ImuMount.h). */
IMU_HIDDEN void ImuGuardInitialOutputs(double declination, const ImuMount *mount, double out[IMU_OUTPUT_COUNT]);
/** @brief Back to no sample seen; the held outputs become the initial ones (declination [rad], mount). */
IMU_HIDDEN void ImuGuardReset(ImuGuard *g, double declination, const ImuMount *mount);
/**
 * @brief Consume one raw sample (rad/s, m/s^2, uT, degC, auxiliary inputs) through the guard and
 *        the pipeline p into out (ImuLayout.h units).
 * @param step time [s] from the previous sample to this one (ignored for the first sample): the FMU
 *        passes the communication step size of the previous doStep, the batch library the
 *        difference of its sample times.
 * @return the ImuGuardIssue bits found (an absent sensor sets none; see ImuGuardAbsent).
 */
IMU_HIDDEN int ImuGuardStep(ImuGuard *g, ImuPipeline *p, double step, const double raw[IMU_INPUT_COUNT],
                            double out[IMU_OUTPUT_COUNT]);
/** @brief The nominal step [s] (IMU_GUARD_STEP_HISTORY): 0 before a step was seen. */
IMU_HIDDEN double ImuGuardNominalStep(const ImuGuard *g);
/** @brief 1 if the step history's count, head and entries are ones ImuGuardStep can leave (a restored state). */
IMU_HIDDEN int ImuGuardStepsValid(const ImuGuard *g);
/** @brief 1 if the clock [s] is one ImuGuardStep can leave (a restored state): finite, >= 0 and
 *         fine enough that adding the nominal step advances it by that step to 1 % (a double
 *         resolves a 1 ms step to 1 % up to a clock of about 4e11 s; a clock of 1e300 would stop
 *         every later step from advancing the time-alignment buffer and the correction terms). */
IMU_HIDDEN int ImuGuardClockValid(const ImuGuard *g);
/** @brief IMU_GUARD_SENSORS bits of the sensors treated as absent (no valid sample yet). */
IMU_HIDDEN int ImuGuardAbsent(const ImuGuard *g);

#endif
