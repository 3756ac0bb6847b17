/**
 * @file SensorModel.c
 * @brief The virtual-sensor FMU's model (model.h hooks): value references, initialisation from the trained
 *        chain compiled in (ImuCoefficientsData.h) and the noise parameters, the step, the checks of a
 *        restored state. The state machine, logging and serialisation are ModelCore.c's.
 */
#include "model.h"

#include <math.h>
#include <string.h>

#include "ImuCoefficientsData.h"
#include "ImuSensorData.h"
#include "ImuMath.h"
#include "ImuQuaternion.h"

/** Where a value reference lives in ModelData: its array and index there (config.h SENSOR_VR_SLOTS). */
typedef struct {
    char causality; /* 'i' inputs[], 'o' outputs[], 's' settings[] */
    int index;
} VariableSlot;

static const VariableSlot variableSlots[VR_COUNT] = SENSOR_VR_SLOTS;
static const SensorSettingRange settingRanges[SENSOR_SETTING_COUNT] = SENSOR_SETTING_RANGES;
/** The parameters' start values of this build (fmu/sensor_fmu.py writes ImuSensorData.h). */
static const double settingDefaults[SENSOR_SETTING_COUNT] = IMU_SENSOR_SETTING_DEFAULTS;

/* The noise parameters run triad by triad, figure by figure, axis by axis; then LSB and full scale per triad. */
typedef char SensorCheckNoiseLayout[SensorSetMagRandomWalkZ == SensorSetGyrNoiseDensityX + 26
                                    && SensorSetMagFullScale == SensorSetGyrLsb + 5 ? 1 : -1];

const char *ModelGuid(void) {
    return IMU_MODEL_GUID;
}

void ModelDataStart(ModelData *m) {
    int i;
    memset(m, 0, sizeof *m);
    for (i = 0; i < SENSOR_OUTPUT_COUNT; i++) {
        m->outputs[i] = NAN; /* no sample yet: an importer that passes them on gives ImuFusion an absent sensor */
    }
    memcpy(m->settings, settingDefaults, sizeof m->settings);
    m->inputs[SensorInTrueAccelZ] = -9.80665; /* at rest and level */
    m->inputs[SensorInTrueQW] = 1.0;
    m->inputs[SensorInTrueFieldX] = 20.0;
    m->inputs[SensorInTrueFieldZ] = 40.0;
    m->inputs[SensorInTrueTemp] = 25.0;
}

char ModelVariableType(unsigned int vr) {
    if (vr >= VR_COUNT) {
        return 0;
    }
    if (VR_IS_BOOLEAN(vr)) {
        return 'B';
    }
    return VR_IS_INTEGER(vr) ? 'I' : 'R';
}

double ModelParameterValue(const ModelData *m, unsigned int vr) {
    return m->settings[variableSlots[vr].index];
}

ModelStatus ModelSetParameter(ModelInstance *mi, const char *function, unsigned int vr, double value) {
    ModelData *m = &mi->state.model;
    if (variableSlots[vr].causality != 's') {
        return ModelFail(mi, function, "outputs cannot be set");
    }
    if (m->initialised) {
        ModelLog(mi, ModelError, LogStatusError,
                 "%s: parameters are fixed after initialisation (value reference %u)", function, vr);
        return ModelError;
    }
    m->settings[variableSlots[vr].index] = value;
    return ModelOk;
}

ModelStatus ModelGetReal(const ModelInstance *mi, const char *function, unsigned int vr, double *value) {
    const ModelData *m = &mi->state.model;
    if (vr == VR_TIME) {
        *value = mi->state.time;
        return ModelOk;
    }
    if (ModelVariableType(vr) != 'R') {
        return ModelBadReference(mi, function, vr, "Real/Float64");
    }
    switch (variableSlots[vr].causality) {
    case 'i':
        *value = m->inputs[variableSlots[vr].index];
        break;
    case 'o':
        *value = m->outputs[variableSlots[vr].index];
        break;
    default:
        *value = m->settings[variableSlots[vr].index];
    }
    return ModelOk;
}

ModelStatus ModelSetReal(ModelInstance *mi, const char *function, unsigned int vr, double value) {
    if (vr == VR_TIME) {
        return ModelFail(mi, function, "time is the independent variable: it cannot be set");
    }
    if (ModelVariableType(vr) != 'R') {
        return ModelBadReference(mi, function, vr, "Real/Float64");
    }
    if (variableSlots[vr].causality == 'i') {
        mi->state.model.inputs[variableSlots[vr].index] = value;
        return ModelOk;
    }
    return ModelSetParameter(mi, function, vr, value);
}

size_t ModelFloat64Count(unsigned int vr) {
    return vr == VR_TIME || ModelVariableType(vr) != 0 ? 1 : 0;
}

ModelStatus ModelGetFloat64s(const ModelInstance *mi, const char *function, unsigned int vr, double *values) {
    return ModelGetReal(mi, function, vr, values);
}

ModelStatus ModelSetFloat64s(ModelInstance *mi, const char *function, unsigned int vr, const double *values) {
    return ModelSetReal(mi, function, vr, *values);
}

/* ---- initialisation ------------------------------------------------------------------------- */

/** @brief NULL if every parameter is within its declared range, else the message of the first that is not. */
static const char *settingsProblem(const double *settings) {
    int i;
    for (i = 0; i < SENSOR_SETTING_COUNT; i++) {
        const SensorSettingRange *r = &settingRanges[i];
        const double v = settings[i];
        if (!(v >= r->min && v <= r->max) || (r->whole && v != floor(v))) {
            return r->message;
        }
    }
    return NULL;
}

/** @brief The noise of the parameters (SensorSetting order: figures triad by triad, then LSB and full scale). */
static void noiseFromSettings(const double *settings, ImuSensorNoise *noise) {
    int i, a;
    memset(noise, 0, sizeof *noise);
    for (i = 0; i < 3; i++) {
        for (a = 0; a < 3; a++) {
            noise->density[i][a] = settings[SensorSetGyrNoiseDensityX + 9 * i + a];
            noise->instability[i][a] = settings[SensorSetGyrNoiseDensityX + 9 * i + 3 + a];
            noise->walk[i][a] = settings[SensorSetGyrNoiseDensityX + 9 * i + 6 + a];
        }
        noise->lsb[i] = settings[SensorSetGyrLsb + 2 * i];
        noise->fullScale[i] = settings[SensorSetGyrFullScale + 2 * i];
    }
    noise->enabled = settings[SensorSetNoise] != 0.0;
    noise->seed = (int)settings[SensorSetSeed];
}

/** @brief The trained chain compiled in (settings and coefficients) into *settings and *c; NULL or what is wrong. */
static const char *trainedChain(ImuPipelineSettings *settings, ImuCoefficients *c) {
    const char *message = NULL;
    if (ImuPipelineSettingsFromArray(settings, IMU_SETTING_DEFAULTS, IMU_SETTING_COUNT) != 0
        || ImuPipelineSettingsCheck(settings, &message) != 0) {
        return message != NULL ? message : "the compiled-in settings of the trained chain do not fit its layout";
    }
    if (ImuCoefficientsFromArray(c, IMU_COEFFICIENT_DATA, IMU_COEFFICIENT_COUNT) != 0) {
        return "the compiled-in coefficients of the trained chain are invalid";
    }
    return NULL;
}

/** @brief Set up m's sensor from the compiled-in chain and m's parameters, keeping the evolving state when
 *         `keepState` (a restored FMU state); NULL or what is wrong. */
static const char *configure(ModelData *m, int keepState) {
    ImuPipelineSettings settings;
    ImuCoefficients coefficients;
    ImuSensorNoise noise;
    const ImuSensor kept = m->sensor; /* its evolving state, for a restored FMU state */
    const char *problem = settingsProblem(m->settings);
    if (problem == NULL) {
        problem = trainedChain(&settings, &coefficients);
    }
    if (problem != NULL) {
        return problem;
    }
    noiseFromSettings(m->settings, &noise);
    ImuSensorInitialise(&m->sensor, &settings, &coefficients, &noise);
    if (keepState) {
        m->sensor.align = kept.align;
        m->sensor.terms = kept.terms;
        m->sensor.psobp = kept.psobp;
        m->sensor.noiseState = kept.noiseState;
        m->sensor.hasSample = kept.hasSample;
        m->sensor.clock = kept.clock;
    }
    return NULL;
}

ModelStatus ModelExitInitialization(ModelInstance *mi, const char *function) {
    const char *problem;
    if (!ModelAllowed(mi, function, PhaseInitialization)) {
        return ModelError;
    }
    problem = configure(&mi->state.model, 0);
    if (problem != NULL) {
        mi->state.phase = PhaseError;
        ModelLog(mi, ModelError, LogStatusError, "%s: invalid parameter: %s", function, problem);
        return ModelError;
    }
    mi->state.model.initialised = 1;
    mi->state.phase = PhaseStepMode;
    ModelLog(mi, ModelOk, LogEvents, "%s: initialised at t = %g s", function, mi->state.time);
    return ModelOk;
}

/* ---- the step -------------------------------------------------------------------------------- */

/** @brief The true body rate, specific force and field (9 values) of the inputs; 0 if one is not finite or the
 *         attitude quaternion is zero. The field: the earth field (norm, dip, declination; true NED) turned into
 *         body axes by the attitude, or the body field inputs. */
static int truthOf(const ModelData *m, double truth[9]) {
    const double *in = m->inputs, *s = m->settings;
    int i;
    for (i = 0; i < 6; i++) {
        truth[i] = in[SensorInTrueRateX + i];
    }
    if (s[SensorSetFieldFromAttitude] != 0.0) {
        const double dip = s[SensorSetFieldDip], declination = s[SensorSetDeclination];
        const double ned[3] = {s[SensorSetFieldNorm] * cos(dip) * cos(declination),
                               s[SensorSetFieldNorm] * cos(dip) * sin(declination), s[SensorSetFieldNorm] * sin(dip)};
        double inverse[4] = {in[SensorInTrueQW], -in[SensorInTrueQX], -in[SensorInTrueQY], -in[SensorInTrueQZ]};
        const double norm = sqrt(inverse[0] * inverse[0] + inverse[1] * inverse[1] + inverse[2] * inverse[2]
                                 + inverse[3] * inverse[3]);
        if (!isfinite(norm) || norm == 0.0) {
            return 0;
        }
        ImuQuaternionNormalise(inverse);
        ImuQuaternionRotate(inverse, ned, &truth[6]);
    } else {
        for (i = 0; i < 3; i++) {
            truth[6 + i] = in[SensorInTrueFieldX + i];
        }
    }
    return ImuAllFinite(truth, 9);
}

ModelStatus ModelDoStep(ModelInstance *mi, const char *function, double t, double h) {
    ModelData *m = &mi->state.model;
    double truth[9], raw[9];
    int issues = 0, i;
    if (!isfinite(t) || !isfinite(h) || !(h > 0.0) || !isfinite(t + h)) {
        issues = ModelIssueStep;
    } else if (!truthOf(m, truth)) {
        issues = ModelIssueTruth;
    } else {
        ImuSensorUpdate(&m->sensor, t, h, truth, m->inputs[SensorInTrueTemp], &m->inputs[SensorInAux1], raw);
        for (i = 0; i < 9; i++) {
            m->outputs[SensorOutGyrX + i] = raw[i];
        }
        m->outputs[SensorOutTemp] = m->inputs[SensorInTrueTemp];
        mi->state.time = t + h;
    }
    if ((issues & ~m->issues) != 0) {
        ModelLog(mi, ModelWarning, LogBadInput, "%s: t = %g s: %s", function, t, issues == ModelIssueStep
                 ? "the step size is not finite and > 0: the step is discarded"
                 : "a true rate, specific force, attitude or field input is not finite (or the attitude quaternion is "
                   "zero): the sample is skipped and the outputs hold");
    } else if (issues == 0 && m->issues != 0) {
        ModelLog(mi, ModelOk, LogBadInput, "%s: t = %g s: valid input again", function, t);
    }
    m->issues = issues;
    return issues == ModelIssueStep ? ModelDiscard : (issues != 0 ? ModelWarning : ModelOk);
}

/* ---- FMU state ------------------------------------------------------------------------------- */

const char *ModelDataRestoredProblem(ModelState *s) {
    ModelData *m = &s->model;
    const char *problem;
    if (!isfinite(s->time)) {
        return "the time is not finite";
    }
    if (!m->initialised) {
        return NULL; /* the sensor is set up from the parameters before it runs */
    }
    problem = configure(m, 1);
    return problem != NULL ? problem : ImuSensorStateProblem(&m->sensor, s->time);
}
