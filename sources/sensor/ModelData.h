/**
 * @file ModelData.h
 * @brief The virtual sensor's values (ModelData) and its kinds of bad input, for the shared core model.h.
 *        Staged in place of the ImuFusion ModelData.h by fmu/sensor_fmu.py.
 */
#ifndef IMU_MODEL_DATA_H
#define IMU_MODEL_DATA_H

#include "ImuCommon.h"
#include "ImuSensor.h"
#include "config.h"

/** Kinds of bad input (one bit each); an episode of a kind lasts while its bit stays set. */
typedef enum {
    ModelIssueTruth = 1 << 0, /* a true rate, specific force, attitude or field input is not finite (or q is 0) */
    ModelIssueStep = 1 << 1   /* step size not finite and > 0: the step is discarded */
} ModelIssue;

#define MODEL_ISSUE_COUNT 2

/** Every value of the model and the virtual sensor that produces the outputs. */
typedef struct {
    double inputs[SENSOR_INPUT_COUNT];     /* true motion as set: rad/s, m/s^2, 1, uT, degC, auxiliary inputs */
    double outputs[SENSOR_OUTPUT_COUNT];   /* the raw sample of the last consumed true sample (NaN before one) */
    double settings[SENSOR_SETTING_COUNT]; /* parameters in user units (SensorSetting order) */
    int issues;                            /* ModelIssue bits of the last step */
    int initialised;                       /* 1 once the parameters are applied: they are locked */
    ImuSensor sensor;                      /* the trained chain backwards, with its noise (ImuSensor.h) */
} ModelData;

#endif
