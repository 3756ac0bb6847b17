/**
 * @file fmi2Functions.c
 * @brief FMI 2.0 co-simulation interface of ImuFusion: FMI 2 types and callbacks around model.c.
 *
 * One of the two files that include FMI headers. It exports exactly the 34 FMI 2.0
 * co-simulation functions (no prefix); the state machine, logging and values are model.c's.
 */
#include <math.h>
#include <string.h>

#include "fmi2Functions.h"
#include "model.h"

/** One FMU instance: the shared core and the importer's FMI 2 callbacks. */
typedef struct {
    ModelInstance core;
    fmi2CallbackLogger logger;
    fmi2CallbackAllocateMemory allocateMemory;
    fmi2CallbackFreeMemory freeMemory;
    fmi2ComponentEnvironment environment;
    char *instanceName;
} Instance;

/** @brief ModelLogCallback: forward a finished message to the importer's fmi2 logger. */
static void forwardLog(void *environment, ModelStatus status, const char *category, const char *message) {
    const Instance *inst = (const Instance *)environment;
    inst->logger(inst->environment, inst->instanceName, (fmi2Status)status, category, "%s", message);
}

/** @brief The shared core of component c (NULL for NULL). */
static ModelInstance *core(fmi2Component c) {
    return c != NULL ? &((Instance *)c)->core : NULL;
}

/** @brief Log that function is not provided by this FMU and return fmi2Error. */
static fmi2Status notProvided(fmi2Component c, const char *function, const char *why) {
    if (!ModelAllowed(core(c), function, MODEL_ANY_PHASE)) {
        return fmi2Error;
    }
    return (fmi2Status)ModelFail(core(c), function, why);
}

/* ---- common functions ---------------------------------------------------------------------- */

const char *fmi2GetTypesPlatform(void) {
    return fmi2TypesPlatform;
}

const char *fmi2GetVersion(void) {
    return fmi2Version;
}

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories, const fmi2String categories[]) {
    if (!ModelAllowed(core(c), "fmi2SetDebugLogging", MODEL_ANY_PHASE)) {
        return fmi2Error;
    }
    return (fmi2Status)ModelSetDebugLogging(core(c), loggingOn != fmi2False, nCategories, categories);
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
    inst->instanceName = (char *)functions->allocateMemory(1, strlen(name) + 1);
    if (inst->instanceName == NULL) {
        functions->freeMemory(inst);
        return NULL;
    }
    memcpy(inst->instanceName, name, strlen(name) + 1);
    inst->logger = functions->logger;
    inst->allocateMemory = functions->allocateMemory;
    inst->freeMemory = functions->freeMemory;
    inst->environment = functions->componentEnvironment;
    ModelInstanceInitialise(&inst->core, inst->logger != NULL ? forwardLog : NULL, inst, loggingOn != fmi2False);
    ModelLog(&inst->core, ModelOk, LogEvents, "fmi2Instantiate: instance '%s' created", name);
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
    ModelInstance *mi = core(c);
    (void)toleranceDefined;
    (void)tolerance;
    if (!ModelAllowed(mi, "fmi2SetupExperiment", PhaseInstantiated)) {
        return fmi2Error;
    }
    if (!isfinite(startTime) || (stopTimeDefined && !(stopTime >= startTime))) {
        return (fmi2Status)ModelFail(mi, "fmi2SetupExperiment", "startTime must be finite and stopTime not before it");
    }
    mi->state.time = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    ModelInstance *mi = core(c);
    if (mi == NULL) {
        return fmi2Error;
    }
    return (fmi2Status)ModelEnterInitialization(mi, "fmi2EnterInitializationMode", mi->state.time, 0, 0.0);
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    return (fmi2Status)ModelExitInitialization(core(c), "fmi2ExitInitializationMode");
}

fmi2Status fmi2Terminate(fmi2Component c) {
    return (fmi2Status)ModelTerminate(core(c), "fmi2Terminate");
}

fmi2Status fmi2Reset(fmi2Component c) {
    if (!ModelAllowed(core(c), "fmi2Reset", MODEL_ANY_PHASE)) {
        return fmi2Error;
    }
    ModelReset(core(c));
    return fmi2OK;
}

/* ---- getting and setting values ------------------------------------------------------------- */

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    size_t i;
    if (!ModelAllowed(core(c), "fmi2GetReal", MODEL_ANY_PHASE) || !ModelArraysGiven(core(c), "fmi2GetReal", nvr, vr, value)) {
        return fmi2Error;
    }
    for (i = 0; i < nvr; i++) {
        if (ModelGetReal(core(c), "fmi2GetReal", vr[i], &value[i]) != ModelOk) {
            return fmi2Error;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[]) {
    size_t i;
    int v;
    if (!ModelAllowed(core(c), "fmi2GetInteger", MODEL_ANY_PHASE) || !ModelArraysGiven(core(c), "fmi2GetInteger", nvr, vr, value)) {
        return fmi2Error;
    }
    for (i = 0; i < nvr; i++) {
        if (ModelGetInteger(core(c), "fmi2GetInteger", vr[i], &v) != ModelOk) {
            return fmi2Error;
        }
        value[i] = v;
    }
    return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[]) {
    size_t i;
    int v;
    if (!ModelAllowed(core(c), "fmi2GetBoolean", MODEL_ANY_PHASE) || !ModelArraysGiven(core(c), "fmi2GetBoolean", nvr, vr, value)) {
        return fmi2Error;
    }
    for (i = 0; i < nvr; i++) {
        if (ModelGetBoolean(core(c), "fmi2GetBoolean", vr[i], &v) != ModelOk) {
            return fmi2Error;
        }
        value[i] = v ? fmi2True : fmi2False;
    }
    return fmi2OK;
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[]) {
    if (!ModelAllowed(core(c), "fmi2GetString", MODEL_ANY_PHASE) || !ModelArraysGiven(core(c), "fmi2GetString", nvr, vr, value)) {
        return fmi2Error;
    }
    if (nvr > 0) {
        ModelLog(core(c), ModelError, LogStatusError, "fmi2GetString: " MODEL_NAME " has no String variables (value reference %u)", vr[0]);
        return fmi2Error;
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    size_t i;
    if (!ModelAllowed(core(c), "fmi2SetReal", MODEL_SET_PHASES) || !ModelArraysGiven(core(c), "fmi2SetReal", nvr, vr, value)) {
        return fmi2Error;
    }
    for (i = 0; i < nvr; i++) {
        if (ModelSetReal(core(c), "fmi2SetReal", vr[i], value[i]) != ModelOk) {
            return fmi2Error;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[]) {
    size_t i;
    if (!ModelAllowed(core(c), "fmi2SetInteger", MODEL_SET_PHASES) || !ModelArraysGiven(core(c), "fmi2SetInteger", nvr, vr, value)) {
        return fmi2Error;
    }
    for (i = 0; i < nvr; i++) {
        if (ModelSetInteger(core(c), "fmi2SetInteger", vr[i], value[i]) != ModelOk) {
            return fmi2Error;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[]) {
    size_t i;
    if (!ModelAllowed(core(c), "fmi2SetBoolean", MODEL_SET_PHASES) || !ModelArraysGiven(core(c), "fmi2SetBoolean", nvr, vr, value)) {
        return fmi2Error;
    }
    for (i = 0; i < nvr; i++) {
        if (ModelSetBoolean(core(c), "fmi2SetBoolean", vr[i], value[i] != fmi2False) != ModelOk) {
            return fmi2Error;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[]) {
    if (!ModelAllowed(core(c), "fmi2SetString", MODEL_SET_PHASES) || !ModelArraysGiven(core(c), "fmi2SetString", nvr, vr, value)) {
        return fmi2Error;
    }
    if (nvr > 0) {
        ModelLog(core(c), ModelError, LogStatusError, "fmi2SetString: " MODEL_NAME " has no String variables (value reference %u)", vr[0]);
        return fmi2Error;
    }
    return fmi2OK;
}

/* ---- FMU state: copies of ModelState --------------------------------------------------------- */

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    Instance *inst = (Instance *)c;
    if (!ModelAllowed(core(c), "fmi2GetFMUstate", MODEL_ANY_PHASE) ||
        !ModelGiven(core(c), "fmi2GetFMUstate", FMUstate, "the FMUstate pointer")) {
        return fmi2Error;
    }
    if (*FMUstate == NULL) {
        *FMUstate = inst->allocateMemory(1, sizeof(ModelState));
        if (*FMUstate == NULL) {
            return (fmi2Status)ModelFail(core(c), "fmi2GetFMUstate", "out of memory");
        }
    }
    memcpy(*FMUstate, &inst->core.state, sizeof(ModelState));
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    if (!ModelAllowed(core(c), "fmi2SetFMUstate", MODEL_ANY_PHASE)) {
        return fmi2Error;
    }
    return (fmi2Status)ModelSetState(core(c), "fmi2SetFMUstate", (const ModelState *)FMUstate);
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    Instance *inst = (Instance *)c;
    if (!ModelAllowed(core(c), "fmi2FreeFMUstate", MODEL_ANY_PHASE)) {
        return fmi2Error;
    }
    if (FMUstate != NULL && *FMUstate != NULL) {
        inst->freeMemory(*FMUstate);
        *FMUstate = NULL;
    }
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    (void)FMUstate;
    if (!ModelAllowed(core(c), "fmi2SerializedFMUstateSize", MODEL_ANY_PHASE) ||
        !ModelGiven(core(c), "fmi2SerializedFMUstateSize", size, "the size pointer")) {
        return fmi2Error;
    }
    *size = sizeof(ModelState);
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[], size_t size) {
    if (!ModelAllowed(core(c), "fmi2SerializeFMUstate", MODEL_ANY_PHASE) ||
        !ModelGiven(core(c), "fmi2SerializeFMUstate", serializedState, "the serializedState buffer")) {
        return fmi2Error;
    }
    if (FMUstate == NULL || size != sizeof(ModelState)) {
        return (fmi2Status)ModelFail(core(c), "fmi2SerializeFMUstate", "NULL state or wrong buffer size");
    }
    ModelSerialize((const ModelState *)FMUstate, serializedState);
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size, fmi2FMUstate *FMUstate) {
    Instance *inst = (Instance *)c;
    if (!ModelAllowed(core(c), "fmi2DeSerializeFMUstate", MODEL_ANY_PHASE) ||
        !ModelGiven(core(c), "fmi2DeSerializeFMUstate", FMUstate, "the FMUstate pointer")) {
        return fmi2Error;
    }
    if (ModelCheckSerialized(core(c), "fmi2DeSerializeFMUstate", serializedState, size) != ModelOk) {
        return fmi2Error;
    }
    if (*FMUstate == NULL) {
        *FMUstate = inst->allocateMemory(1, sizeof(ModelState));
        if (*FMUstate == NULL) {
            return (fmi2Status)ModelFail(core(c), "fmi2DeSerializeFMUstate", "out of memory");
        }
    }
    memcpy(*FMUstate, serializedState, sizeof(ModelState));
    return fmi2OK;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    (void)vUnknown_ref;
    (void)nUnknown;
    (void)vKnown_ref;
    (void)nKnown;
    (void)dvKnown;
    (void)dvUnknown;
    return notProvided(c, "fmi2GetDirectionalDerivative", "directional derivatives are not provided");
}

/* ---- co-simulation -------------------------------------------------------------------------- */

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    return notProvided(c, "fmi2SetRealInputDerivatives", "input derivatives are not supported (canInterpolateInputs=false)");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    return notProvided(c, "fmi2GetRealOutputDerivatives", "output derivatives are not provided (maxOutputDerivativeOrder=0)");
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!ModelAllowed(core(c), "fmi2DoStep", PhaseStepMode)) {
        return fmi2Error;
    }
    return (fmi2Status)ModelDoStep(core(c), "fmi2DoStep", currentCommunicationPoint, communicationStepSize);
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    return notProvided(c, "fmi2CancelStep", "doStep never runs asynchronously, there is nothing to cancel");
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    (void)s;
    (void)value;
    return notProvided(c, "fmi2GetStatus", "doStep never returns fmi2Pending, so there is no status to query");
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    if (!ModelAllowed(core(c), "fmi2GetRealStatus", MODEL_ANY_PHASE) || !ModelGiven(core(c), "fmi2GetRealStatus", value, "the value pointer")) {
        return fmi2Error;
    }
    if (s != fmi2LastSuccessfulTime) {
        return (fmi2Status)ModelFail(core(c), "fmi2GetRealStatus", "only fmi2LastSuccessfulTime is provided");
    }
    *value = core(c)->state.time;
    return fmi2OK;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    (void)s;
    (void)value;
    return notProvided(c, "fmi2GetIntegerStatus", "no integer status is provided");
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    if (!ModelAllowed(core(c), "fmi2GetBooleanStatus", MODEL_ANY_PHASE) || !ModelGiven(core(c), "fmi2GetBooleanStatus", value, "the value pointer")) {
        return fmi2Error;
    }
    if (s != fmi2Terminated) {
        return (fmi2Status)ModelFail(core(c), "fmi2GetBooleanStatus", "only fmi2Terminated is provided");
    }
    *value = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    (void)s;
    (void)value;
    return notProvided(c, "fmi2GetStringStatus", "no string status is provided");
}
