/**
 * @file model.c
 * @brief The ImuFusion FMU's model (model.h hooks): value references, initialisation, the step and its
 *        bad-input handling, the checks of a restored state. The state machine and logging are ModelCore.c's.
 */
#include "model.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ImuCoefficientsData.h"

/** Where a value reference lives in ModelData: its array and index there (config.h IMU_VR_SLOTS). */
typedef struct {
    char causality; /* 'i' inputs[], 'o' outputs[], 's' settings[] */
    int index;      /* array index (ImuLayout.h order) */
} VariableSlot;

/** The slot of every value reference 0..VR_COUNT - 1, generated from the variable table. */
static const VariableSlot variableSlots[VR_COUNT] = IMU_VR_SLOTS;

/** The coefficient blocks (FMI 3 array parameters VR_COEFFICIENT_BLOCKS + b), in array order. */
static const ImuCoefficientBlock coefficientBlocks[IMU_COEFFICIENT_BLOCK_COUNT] = IMU_COEFFICIENT_BLOCKS;

/** Short names of the ModelIssue kinds, in bit order (for the recovery messages). */
static const char *const issueNames[MODEL_ISSUE_COUNT] = {
    "gyroscope", "accelerometer", "magnetometer", "magnetometer field", "temperature",
    "sample time order", "sample time gap", "step size", "non-finite output", "auxiliary", "calibrated-range"
};

typedef char ModelCheckIssues[(1 << (MODEL_ISSUE_COUNT - 1)) == ModelIssueCalibration ? 1 : -1];

const char *ModelGuid(void) {
    return IMU_MODEL_GUID;
}

/* ---- values ---------------------------------------------------------------------------------- */

/** @brief Outputs before the first sample: level, north-facing, zero signals, heading = declination [rad]. */
static void setInitialOutputs(ModelData *m) {
    ImuMount mount;
    if (ImuMountFromCodes(&mount, &m->settings[ImuSetMountX]) != 0) {
        ImuMountIdentity(&mount); /* initialisation refuses the codes; until then the identity */
    }
    ImuGuardInitialOutputs(m->settings[ImuSetDeclination], &mount, m->outputs);
    m->outputs[ImuOutCalibrationValid] = 1.0; /* no model has been evaluated outside its range */
}

void ModelDataStart(ModelData *m) {
    static const double startInputs[IMU_INPUT_COUNT] = {
        0.0, 0.0, 0.0,        /* rad/s */
        0.0, 0.0, -9.80665,   /* m/s^2: at rest and level */
        20.0, 0.0, 40.0,      /* uT: mid-latitude field, north and down */
        25.0,                 /* degC */
        0.0, 0.0, 0.0, 0.0    /* auxiliary inputs */
    };
    memset(m, 0, sizeof *m);
    memcpy(m->inputs, startInputs, sizeof startInputs);
    memcpy(m->settings, IMU_SETTING_DEFAULTS, sizeof m->settings);
    memcpy(m->coefficients, IMU_COEFFICIENT_DATA, sizeof m->coefficients);
    setInitialOutputs(m);
    {
        ImuMount identity;
        ImuMountIdentity(&identity); /* the default settings' mounting */
        ImuGuardReset(&m->runtime.guard, m->settings[ImuSetDeclination], &identity);
    }
}

/** @brief 1 if vr is an FMI 2 coefficient parameter (VR_COEFFICIENTS + its index in the coefficient array). */
static int isCoefficient(unsigned int vr) {
    return vr >= VR_COEFFICIENTS && vr - VR_COEFFICIENTS < (unsigned int)IMU_COEFFICIENT_COUNT;
}

/** @brief Array of vr ('i' inputs, 'o' outputs, 's' settings, 'c' coefficients; 0 for an unknown vr) and its index there. */
static char locate(unsigned int vr, int *index) {
    if (isCoefficient(vr)) {
        *index = (int)(vr - VR_COEFFICIENTS);
        return 'c';
    }
    if (vr >= VR_COUNT) {
        *index = -1;
        return 0;
    }
    *index = variableSlots[vr].index;
    return variableSlots[vr].causality;
}

double ModelParameterValue(const ModelData *m, unsigned int vr) {
    int index;
    (void)locate(vr, &index);
    return m->settings[index];
}

char ModelVariableType(unsigned int vr) {
    if (isCoefficient(vr)) {
        return 'R';
    }
    if (vr >= VR_COUNT) {
        return 0;
    }
    if (VR_IS_BOOLEAN(vr)) {
        return 'B';
    }
    return VR_IS_INTEGER(vr) ? 'I' : 'R';
}

ModelStatus ModelSetParameter(ModelInstance *mi, const char *function, unsigned int vr, double value) {
    ModelData *m = &mi->state.model;
    int index;
    const char causality = locate(vr, &index);
    if (causality != 's' && causality != 'c') {
        return ModelFail(mi, function, "outputs cannot be set");
    }
    if (m->initialised) {
        ModelLog(mi, ModelError, LogStatusError,
                 "%s: parameters are fixed after initialisation (value reference %u)", function, vr);
        return ModelError;
    }
    if (causality == 'c') {
        m->coefficients[index] = value;
        return ModelOk;
    }
    m->settings[index] = value;
    setInitialOutputs(m);
    return ModelOk;
}

ModelStatus ModelGetReal(const ModelInstance *mi, const char *function, unsigned int vr, double *value) {
    const ModelData *m = &mi->state.model;
    int index;
    char causality;
    if (vr == VR_TIME) {
        *value = mi->state.time;
        return ModelOk;
    }
    if (ModelVariableType(vr) != 'R') {
        return ModelBadReference(mi, function, vr, "Real/Float64");
    }
    causality = locate(vr, &index);
    if (causality == 'i') {
        *value = m->inputs[index];
    } else if (causality == 'o') {
        *value = m->outputs[index];
    } else if (causality == 'c') {
        *value = m->coefficients[index];
    } else {
        *value = m->settings[index];
    }
    return ModelOk;
}

ModelStatus ModelSetReal(ModelInstance *mi, const char *function, unsigned int vr, double value) {
    if (vr == VR_TIME) {
        return ModelFail(mi, function, "time is the independent variable: it cannot be set");
    }
    int index;
    if (ModelVariableType(vr) != 'R') {
        return ModelBadReference(mi, function, vr, "Real/Float64");
    }
    if (locate(vr, &index) == 'i') {
        mi->state.model.inputs[index] = value;
        return ModelOk;
    }
    return ModelSetParameter(mi, function, vr, value);
}

/** @brief The coefficient block of an FMI 3 array parameter vr, or NULL. */
static const ImuCoefficientBlock *coefficientBlock(unsigned int vr) {
    return vr >= VR_COEFFICIENT_BLOCKS && vr - VR_COEFFICIENT_BLOCKS < (unsigned int)IMU_COEFFICIENT_BLOCK_COUNT
        ? &coefficientBlocks[vr - VR_COEFFICIENT_BLOCKS] : NULL;
}

size_t ModelFloat64Count(unsigned int vr) {
    const ImuCoefficientBlock *block = coefficientBlock(vr);
    if (block != NULL) {
        return (size_t)block->size;
    }
    if (vr == VR_TIME) {
        return 1;
    }
    return !isCoefficient(vr) && ModelVariableType(vr) != 0 ? 1 : 0;
}

ModelStatus ModelGetFloat64s(const ModelInstance *mi, const char *function, unsigned int vr, double *values) {
    const ImuCoefficientBlock *block = coefficientBlock(vr);
    if (block != NULL) {
        memcpy(values, mi->state.model.coefficients + block->offset, (size_t)block->size * sizeof *values);
        return ModelOk;
    }
    if (isCoefficient(vr)) { /* FMI 2's scalar coefficient parameters are not FMI 3 variables */
        ModelLog(mi, ModelError, LogStatusError, "%s: unknown value reference %u", function, vr);
        return ModelError;
    }
    return ModelGetReal(mi, function, vr, values);
}

ModelStatus ModelSetFloat64s(ModelInstance *mi, const char *function, unsigned int vr, const double *values) {
    const ImuCoefficientBlock *block = coefficientBlock(vr);
    if (block != NULL) {
        if (mi->state.model.initialised) {
            ModelLog(mi, ModelError, LogStatusError,
                     "%s: parameters are fixed after initialisation (%s, value reference %u)", function, block->name, vr);
            return ModelError;
        }
        memcpy(mi->state.model.coefficients + block->offset, values, (size_t)block->size * sizeof *values);
        return ModelOk;
    }
    if (isCoefficient(vr)) {
        ModelLog(mi, ModelError, LogStatusError, "%s: unknown value reference %u", function, vr);
        return ModelError;
    }
    return ModelSetReal(mi, function, vr, *values);
}

/* ---- instance: logging and state machine ---------------------------------------------------- */










ModelStatus ModelExitInitialization(ModelInstance *mi, const char *function) {
    ModelData *m;
    const char *message = NULL;
    if (!ModelAllowed(mi, function, PhaseInitialization)) {
        return ModelError;
    }
    m = &mi->state.model;
    if (ImuRuntimeInitialise(&m->runtime, m->coefficients, IMU_COEFFICIENT_COUNT, m->settings,
                             IMU_SETTING_COUNT, &message) == ImuRuntimeOk) {
        m->initialised = 1;
        setInitialOutputs(m);
        mi->state.phase = PhaseStepMode;
        ModelLog(mi, ModelOk, LogEvents, "%s: initialised at t = %g s", function, mi->state.time);
        return ModelOk;
    }
    mi->state.phase = PhaseError;
    ModelLog(mi, ModelError, LogStatusError, "%s: invalid parameter: %s", function, message);
    return ModelError;
}


/* ---- bad input ------------------------------------------------------------------------------- */

/** @brief The warning that opens an episode of issue bit `issue` (the sample is in mi). */
static void logIssue(const ModelInstance *mi, const char *function, int issue, double t, double h) {
    const double *x = mi->state.model.inputs;
    const double fieldNorm = mi->state.model.settings[ImuSetFieldNorm];
    const ModelData *m = &mi->state.model;
    static const char *const hold = "the triad is skipped and its corrected outputs hold their last valid values until it recovers";
    switch (issue) {
    case ModelIssueGyr:
        ModelLog(mi, ModelWarning, LogBadInput, "%s: t = %g s: bad gyroscope input [%g, %g, %g] rad/s (not finite or beyond +-%g rad/s): %s",
                 function, t, x[ImuInGyrX], x[ImuInGyrY], x[ImuInGyrZ], IMU_GUARD_GYR_LIMIT, hold);
        break;
    case ModelIssueAcc:
        ModelLog(mi, ModelWarning, LogBadInput, "%s: t = %g s: bad accelerometer input [%g, %g, %g] m/s2 (not finite or beyond +-%g m/s2): %s",
                 function, t, x[ImuInAccX], x[ImuInAccY], x[ImuInAccZ], IMU_GUARD_ACC_LIMIT, hold);
        break;
    case ModelIssueMag:
        ModelLog(mi, ModelWarning, LogBadInput, "%s: t = %g s: bad magnetometer input [%g, %g, %g] uT (not finite, or an axis saturated at +-%g uT = %g x field_norm): %s",
                 function, t, x[ImuInMagX], x[ImuInMagY], x[ImuInMagZ], IMU_GUARD_MAG_SATURATION * fieldNorm, IMU_GUARD_MAG_SATURATION, hold);
        break;
    case ModelIssueMagZero:
        ModelLog(mi, ModelWarning, LogBadInput, "%s: t = %g s: magnetometer reads no field [%g, %g, %g] uT (magnitude below %g uT = %g x field_norm): %s",
                 function, t, x[ImuInMagX], x[ImuInMagY], x[ImuInMagZ], IMU_GUARD_MAG_MINIMUM * fieldNorm, IMU_GUARD_MAG_MINIMUM, hold);
        break;
    case ModelIssueTemp:
        ModelLog(mi, ModelWarning, LogBadInput, "%s: t = %g s: bad temperature %g degC (not finite or outside [%g, %g] degC): the last valid temperature %g degC is used until it recovers",
                 function, t, x[ImuInTemp], IMU_GUARD_TEMP_MIN, IMU_GUARD_TEMP_MAX, m->runtime.guard.lastValidTemp);
        break;
    case ModelIssueOrder:
        ModelLog(mi, ModelWarning, LogBadInput, "%s: t = %g s: the time since the previous sample (%g s) is not finite and > 0: the sample is fused without propagating the attitude",
                 function, t, m->stepSize);
        break;
    case ModelIssueGap:
        ModelLog(mi, ModelWarning, LogBadInput, "%s: t = %g s: a gap of %g s since the previous sample (more than %g x the nominal step %g s): "
                 "nothing is integrated across it, the attitude restarts from the accelerometer and magnetometer as at power-on (gyro bias kept)",
                 function, t, m->stepSize, IMU_GUARD_GAP_STEPS, ImuGuardNominalStep(&m->runtime.guard));
        break;
    case ModelIssueStep:
        ModelLog(mi, ModelWarning, LogBadInput, "%s: t = %g s: communicationStepSize = %g s must be finite and > 0 (and t and t + h finite): the step is discarded, outputs hold their last values",
                 function, t, h);
        break;
    case ModelIssueAux: {
        int i = 0;
        while (i < IMU_TERMS_AUX_COUNT - 1
               && (isfinite(x[ImuInAux1 + i]) || !ImuTermsUseSignal(&m->runtime.pipeline.coefficients.terms, ImuSigAux1 + i))) {
            i++;
        }
        ModelLog(mi, ModelWarning, LogBadInput, "%s: t = %g s: bad auxiliary input aux_%d = %g (not finite): the correction terms on it use its last "
                 "finite value %g until it recovers (NaN: skipped)", function, t, i + 1, x[ImuInAux1 + i], m->runtime.guard.lastValidAux[i]);
        break;
    }
    case ModelIssueCalibration: {
        char ranges[MODEL_LOG_BUFFER_SIZE / 2];
        const int rangeIssues = m->runtime.pipeline.rangeIssues;
        ImuPipelineDescribeRanges(&m->runtime.pipeline, rangeIssues, ranges, sizeof ranges);
        if (rangeIssues & (ImuRangeThermalGyr | ImuRangeThermalAcc | ImuRangeThermalMag | ImuRangePsoBp)) {
            ModelLog(mi, ModelWarning, LogBadInput, "%s: t = %g s: temperature %g degC: outside the calibrated range of the %s: the gain/bias models "
                     "%s, the other models hold their edge value, and calibration_valid = 0 until they return",
                     function, t, x[ImuInTemp], ranges,
                     m->runtime.pipeline.settings.thermalContinuation
                         ? "continue along their tangent at the range edge (at most one calibrated span)"
                         : "hold their edge value");
        } else {
            ModelLog(mi, ModelWarning, LogBadInput, "%s: t = %g s: an input outside the calibrated range of the %s: "
                     "each model is evaluated with its inputs clamped to that range (no extrapolation) and calibration_valid = 0 until they return",
                     function, t, ranges);
        }
        break;
    }
    default:
        ModelLog(mi, ModelWarning, LogBadInput, "%s: t = %g s: an output was not finite for valid inputs: the outputs hold their last finite values",
                 function, t);
        break;
    }
}

/** @brief Log the episodes that start (Warning) and end (OK, logBadInput) when the issue bits
 *         change to `issues`; store them; Warning if any is set. */
static ModelStatus updateIssues(ModelInstance *mi, const char *function, int issues, double t, double h) {
    const int previous = mi->state.model.issues;
    int k;
    mi->state.model.issues = issues;
    for (k = 0; k < MODEL_ISSUE_COUNT; k++) {
        const int bit = 1 << k;
        if ((issues & bit) && !(previous & bit)) {
            logIssue(mi, function, bit, t, h);
        } else if (!(issues & bit) && (previous & bit)) {
            ModelLog(mi, ModelOk, LogBadInput, "%s: t = %g s: %s input valid again", function, t, issueNames[k]);
        }
    }
    return issues ? ModelWarning : ModelOk;
}

/** @brief One OK message (logEvents) per sensor that becomes absent at the first sample or delivers
 *         its first valid sample later (presentBefore: ImuGuard.present before the step). */
static void logPresence(const ModelInstance *mi, const char *function, int firstSample, int presentBefore, double t) {
    static const char *const name[] = {"gyroscope", "accelerometer", "magnetometer", "magnetometer field", "temperature"};
    static const char *const consequence[] = {
        "rate_x, rate_y, rate_z are NaN and the attitude comes from the accelerometer and magnetometer alone",
        "accel_x, accel_y, accel_z are NaN and roll and pitch come from the gyroscope alone, from a level start",
        "field_x, field_y, field_z are NaN and yaw comes from the gyroscope alone, relative to the heading at the first sample, and drifts with the residual gyro bias",
        "", /* ImuGuardIssueMagZero is no sensor */
        "the gain/bias models are evaluated at their reference temperature t0 (the centre of the range they were fitted on), the PSO-BP network at the centre of its range with rate 0, and correction terms on the temperature are skipped"
    };
    const int present = mi->state.model.runtime.guard.present;
    int k;
    for (k = 0; k < 5; k++) {
        const int bit = 1 << k;
        if (!(IMU_GUARD_SENSORS & bit)) {
            continue;
        }
        if (firstSample && !(present & bit)) {
            ModelLog(mi, ModelOk, LogEvents, "%s: t = %g s: no %s input (NaN): treated as an absent sensor until it delivers a valid sample: %s",
                     function, t, name[k], consequence[k]);
        } else if (!firstSample && (present & bit) && !(presentBefore & bit)) {
            ModelLog(mi, ModelOk, LogEvents, "%s: t = %g s: first valid %s sample: no longer absent", function, t, name[k]);
        }
    }
}

ModelStatus ModelDoStep(ModelInstance *mi, const char *function, double t, double h) {
    ModelData *m = &mi->state.model;
    const int presentBefore = m->runtime.guard.present, firstSample = !m->runtime.guard.hasSample;
    double out[IMU_OUTPUT_COUNT];
    ModelStatus status;
    int issues;
    if (!isfinite(t) || !isfinite(h) || !(h > 0.0) || !isfinite(t + h)) {
        updateIssues(mi, function, m->issues | ModelIssueStep, t, h);
        return ModelDiscard;
    }
    /* The sample consumed now was taken the previous step size after the previous one: the
     * importer's h, never a difference of absolute times (which loses the step beyond ~1e13 s). */
    issues = ImuRuntimeStep(&m->runtime, m->stepSize, m->inputs, out);
    if (m->runtime.pipeline.rangeIssues != 0) {
        issues |= ModelIssueCalibration;
    }
    memcpy(m->outputs, out, sizeof m->outputs);
    mi->state.time = t + h;
    logPresence(mi, function, firstSample, presentBefore, t);
    status = updateIssues(mi, function, issues, t, h);
    m->stepSize = h;
    return status;
}

/* ---- FMU state ------------------------------------------------------------------------------- */







/** @brief 1 if the n values are all finite. */
static int allFinite(const double *x, int n) {
    int i;
    for (i = 0; i < n; i++) {
        if (!isfinite(x[i])) {
            return 0;
        }
    }
    return 1;
}

/** @brief Replace what the pipeline of an initialised state derives from its parameters (settings,
 *         coefficients of every stage, the derived values of the attitude, particle filter and
 *         PSO-BP) by values built from m->settings and m->coefficients, so no
 *         restored count, size or index of them is used; NULL, or what is wrong. */
static const char *rederivePipeline(ModelData *m) {
    const char *problem = NULL;
    (void)ImuRuntimeConfigure(&m->runtime, m->coefficients, IMU_COEFFICIENT_COUNT, m->settings,
                              IMU_SETTING_COUNT, &problem);
    return problem;
}

const char *ModelDataRestoredProblem(ModelState *s) {
    ModelData *m = &s->model;
    const char *problem;
    if ((m->runtime.guard.hasSample != 0 && m->runtime.guard.hasSample != 1) || (m->runtime.guard.present & ~IMU_GUARD_SENSORS) != 0) {
        return "the guard's hasSample or present bits are invalid";
    }
    if (!ImuGuardStepsValid(&m->runtime.guard)) {
        return "the guard's step history (count, head or a step) is invalid";
    }
    if (!isfinite(s->time) || !isfinite(m->stepSize) || !allFinite(m->runtime.guard.held, IMU_OUTPUT_COUNT)) {
        return "the time, step size [s] or held outputs are not finite";
    }
    if (!ImuGuardClockValid(&m->runtime.guard)) {
        return "the guard's clock [s] is not finite, >= 0 and fine enough to resolve the nominal step";
    }
    if (!m->initialised) {
        return NULL; /* the pipeline is initialised from the parameters before it runs */
    }
    problem = rederivePipeline(m);
    if (problem != NULL) {
        return problem;
    }
    return ImuPipelineStateProblem(&m->runtime.pipeline, m->runtime.guard.clock);
}


