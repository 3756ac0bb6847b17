/**
 * @file model.c
 * @brief Maps value references to the ImuFusion pipeline: start values, get/set, initialise, step.
 */
#include "model.h"

#include "ImuCoefficientsData.h"

/* The value-reference groups of config.h must match the array sizes of ImuLayout.h. */
typedef char ModelCheckInputs[(VR_FIRST_OUTPUT - VR_FIRST_INPUT == IMU_INPUT_COUNT) ? 1 : -1];
typedef char ModelCheckOutputs[(VR_FIRST_SETTING - VR_FIRST_OUTPUT == IMU_OUTPUT_COUNT) ? 1 : -1];
typedef char ModelCheckSettings[(VR_COUNT - VR_FIRST_SETTING == IMU_SETTING_COUNT) ? 1 : -1];
typedef char ModelCheckBoolean[(vr_enable_thermal - VR_FIRST_SETTING == ImuSetEnableThermal) ? 1 : -1];

static const char *const unknownReference = "unknown value reference";

/** @brief Outputs before the first sample: level, north-facing, zero signals, heading = declination [rad]. */
static void setInitialOutputs(ModelData *m) {
    int i;
    for (i = 0; i < IMU_OUTPUT_COUNT; i++) {
        m->outputs[i] = 0.0;
    }
    m->outputs[ImuOutQw] = 1.0;
    m->outputs[ImuOutHeading] = m->settings[ImuSetDeclination];
}

const char *ModelGuid(void) {
    return IMU_MODEL_GUID;
}

void ModelSetStartValues(ModelData *m) {
    static const double startInputs[IMU_INPUT_COUNT] = {
        0.0, 0.0, 0.0,        /* rad/s */
        0.0, 0.0, -9.80665,   /* m/s^2: at rest and level */
        20.0, 0.0, 40.0,      /* uT: mid-latitude field, north and down */
        25.0                  /* degC */
    };
    int i;
    for (i = 0; i < IMU_INPUT_COUNT; i++) {
        m->inputs[i] = startInputs[i];
    }
    for (i = 0; i < IMU_SETTING_COUNT; i++) {
        m->settings[i] = IMU_SETTING_DEFAULTS[i];
    }
    m->initialised = 0;
    setInitialOutputs(m);
}

ModelStatus ModelGetReal(const ModelData *m, unsigned int vr, double *value, const char **message) {
    if (vr < VR_FIRST_OUTPUT) {
        *value = m->inputs[vr - VR_FIRST_INPUT];
    } else if (vr < VR_FIRST_SETTING) {
        *value = m->outputs[vr - VR_FIRST_OUTPUT];
    } else if (vr < VR_COUNT && vr != vr_enable_thermal) {
        *value = m->settings[vr - VR_FIRST_SETTING];
    } else {
        *message = vr == vr_enable_thermal ? "enable_thermal is a Boolean variable" : unknownReference;
        return ModelError;
    }
    return ModelOk;
}

ModelStatus ModelSetReal(ModelData *m, unsigned int vr, double value, const char **message) {
    if (vr < VR_FIRST_OUTPUT) {
        m->inputs[vr - VR_FIRST_INPUT] = value;
        return ModelOk;
    }
    if (vr < VR_FIRST_SETTING) {
        *message = "outputs cannot be set";
        return ModelError;
    }
    if (vr >= VR_COUNT || vr == vr_enable_thermal) {
        *message = vr == vr_enable_thermal ? "enable_thermal is a Boolean variable" : unknownReference;
        return ModelError;
    }
    if (m->initialised) {
        *message = "parameters are fixed: set them before fmi2ExitInitializationMode";
        return ModelError;
    }
    m->settings[vr - VR_FIRST_SETTING] = value;
    setInitialOutputs(m);
    return ModelOk;
}

ModelStatus ModelGetBoolean(const ModelData *m, unsigned int vr, int *value, const char **message) {
    if (vr != vr_enable_thermal) {
        *message = vr < VR_COUNT ? "not a Boolean variable" : unknownReference;
        return ModelError;
    }
    *value = m->settings[ImuSetEnableThermal] != 0.0;
    return ModelOk;
}

ModelStatus ModelSetBoolean(ModelData *m, unsigned int vr, int value, const char **message) {
    if (vr != vr_enable_thermal) {
        *message = vr < VR_COUNT ? "not a Boolean variable" : unknownReference;
        return ModelError;
    }
    if (m->initialised) {
        *message = "parameters are fixed: set them before fmi2ExitInitializationMode";
        return ModelError;
    }
    m->settings[ImuSetEnableThermal] = value ? 1.0 : 0.0;
    return ModelOk;
}

ModelStatus ModelInitialise(ModelData *m, const char **message) {
    ImuCoefficients coefficients;
    ImuPipelineSettings settings;
    if (ImuCoefficientsFromArray(&coefficients, IMU_COEFFICIENT_DATA, IMU_COEFFICIENT_COUNT) != 0) {
        *message = "the compiled-in coefficient data has the wrong size or layout version";
        return ModelError;
    }
    if (ImuPipelineSettingsFromArray(&settings, m->settings, IMU_SETTING_COUNT) != 0) {
        *message = "the settings array has the wrong size";
        return ModelError;
    }
    if (ImuPipelineSettingsCheck(&settings, message) != 0) {
        return ModelError;
    }
    ImuPipelineInitialise(&m->pipeline, &settings, &coefficients);
    m->initialised = 1;
    setInitialOutputs(m);
    return ModelOk;
}

void ModelDoStep(ModelData *m, double time) {
    ImuPipelineUpdate(&m->pipeline, time, m->inputs, m->outputs);
}
