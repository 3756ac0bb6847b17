/**
 * @file fmi2Functions.c
 * @brief FMI 2.0 co-simulation interface of ImuFusion: state machine, logging, FMU state.
 *
 * The only file that includes FMI headers. It exports exactly the 34 FMI 2.0 co-simulation
 * functions (no prefix); everything else here is static.
 */
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "fmi2Functions.h"
#include "model.h"

/** Phases of the FMI 2.0 co-simulation state machine (one bit each). */
typedef enum {
    PhaseInstantiated = 1 << 0,
    PhaseInitialization = 1 << 1,
    PhaseStepComplete = 1 << 2,
    PhaseTerminated = 1 << 3,
    PhaseError = 1 << 4
} Phase;

#define ANY_PHASE (PhaseInstantiated | PhaseInitialization | PhaseStepComplete | PhaseTerminated | PhaseError)
#define RUNNING_PHASES (PhaseInstantiated | PhaseInitialization | PhaseStepComplete)

/** Log categories, in the order of LogCategories in modelDescription.xml. */
typedef enum {
    LogEvents,
    LogStatusWarning,
    LogStatusError,
    LOG_CATEGORY_COUNT
} LogCategory;

static const char *const logCategoryNames[LOG_CATEGORY_COUNT] = {
    "logEvents", "logStatusWarning", "logStatusError"
};

#define STATE_MAGIC 0x494D5546u /* "IMUF" */
#define LOG_BUFFER_SIZE 512

/** The FMU state: a copy of everything that evolves, so get/set/serialize are copies. */
typedef struct {
    unsigned int magic;  /* STATE_MAGIC */
    unsigned int size;   /* sizeof(FmuState) */
    int phase;           /* Phase when the state was taken */
    double time;         /* s, current communication point */
    ModelData model;
} FmuState;

/** One FMU instance. */
typedef struct {
    fmi2CallbackLogger logger;
    fmi2CallbackAllocateMemory allocateMemory;
    fmi2CallbackFreeMemory freeMemory;
    fmi2ComponentEnvironment environment;
    char *instanceName;
    int loggingOn;
    int categoryOn[LOG_CATEGORY_COUNT];
    FmuState state;
} Instance;

/** @brief Send a printf-style message to the importer's logger (errors and warnings always, events when enabled). */
static void logMessage(const Instance *inst, fmi2Status status, LogCategory category, const char *format, ...) {
    char buffer[LOG_BUFFER_SIZE];
    va_list args;
    int isProblem = status == fmi2Warning || status == fmi2Error || status == fmi2Fatal;
    if (inst->logger == NULL || !(isProblem || (inst->loggingOn && inst->categoryOn[category]))) {
        return;
    }
    va_start(args, format);
    vsnprintf(buffer, sizeof buffer, format, args);
    va_end(args);
    inst->logger(inst->environment, inst->instanceName, status, logCategoryNames[category], "%s", buffer);
}

/** @brief Log an error and return fmi2Error. */
static fmi2Status fail(const Instance *inst, const char *function, const char *message) {
    logMessage(inst, fmi2Error, LogStatusError, "%s: %s", function, message);
    return fmi2Error;
}

/** @brief Check that c is an instance and that function may be called in its current phase. */
static int allowed(const Instance *inst, const char *function, int phases) {
    if (inst == NULL) {
        return 0;
    }
    if ((inst->state.phase & phases) == 0) {
        logMessage(inst, fmi2Error, LogStatusError, "%s must not be called in the current state", function);
        return 0;
    }
    return 1;
}

/** @brief Allocate n zeroed bytes through the importer's allocator. */
static void *allocate(const Instance *inst, size_t n) {
    return inst->allocateMemory(1, n);
}

/* ---- common functions ---------------------------------------------------------------------- */

const char *fmi2GetTypesPlatform(void) {
    return fmi2TypesPlatform;
}

const char *fmi2GetVersion(void) {
    return fmi2Version;
}

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories, const fmi2String categories[]) {
    Instance *inst = (Instance *)c;
    size_t i;
    int k;
    if (!allowed(inst, "fmi2SetDebugLogging", ANY_PHASE)) {
        return fmi2Error;
    }
    inst->loggingOn = loggingOn != fmi2False;
    for (k = 0; k < LOG_CATEGORY_COUNT; k++) {
        inst->categoryOn[k] = nCategories == 0;
    }
    for (i = 0; i < nCategories; i++) {
        for (k = 0; k < LOG_CATEGORY_COUNT && strcmp(categories[i], logCategoryNames[k]) != 0; k++) {
        }
        if (k == LOG_CATEGORY_COUNT) {
            logMessage(inst, fmi2Warning, LogStatusWarning, "fmi2SetDebugLogging: unknown log category '%s'", categories[i]);
            return fmi2Warning;
        }
        inst->categoryOn[k] = 1;
    }
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    Instance *inst;
    const char *name = instanceName != NULL ? instanceName : "";
    (void)fmuResourceLocation;
    (void)visible;
    if (functions == NULL || functions->allocateMemory == NULL || functions->freeMemory == NULL) {
        return NULL;
    }
    if (fmuType != fmi2CoSimulation || fmuGUID == NULL || strcmp(fmuGUID, ModelGuid()) != 0) {
        if (functions->logger != NULL) {
            functions->logger(functions->componentEnvironment, name, fmi2Error, "logStatusError",
                              "fmi2Instantiate: %s", fmuType != fmi2CoSimulation
                                  ? MODEL_NAME " supports co-simulation only"
                                  : "the GUID does not match the one this binary was built with");
        }
        return NULL;
    }
    inst = (Instance *)functions->allocateMemory(1, sizeof(Instance));
    if (inst == NULL) {
        return NULL;
    }
    inst->logger = functions->logger;
    inst->allocateMemory = functions->allocateMemory;
    inst->freeMemory = functions->freeMemory;
    inst->environment = functions->componentEnvironment;
    inst->instanceName = (char *)allocate(inst, strlen(name) + 1);
    if (inst->instanceName == NULL) {
        functions->freeMemory(inst);
        return NULL;
    }
    memcpy(inst->instanceName, name, strlen(name) + 1);
    inst->state.magic = STATE_MAGIC;
    inst->state.size = (unsigned int)sizeof(FmuState);
    inst->state.phase = PhaseInstantiated;
    inst->state.time = 0.0;
    ModelSetStartValues(&inst->state.model);
    fmi2SetDebugLogging(inst, loggingOn, 0, NULL);
    logMessage(inst, fmi2OK, LogEvents, "fmi2Instantiate: instance '%s' created", name);
    return inst;
}

void fmi2FreeInstance(fmi2Component c) {
    Instance *inst = (Instance *)c;
    if (inst == NULL) {
        return;
    }
    inst->freeMemory(inst->instanceName);
    inst->freeMemory(inst);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    Instance *inst = (Instance *)c;
    (void)toleranceDefined;
    (void)tolerance;
    if (!allowed(inst, "fmi2SetupExperiment", PhaseInstantiated)) {
        return fmi2Error;
    }
    if (stopTimeDefined && stopTime < startTime) {
        return fail(inst, "fmi2SetupExperiment", "stopTime is before startTime");
    }
    inst->state.time = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    Instance *inst = (Instance *)c;
    if (!allowed(inst, "fmi2EnterInitializationMode", PhaseInstantiated)) {
        return fmi2Error;
    }
    inst->state.phase = PhaseInitialization;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Instance *inst = (Instance *)c;
    const char *message = "";
    if (!allowed(inst, "fmi2ExitInitializationMode", PhaseInitialization)) {
        return fmi2Error;
    }
    if (ModelInitialise(&inst->state.model, &message) != ModelOk) {
        inst->state.phase = PhaseError;
        return fail(inst, "fmi2ExitInitializationMode", message);
    }
    inst->state.phase = PhaseStepComplete;
    logMessage(inst, fmi2OK, LogEvents, "fmi2ExitInitializationMode: initialised at t = %g s", inst->state.time);
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    Instance *inst = (Instance *)c;
    if (!allowed(inst, "fmi2Terminate", PhaseStepComplete)) {
        return fmi2Error;
    }
    inst->state.phase = PhaseTerminated;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    Instance *inst = (Instance *)c;
    if (!allowed(inst, "fmi2Reset", ANY_PHASE)) {
        return fmi2Error;
    }
    inst->state.phase = PhaseInstantiated;
    inst->state.time = 0.0;
    ModelSetStartValues(&inst->state.model);
    return fmi2OK;
}

/* ---- getting and setting values ------------------------------------------------------------- */

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    Instance *inst = (Instance *)c;
    const char *message = "";
    size_t i;
    if (!allowed(inst, "fmi2GetReal", ANY_PHASE)) {
        return fmi2Error;
    }
    for (i = 0; i < nvr; i++) {
        if (ModelGetReal(&inst->state.model, vr[i], &value[i], &message) != ModelOk) {
            logMessage(inst, fmi2Error, LogStatusError, "fmi2GetReal: %s (value reference %u)", message, vr[i]);
            return fmi2Error;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[]) {
    Instance *inst = (Instance *)c;
    (void)value;
    if (!allowed(inst, "fmi2GetInteger", ANY_PHASE)) {
        return fmi2Error;
    }
    if (nvr > 0) {
        logMessage(inst, fmi2Error, LogStatusError, "fmi2GetInteger: " MODEL_NAME " has no Integer variables (value reference %u)", vr[0]);
        return fmi2Error;
    }
    return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[]) {
    Instance *inst = (Instance *)c;
    const char *message = "";
    size_t i;
    int v;
    if (!allowed(inst, "fmi2GetBoolean", ANY_PHASE)) {
        return fmi2Error;
    }
    for (i = 0; i < nvr; i++) {
        if (ModelGetBoolean(&inst->state.model, vr[i], &v, &message) != ModelOk) {
            logMessage(inst, fmi2Error, LogStatusError, "fmi2GetBoolean: %s (value reference %u)", message, vr[i]);
            return fmi2Error;
        }
        value[i] = v ? fmi2True : fmi2False;
    }
    return fmi2OK;
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[]) {
    Instance *inst = (Instance *)c;
    (void)value;
    if (!allowed(inst, "fmi2GetString", ANY_PHASE)) {
        return fmi2Error;
    }
    if (nvr > 0) {
        logMessage(inst, fmi2Error, LogStatusError, "fmi2GetString: " MODEL_NAME " has no String variables (value reference %u)", vr[0]);
        return fmi2Error;
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    Instance *inst = (Instance *)c;
    const char *message = "";
    size_t i;
    if (!allowed(inst, "fmi2SetReal", RUNNING_PHASES)) {
        return fmi2Error;
    }
    for (i = 0; i < nvr; i++) {
        if (ModelSetReal(&inst->state.model, vr[i], value[i], &message) != ModelOk) {
            logMessage(inst, fmi2Error, LogStatusError, "fmi2SetReal: %s (value reference %u)", message, vr[i]);
            return fmi2Error;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[]) {
    Instance *inst = (Instance *)c;
    (void)value;
    if (!allowed(inst, "fmi2SetInteger", RUNNING_PHASES)) {
        return fmi2Error;
    }
    if (nvr > 0) {
        logMessage(inst, fmi2Error, LogStatusError, "fmi2SetInteger: " MODEL_NAME " has no Integer variables (value reference %u)", vr[0]);
        return fmi2Error;
    }
    return fmi2OK;
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[]) {
    Instance *inst = (Instance *)c;
    const char *message = "";
    size_t i;
    if (!allowed(inst, "fmi2SetBoolean", RUNNING_PHASES)) {
        return fmi2Error;
    }
    for (i = 0; i < nvr; i++) {
        if (ModelSetBoolean(&inst->state.model, vr[i], value[i] != fmi2False, &message) != ModelOk) {
            logMessage(inst, fmi2Error, LogStatusError, "fmi2SetBoolean: %s (value reference %u)", message, vr[i]);
            return fmi2Error;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[]) {
    Instance *inst = (Instance *)c;
    (void)value;
    if (!allowed(inst, "fmi2SetString", RUNNING_PHASES)) {
        return fmi2Error;
    }
    if (nvr > 0) {
        logMessage(inst, fmi2Error, LogStatusError, "fmi2SetString: " MODEL_NAME " has no String variables (value reference %u)", vr[0]);
        return fmi2Error;
    }
    return fmi2OK;
}

/* ---- FMU state: copies of FmuState ---------------------------------------------------------- */

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    Instance *inst = (Instance *)c;
    if (!allowed(inst, "fmi2GetFMUstate", ANY_PHASE)) {
        return fmi2Error;
    }
    if (*FMUstate == NULL) {
        *FMUstate = allocate(inst, sizeof(FmuState));
        if (*FMUstate == NULL) {
            return fail(inst, "fmi2GetFMUstate", "out of memory");
        }
    }
    memcpy(*FMUstate, &inst->state, sizeof(FmuState));
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    Instance *inst = (Instance *)c;
    if (!allowed(inst, "fmi2SetFMUstate", ANY_PHASE)) {
        return fmi2Error;
    }
    if (FMUstate == NULL) {
        return fail(inst, "fmi2SetFMUstate", "the FMU state is NULL");
    }
    memcpy(&inst->state, FMUstate, sizeof(FmuState));
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    Instance *inst = (Instance *)c;
    if (!allowed(inst, "fmi2FreeFMUstate", ANY_PHASE)) {
        return fmi2Error;
    }
    if (FMUstate != NULL && *FMUstate != NULL) {
        inst->freeMemory(*FMUstate);
        *FMUstate = NULL;
    }
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    Instance *inst = (Instance *)c;
    (void)FMUstate;
    if (!allowed(inst, "fmi2SerializedFMUstateSize", ANY_PHASE)) {
        return fmi2Error;
    }
    *size = sizeof(FmuState);
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[], size_t size) {
    Instance *inst = (Instance *)c;
    if (!allowed(inst, "fmi2SerializeFMUstate", ANY_PHASE)) {
        return fmi2Error;
    }
    if (FMUstate == NULL || size != sizeof(FmuState)) {
        return fail(inst, "fmi2SerializeFMUstate", "NULL state or wrong buffer size");
    }
    memcpy(serializedState, FMUstate, sizeof(FmuState));
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size, fmi2FMUstate *FMUstate) {
    Instance *inst = (Instance *)c;
    FmuState incoming;
    if (!allowed(inst, "fmi2DeSerializeFMUstate", ANY_PHASE)) {
        return fmi2Error;
    }
    if (size != sizeof(FmuState)) {
        return fail(inst, "fmi2DeSerializeFMUstate", "the serialized state has the wrong size for this binary");
    }
    memcpy(&incoming, serializedState, sizeof(FmuState));
    if (incoming.magic != STATE_MAGIC || incoming.size != sizeof(FmuState)) {
        return fail(inst, "fmi2DeSerializeFMUstate", "the bytes are not an ImuFusion FMU state");
    }
    if (*FMUstate == NULL) {
        *FMUstate = allocate(inst, sizeof(FmuState));
        if (*FMUstate == NULL) {
            return fail(inst, "fmi2DeSerializeFMUstate", "out of memory");
        }
    }
    memcpy(*FMUstate, &incoming, sizeof(FmuState));
    return fmi2OK;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    Instance *inst = (Instance *)c;
    (void)vUnknown_ref;
    (void)nUnknown;
    (void)vKnown_ref;
    (void)nKnown;
    (void)dvKnown;
    (void)dvUnknown;
    if (!allowed(inst, "fmi2GetDirectionalDerivative", ANY_PHASE)) {
        return fmi2Error;
    }
    return fail(inst, "fmi2GetDirectionalDerivative", "directional derivatives are not provided");
}

/* ---- co-simulation -------------------------------------------------------------------------- */

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    Instance *inst = (Instance *)c;
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    if (!allowed(inst, "fmi2SetRealInputDerivatives", ANY_PHASE)) {
        return fmi2Error;
    }
    return fail(inst, "fmi2SetRealInputDerivatives", "input derivatives are not supported (canInterpolateInputs=false)");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    Instance *inst = (Instance *)c;
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    if (!allowed(inst, "fmi2GetRealOutputDerivatives", ANY_PHASE)) {
        return fmi2Error;
    }
    return fail(inst, "fmi2GetRealOutputDerivatives", "output derivatives are not provided (maxOutputDerivativeOrder=0)");
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    Instance *inst = (Instance *)c;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!allowed(inst, "fmi2DoStep", PhaseStepComplete)) {
        return fmi2Error;
    }
    if (!(communicationStepSize >= 0.0)) {
        logMessage(inst, fmi2Error, LogStatusError, "fmi2DoStep: communicationStepSize = %g s must not be negative",
                   communicationStepSize);
        return fmi2Error;
    }
    ModelDoStep(&inst->state.model, currentCommunicationPoint);
    inst->state.time = currentCommunicationPoint + communicationStepSize;
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    Instance *inst = (Instance *)c;
    if (!allowed(inst, "fmi2CancelStep", ANY_PHASE)) {
        return fmi2Error;
    }
    return fail(inst, "fmi2CancelStep", "doStep never runs asynchronously, there is nothing to cancel");
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    Instance *inst = (Instance *)c;
    if (!allowed(inst, "fmi2GetStatus", ANY_PHASE)) {
        return fmi2Error;
    }
    if (s != fmi2DoStepStatus) {
        return fail(inst, "fmi2GetStatus", "only fmi2DoStepStatus is provided");
    }
    *value = fmi2OK;
    return fmi2OK;
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    Instance *inst = (Instance *)c;
    if (!allowed(inst, "fmi2GetRealStatus", ANY_PHASE)) {
        return fmi2Error;
    }
    if (s != fmi2LastSuccessfulTime) {
        return fail(inst, "fmi2GetRealStatus", "only fmi2LastSuccessfulTime is provided");
    }
    *value = inst->state.time;
    return fmi2OK;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    Instance *inst = (Instance *)c;
    (void)s;
    (void)value;
    if (!allowed(inst, "fmi2GetIntegerStatus", ANY_PHASE)) {
        return fmi2Error;
    }
    return fail(inst, "fmi2GetIntegerStatus", "no integer status is provided");
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    Instance *inst = (Instance *)c;
    if (!allowed(inst, "fmi2GetBooleanStatus", ANY_PHASE)) {
        return fmi2Error;
    }
    if (s != fmi2Terminated) {
        return fail(inst, "fmi2GetBooleanStatus", "only fmi2Terminated is provided");
    }
    *value = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    Instance *inst = (Instance *)c;
    (void)s;
    (void)value;
    if (!allowed(inst, "fmi2GetStringStatus", ANY_PHASE)) {
        return fmi2Error;
    }
    return fail(inst, "fmi2GetStringStatus", "no string status is provided");
}
