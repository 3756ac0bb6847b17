/**
 * @file ModelCore.c
 * @brief What every FMU of this source tree shares (model.h): the co-simulation state machine, logging
 *        and the FMU state's copy, serialisation and checks. The model's own values, step and state
 *        checks come from its hooks (model.c for ImuFusion, sensor/SensorModel.c for the virtual sensor).
 */
#include "model.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MODEL_STATE_MAGIC 0x494D5546u /* "IMUF" */
#define MODEL_FNV_OFFSET 14695981039346656037ull
#define MODEL_FNV_PRIME 1099511628211ull

static const char *const logCategoryNames[MODEL_LOG_CATEGORY_COUNT] = {
    "logEvents", "logBadInput", "logStatusWarning", "logStatusError"
};

void ModelLog(const ModelInstance *mi, ModelStatus status, ModelLogCategory category, const char *format, ...) {
    char buffer[MODEL_LOG_BUFFER_SIZE];
    va_list args;
    if (mi == NULL || mi->log == NULL || !(status >= ModelWarning || (mi->loggingOn && mi->categoryOn[category]))) {
        return;
    }
    va_start(args, format);
    vsnprintf(buffer, sizeof buffer, format, args);
    va_end(args);
    mi->log(mi->environment, status, logCategoryNames[category], buffer);
}

ModelStatus ModelFail(const ModelInstance *mi, const char *function, const char *message) {
    ModelLog(mi, ModelError, LogStatusError, "%s: %s", function, message);
    return ModelError;
}

int ModelGiven(const ModelInstance *mi, const char *function, const void *pointer, const char *what) {
    if (pointer == NULL) {
        ModelLog(mi, ModelError, LogStatusError, "%s: %s is NULL", function, what);
        return 0;
    }
    return 1;
}

int ModelArraysGiven(const ModelInstance *mi, const char *function, size_t n, const void *vr, const void *values) {
    return n == 0 || (ModelGiven(mi, function, vr, "the value reference array") &&
                      ModelGiven(mi, function, values, "the value array"));
}

int ModelAllowed(const ModelInstance *mi, const char *function, int phases) {
    if (mi == NULL) {
        return 0;
    }
    if ((mi->state.phase & phases) == 0) {
        ModelLog(mi, ModelError, LogStatusError, "%s must not be called in the current state", function);
        return 0;
    }
    return 1;
}

ModelStatus ModelSetDebugLogging(ModelInstance *mi, int loggingOn, size_t n, const char *const categories[]) {
    size_t i;
    int k;
    if (n > 0 && categories == NULL) {
        return ModelFail(mi, "SetDebugLogging", "nCategories > 0 but the category list is NULL");
    }
    for (i = 0; i < n; i++) {
        if (categories[i] == NULL) {
            ModelLog(mi, ModelError, LogStatusError, "SetDebugLogging: category %lu of the list is NULL", (unsigned long)i);
            return ModelError;
        }
    }
    mi->loggingOn = loggingOn != 0;
    for (k = 0; k < MODEL_LOG_CATEGORY_COUNT; k++) {
        mi->categoryOn[k] = n == 0;
    }
    for (i = 0; i < n; i++) {
        for (k = 0; k < MODEL_LOG_CATEGORY_COUNT && strcmp(categories[i], logCategoryNames[k]) != 0; k++) {
        }
        if (k == MODEL_LOG_CATEGORY_COUNT) {
            ModelLog(mi, ModelWarning, LogStatusWarning, "SetDebugLogging: unknown log category '%s'", categories[i]);
            return ModelWarning;
        }
        mi->categoryOn[k] = 1;
    }
    return ModelOk;
}

void ModelReset(ModelInstance *mi) {
    ModelState *s = &mi->state;
    memset(s, 0, sizeof *s);
    s->header.magic = MODEL_STATE_MAGIC;
    s->header.size = (unsigned int)sizeof(ModelState);
    strncpy(s->header.guid, ModelGuid(), MODEL_GUID_SIZE - 1);
    s->phase = PhaseInstantiated;
    s->time = 0.0;
    ModelDataStart(&s->model);
}

void ModelInstanceInitialise(ModelInstance *mi, ModelLogCallback log, void *environment, int loggingOn) {
    mi->log = log;
    mi->environment = environment;
    ModelSetDebugLogging(mi, loggingOn, 0, NULL);
    ModelReset(mi);
}

ModelStatus ModelEnterInitialization(ModelInstance *mi, const char *function, double startTime,
                                     int stopTimeDefined, double stopTime) {
    if (!ModelAllowed(mi, function, PhaseInstantiated)) {
        return ModelError;
    }
    if (!isfinite(startTime) || (stopTimeDefined && !(stopTime >= startTime))) {
        return ModelFail(mi, function, "startTime must be finite and stopTime not before it");
    }
    mi->state.time = startTime;
    mi->state.phase = PhaseInitialization;
    return ModelOk;
}

ModelStatus ModelTerminate(ModelInstance *mi, const char *function) {
    if (!ModelAllowed(mi, function, PhaseStepMode)) {
        return ModelError;
    }
    mi->state.phase = PhaseTerminated;
    return ModelOk;
}

unsigned long long ModelStateChecksum(const void *bytes, size_t size) {
    const unsigned char *b = (const unsigned char *)bytes;
    unsigned long long hash = MODEL_FNV_OFFSET;
    size_t i;
    for (i = 0; i < size; i++) {
        hash = (hash ^ b[i]) * MODEL_FNV_PRIME;
    }
    return hash;
}

/** @brief Checksum of the body of a serialized state: every byte after the header. */
static unsigned long long bodyChecksum(const void *bytes) {
    return ModelStateChecksum((const unsigned char *)bytes + sizeof(ModelStateHeader),
                              sizeof(ModelState) - sizeof(ModelStateHeader));
}

void ModelSerialize(const ModelState *state, void *bytes) {
    ModelStateHeader header;
    memcpy(bytes, state, sizeof(ModelState));
    memcpy(&header, bytes, sizeof header);
    header.checksum = bodyChecksum(bytes);
    memcpy(bytes, &header, sizeof header);
}

/** @brief NULL if *h heads a state of this binary, else what is wrong with it. */
static const char *stateProblem(const ModelStateHeader *h) {
    if (h->magic != MODEL_STATE_MAGIC || h->size != sizeof(ModelState)) {
        return "the bytes are not an " MODEL_NAME " FMU state of this binary";
    }
    if (strncmp(h->guid, ModelGuid(), MODEL_GUID_SIZE) != 0) {
        return "the FMU state was made by a different build (GUID differs)";
    }
    return NULL;
}

/** @brief 1 if phase is exactly one ModelPhase. */
static int validPhase(int phase) {
    return phase == PhaseInstantiated || phase == PhaseInitialization || phase == PhaseStepMode
        || phase == PhaseTerminated || phase == PhaseError;
}

/** @brief What every model's restored state must satisfy: a phase of the state machine, initialised 0 or 1 (and 1
 *         in Step Mode or Terminated), only ModelIssue bits; NULL, or what is wrong. */
static const char *commonStateProblem(const ModelState *s) {
    const ModelData *m = &s->model;
    if (!validPhase(s->phase)) {
        return "phase is not a state-machine phase";
    }
    if (m->initialised != 0 && m->initialised != 1) {
        return "initialised is not 0 or 1";
    }
    if ((s->phase & (PhaseStepMode | PhaseTerminated)) && !m->initialised) {
        return "the phase is Step Mode or Terminated but the model is not initialised";
    }
    if ((m->issues & ~((1 << MODEL_ISSUE_COUNT) - 1)) != 0) {
        return "issues has bits that are no ModelIssue";
    }
    return NULL;
}

ModelStatus ModelSetState(ModelInstance *mi, const char *function, const ModelState *state) {
    ModelState *restored;
    const char *problem;
    if (state == NULL) {
        return ModelFail(mi, function, "the FMU state is NULL");
    }
    problem = stateProblem(&state->header);
    if (problem != NULL) {
        return ModelFail(mi, function, problem);
    }
    restored = (ModelState *)malloc(sizeof *restored);
    if (restored == NULL) {
        return ModelFail(mi, function, "out of memory");
    }
    memcpy(restored, state, sizeof *restored);
    problem = commonStateProblem(restored);
    if (problem == NULL) {
        problem = ModelDataRestoredProblem(restored);
    }
    if (problem == NULL) {
        memcpy(&mi->state, restored, sizeof(ModelState));
        mi->state.header.checksum = 0;
    } else {
        ModelLog(mi, ModelError, LogStatusError, "%s: invalid FMU state: %s", function, problem);
    }
    free(restored);
    return problem == NULL ? ModelOk : ModelError;
}

ModelStatus ModelCheckSerialized(const ModelInstance *mi, const char *function, const void *bytes, size_t size) {
    ModelStateHeader incoming;
    const char *problem;
    if (bytes == NULL || size != sizeof(ModelState)) {
        return ModelFail(mi, function, "the serialized FMU state has the wrong size for this binary");
    }
    memcpy(&incoming, bytes, sizeof incoming); /* the header is the state's first member */
    problem = stateProblem(&incoming);
    if (problem == NULL && incoming.checksum != bodyChecksum(bytes)) {
        problem = "the serialized FMU state is corrupt (FNV-1a 64 checksum of its body differs)";
    }
    return problem == NULL ? ModelOk : ModelFail(mi, function, problem);
}

/* ---- typed access shared by the models (through their hooks) --------------------------------- */

ModelStatus ModelBadReference(const ModelInstance *mi, const char *function, unsigned int vr, const char *type) {
    if (ModelVariableType(vr) == 0) {
        ModelLog(mi, ModelError, LogStatusError, "%s: unknown value reference %u", function, vr);
    } else {
        ModelLog(mi, ModelError, LogStatusError, "%s: value reference %u is not a %s variable", function, vr, type);
    }
    return ModelError;
}

ModelStatus ModelGetBoolean(const ModelInstance *mi, const char *function, unsigned int vr, int *value) {
    if (ModelVariableType(vr) != 'B') {
        return ModelBadReference(mi, function, vr, "Boolean");
    }
    *value = ModelParameterValue(&mi->state.model, vr) != 0.0;
    return ModelOk;
}

ModelStatus ModelSetBoolean(ModelInstance *mi, const char *function, unsigned int vr, int value) {
    if (ModelVariableType(vr) != 'B') {
        return ModelBadReference(mi, function, vr, "Boolean");
    }
    return ModelSetParameter(mi, function, vr, value ? 1.0 : 0.0);
}

ModelStatus ModelGetInteger(const ModelInstance *mi, const char *function, unsigned int vr, int *value) {
    if (ModelVariableType(vr) != 'I') {
        return ModelBadReference(mi, function, vr, "Integer/Int32");
    }
    *value = (int)ModelParameterValue(&mi->state.model, vr);
    return ModelOk;
}

ModelStatus ModelSetInteger(ModelInstance *mi, const char *function, unsigned int vr, int value) {
    if (ModelVariableType(vr) != 'I') {
        return ModelBadReference(mi, function, vr, "Integer/Int32");
    }
    return ModelSetParameter(mi, function, vr, (double)value);
}
