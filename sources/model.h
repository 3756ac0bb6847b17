/**
 * @file model.h
 * @brief Maps the FMU's value references to the ImuFusion runtime (no FMI types here).
 *
 * ModelData is one plain struct: the FMU state that fmi2GetFMUstate / fmi2SerializeFMUstate
 * copy. fmi2Functions.c owns the FMI state machine and the logging; this file owns the values.
 */
#ifndef IMU_MODEL_H
#define IMU_MODEL_H

#include "ImuCommon.h"
#include "ImuLayout.h"
#include "ImuPipeline.h"
#include "config.h"

/** Result of a model call; on ModelError a static message says what went wrong. */
typedef enum {
    ModelOk,
    ModelError
} ModelStatus;

/** Every value of the model and the pipeline that produces the outputs. */
typedef struct {
    double inputs[IMU_INPUT_COUNT];     /* raw sample: rad/s, m/s^2, uT, degC */
    double outputs[IMU_OUTPUT_COUNT];   /* estimate for the last consumed sample */
    double settings[IMU_SETTING_COUNT]; /* parameters in user units (ImuLayout.h order) */
    int initialised;                    /* 1 once settings are applied: parameters are locked */
    ImuPipeline pipeline;
} ModelData;

/** @brief The GUID of the modelDescription.xml this binary was built for. */
IMU_HIDDEN const char *ModelGuid(void);
/** @brief Set every variable to its start value (the state right after instantiation). */
IMU_HIDDEN void ModelSetStartValues(ModelData *m);
/** @brief Read the Real variable vr into *value. */
IMU_HIDDEN ModelStatus ModelGetReal(const ModelData *m, unsigned int vr, double *value, const char **message);
/** @brief Write value into the Real variable vr (inputs always, parameters before initialisation). */
IMU_HIDDEN ModelStatus ModelSetReal(ModelData *m, unsigned int vr, double value, const char **message);
/** @brief Read the Boolean variable vr into *value (0 or 1). */
IMU_HIDDEN ModelStatus ModelGetBoolean(const ModelData *m, unsigned int vr, int *value, const char **message);
/** @brief Write the Boolean variable vr (a parameter: only before initialisation). */
IMU_HIDDEN ModelStatus ModelSetBoolean(ModelData *m, unsigned int vr, int value, const char **message);
/** @brief Check the settings, unpack the trained coefficients and initialise the pipeline. */
IMU_HIDDEN ModelStatus ModelInitialise(ModelData *m, const char **message);
/**
 * @brief Consume the sample whose inputs are set: outputs become its estimate.
 * @param time time of the sample [s] (the communication point the step starts at).
 */
IMU_HIDDEN void ModelDoStep(ModelData *m, double time);

#endif
