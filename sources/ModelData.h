/**
 * @file ModelData.h
 * @brief The ImuFusion FMU's values (ModelData) and its kinds of bad input, for the shared core model.h.
 */
#ifndef IMU_MODEL_DATA_H
#define IMU_MODEL_DATA_H

#include "ImuCommon.h"
#include "ImuLayout.h"
#include "ImuRuntime.h"
#include "config.h"

/** Kinds of bad input (one bit each); an episode of a kind lasts while its bit stays set. The
 *  input and time kinds are those of the shared guard (ImuGuard.h). */
typedef enum {
    ModelIssueGyr = ImuGuardIssueGyr,         /* gyroscope not finite or beyond IMU_GUARD_GYR_LIMIT */
    ModelIssueAcc = ImuGuardIssueAcc,         /* accelerometer not finite or beyond IMU_GUARD_ACC_LIMIT */
    ModelIssueMag = ImuGuardIssueMag,         /* magnetometer not finite or an axis saturated */
    ModelIssueMagZero = ImuGuardIssueMagZero, /* magnetometer reads (almost) no field */
    ModelIssueTemp = ImuGuardIssueTemp,       /* temperature not finite or outside the valid range */
    ModelIssueOrder = ImuGuardIssueOrder,     /* time since the previous sample not finite and > 0 */
    ModelIssueGap = ImuGuardIssueGap,         /* a gap: step longer than IMU_GUARD_GAP_STEPS nominal steps */
    ModelIssueStep = 1 << 7,    /* step size not finite and > 0: the step is discarded */
    ModelIssueOutput = ImuGuardIssueOutput, /* an output was not finite although the inputs were valid */
    ModelIssueAux = ImuGuardIssueAux,       /* an auxiliary input a correction term uses is not finite: held */
    ModelIssueCalibration = 1 << 10 /* a model input left its calibrated range (ImuRangeIssue): evaluated clamped */
} ModelIssue;

#define MODEL_ISSUE_COUNT 11

/** Every value of the model and the pipeline that produces the outputs. */
typedef struct {
    double inputs[IMU_INPUT_COUNT];     /* raw sample as set: rad/s, m/s^2, uT, degC, auxiliary inputs */
    double outputs[IMU_OUTPUT_COUNT];   /* estimate for the last consumed sample: finite, except the
                                         * corrected outputs of an absent sensor (NaN, ImuGuard.h) */
    double settings[IMU_SETTING_COUNT]; /* parameters in user units (ImuLayout.h order) */
    double coefficients[IMU_COEFFICIENT_COUNT]; /* the coefficient parameters (contract/coefficient_parameters.py):
                                         * start = the compiled-in ImuCoefficientsData.h */
    int issues;                         /* ModelIssue bits of the last step */
    double stepSize;                    /* s, communicationStepSize of the last doStep: the time from
                                         * the last consumed sample to the next (ImuGuardStep) */
    int initialised;                    /* 1 once settings are applied: parameters are locked */
    ImuRuntime runtime;                 /* the guarded pipeline (ImuRuntime.h, shared with the batch library) */
} ModelData;

#endif
