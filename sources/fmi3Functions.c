/**
 * @file fmi3Functions.c
 * @brief FMI 3.0 co-simulation interface of ImuFusion: FMI 3 types and callbacks around model.c.
 *
 * One of the two files that include FMI headers. It exports exactly the 75 FMI 3.0 functions
 * without prefix; those of interfaces this FMU does not provide (model exchange, scheduled
 * execution, event mode, clocks, derivatives, the types it has no variables of) log why and
 * return fmi3Error. The state machine, logging and values are model.c's.
 */
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "model.h"

/** One FMU instance: the shared core and the importer's FMI 3 callback. */
typedef struct {
    ModelInstance core;
    fmi3LogMessageCallback logMessage;
    fmi3InstanceEnvironment environment;
} Instance;

/** @brief ModelLogCallback: forward a finished message to the importer's fmi3 logger. */
static void forwardLog(void *environment, ModelStatus status, const char *category, const char *message) {
    const Instance *inst = (const Instance *)environment;
    inst->logMessage(inst->environment, (fmi3Status)status, category, message);
}

/** @brief The shared core of instance (NULL for NULL). */
static ModelInstance *core(fmi3Instance instance) {
    return instance != NULL ? &((Instance *)instance)->core : NULL;
}

/** @brief Log that function belongs to an interface this FMU does not provide; fmi3Error. */
static fmi3Status notProvided(fmi3Instance instance, const char *function, const char *why) {
    if (!ModelAllowed(core(instance), function, MODEL_ANY_PHASE)) {
        return fmi3Error;
    }
    return (fmi3Status)ModelFail(core(instance), function, why);
}

/** @brief Getter/setter of a type this FMU has no variables of: OK for none, else fmi3Error. */
static fmi3Status noVariables(fmi3Instance instance, const char *function, const fmi3ValueReference vr[], size_t nvr) {
    if (!ModelAllowed(core(instance), function, MODEL_ANY_PHASE) ||
        (nvr > 0 && !ModelGiven(core(instance), function, vr, "the value reference array"))) {
        return fmi3Error;
    }
    if (nvr > 0) {
        ModelLog(core(instance), ModelError, LogStatusError,
                 "%s: " MODEL_NAME " has no variables of this type (value reference %u)", function, vr[0]);
        return fmi3Error;
    }
    return fmi3OK;
}

/** @brief Check the phase, that both arrays are given and that one value per value reference is
 *  passed (every variable of these types is a scalar). */
static int accessAllowed(fmi3Instance instance, const char *function, int phases, size_t nvr, const void *vr,
                         const void *values, size_t nValues) {
    if (!ModelAllowed(core(instance), function, phases) || !ModelArraysGiven(core(instance), function, nvr, vr, values)) {
        return 0;
    }
    if (nValues != nvr) {
        ModelLog(core(instance), ModelError, LogStatusError,
                 "%s: nValues = %lu differs from nValueReferences = %lu (every variable of this type is a scalar)",
                 function, (unsigned long)nValues, (unsigned long)nvr);
        return 0;
    }
    return 1;
}

/* Getters and setters of the types without variables: same signature, one line each. */
#define IMU_NO_GET(name, type)                                                                                \
    fmi3Status name(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, type values[], size_t n) { \
        (void)values;                                                                                         \
        (void)n;                                                                                              \
        return noVariables(instance, #name, vr, nvr);                                                         \
    }
#define IMU_NO_SET(name, type) IMU_NO_GET(name, const type)

/* ---- inquiry, logging, instantiation ------------------------------------------------------- */

const char *fmi3GetVersion(void) {
    return fmi3Version;
}

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories, const fmi3String categories[]) {
    if (!ModelAllowed(core(instance), "fmi3SetDebugLogging", MODEL_ANY_PHASE)) {
        return fmi3Error;
    }
    return (fmi3Status)ModelSetDebugLogging(core(instance), loggingOn, nCategories, categories);
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
                                          fmi3Boolean visible, fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    (void)instanceName;
    (void)instantiationToken;
    (void)resourcePath;
    (void)visible;
    (void)loggingOn;
    if (logMessage != NULL) {
        logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                   "fmi3InstantiateModelExchange: " MODEL_NAME " supports co-simulation only");
    }
    return NULL;
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
                                         fmi3Boolean visible, fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
                                         fmi3Boolean earlyReturnAllowed, const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables, fmi3InstanceEnvironment instanceEnvironment,
                                         fmi3LogMessageCallback logMessage, fmi3IntermediateUpdateCallback intermediateUpdate) {
    Instance *inst;
    const char *problem = NULL;
    (void)resourcePath;
    (void)visible;
    (void)earlyReturnAllowed;
    (void)requiredIntermediateVariables;
    (void)intermediateUpdate;
    if (instantiationToken == NULL || strcmp(instantiationToken, ModelGuid()) != 0) {
        problem = "the instantiation token does not match the one this binary was built with";
    } else if (eventModeUsed) {
        problem = MODEL_NAME " has no event mode (hasEventMode=false)";
    } else if (nRequiredIntermediateVariables > 0) {
        problem = MODEL_NAME " provides no intermediate variable access";
    }
    if (problem != NULL) {
        if (logMessage != NULL) {
            logMessage(instanceEnvironment, fmi3Error, "logStatusError", problem);
        }
        return NULL;
    }
    inst = (Instance *)calloc(1, sizeof(Instance));
    if (inst == NULL) {
        return NULL;
    }
    inst->logMessage = logMessage;
    inst->environment = instanceEnvironment;
    ModelInstanceInitialise(&inst->core, logMessage != NULL ? forwardLog : NULL, inst, loggingOn);
    ModelLog(&inst->core, ModelOk, LogEvents, "fmi3InstantiateCoSimulation: instance '%s' created",
             instanceName != NULL ? instanceName : "");
    return inst;
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
                                               fmi3Boolean visible, fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instanceName;
    (void)instantiationToken;
    (void)resourcePath;
    (void)visible;
    (void)loggingOn;
    (void)clockUpdate;
    (void)lockPreemption;
    (void)unlockPreemption;
    if (logMessage != NULL) {
        logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                   "fmi3InstantiateScheduledExecution: " MODEL_NAME " supports co-simulation only");
    }
    return NULL;
}

void fmi3FreeInstance(fmi3Instance instance) {
    free(instance);
}

/* ---- life cycle ------------------------------------------------------------------------------- */

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    (void)toleranceDefined;
    (void)tolerance;
    if (instance == NULL) {
        return fmi3Error;
    }
    return (fmi3Status)ModelEnterInitialization(core(instance), "fmi3EnterInitializationMode", startTime,
                                                stopTimeDefined, stopTime);
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    return (fmi3Status)ModelExitInitialization(core(instance), "fmi3ExitInitializationMode");
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance) {
    return notProvided(instance, "fmi3EnterEventMode", "there is no event mode (hasEventMode=false)");
}

fmi3Status fmi3Terminate(fmi3Instance instance) {
    return (fmi3Status)ModelTerminate(core(instance), "fmi3Terminate");
}

fmi3Status fmi3Reset(fmi3Instance instance) {
    if (!ModelAllowed(core(instance), "fmi3Reset", MODEL_ANY_PHASE)) {
        return fmi3Error;
    }
    ModelReset(core(instance));
    return fmi3OK;
}

/* ---- getting and setting values --------------------------------------------------------------- */

IMU_NO_GET(fmi3GetFloat32, fmi3Float32)
IMU_NO_GET(fmi3GetInt8, fmi3Int8)
IMU_NO_GET(fmi3GetUInt8, fmi3UInt8)
IMU_NO_GET(fmi3GetInt16, fmi3Int16)
IMU_NO_GET(fmi3GetUInt16, fmi3UInt16)
IMU_NO_GET(fmi3GetUInt32, fmi3UInt32)
IMU_NO_GET(fmi3GetInt64, fmi3Int64)
IMU_NO_GET(fmi3GetUInt64, fmi3UInt64)
IMU_NO_GET(fmi3GetString, fmi3String)
IMU_NO_SET(fmi3SetFloat32, fmi3Float32)
IMU_NO_SET(fmi3SetInt8, fmi3Int8)
IMU_NO_SET(fmi3SetUInt8, fmi3UInt8)
IMU_NO_SET(fmi3SetInt16, fmi3Int16)
IMU_NO_SET(fmi3SetUInt16, fmi3UInt16)
IMU_NO_SET(fmi3SetUInt32, fmi3UInt32)
IMU_NO_SET(fmi3SetInt64, fmi3Int64)
IMU_NO_SET(fmi3SetUInt64, fmi3UInt64)
IMU_NO_SET(fmi3SetString, fmi3String)

/** @brief Check that nValues is the number of Float64 values the nvr value references carry (a
 *  coefficient block's array parameter carries its length, a scalar one; ModelFloat64Count). */
static int float64ValuesMatch(fmi3Instance instance, const char *function, const fmi3ValueReference vr[], size_t nvr,
                              size_t nValues) {
    size_t i, expected = 0;
    for (i = 0; i < nvr; i++) {
        const size_t count = ModelFloat64Count(vr[i]);
        if (count == 0) {
            ModelLog(core(instance), ModelError, LogStatusError, "%s: unknown value reference %u", function, vr[i]);
            return 0;
        }
        expected += count;
    }
    if (nValues != expected) {
        ModelLog(core(instance), ModelError, LogStatusError,
                 "%s: nValues = %lu differs from the %lu values the value references carry",
                 function, (unsigned long)nValues, (unsigned long)expected);
        return 0;
    }
    return 1;
}

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Float64 values[], size_t nValues) {
    size_t i, k = 0;
    if (!ModelAllowed(core(instance), "fmi3GetFloat64", MODEL_ANY_PHASE)
        || !ModelArraysGiven(core(instance), "fmi3GetFloat64", nvr, vr, values)
        || !float64ValuesMatch(instance, "fmi3GetFloat64", vr, nvr, nValues)) {
        return fmi3Error;
    }
    for (i = 0; i < nvr; k += ModelFloat64Count(vr[i]), i++) {
        if (ModelGetFloat64s(core(instance), "fmi3GetFloat64", vr[i], &values[k]) != ModelOk) {
            return fmi3Error;
        }
    }
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Float64 values[], size_t nValues) {
    size_t i, k = 0;
    if (!ModelAllowed(core(instance), "fmi3SetFloat64", MODEL_SET_PHASES)
        || !ModelArraysGiven(core(instance), "fmi3SetFloat64", nvr, vr, values)
        || !float64ValuesMatch(instance, "fmi3SetFloat64", vr, nvr, nValues)) {
        return fmi3Error;
    }
    for (i = 0; i < nvr; k += ModelFloat64Count(vr[i]), i++) {
        if (ModelSetFloat64s(core(instance), "fmi3SetFloat64", vr[i], &values[k]) != ModelOk) {
            return fmi3Error;
        }
    }
    return fmi3OK;
}

fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Int32 values[], size_t nValues) {
    size_t i;
    int v;
    if (!accessAllowed(instance, "fmi3GetInt32", MODEL_ANY_PHASE, nvr, vr, values, nValues)) {
        return fmi3Error;
    }
    for (i = 0; i < nvr; i++) {
        if (ModelGetInteger(core(instance), "fmi3GetInt32", vr[i], &v) != ModelOk) {
            return fmi3Error;
        }
        values[i] = (fmi3Int32)v;
    }
    return fmi3OK;
}

fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Int32 values[], size_t nValues) {
    size_t i;
    if (!accessAllowed(instance, "fmi3SetInt32", MODEL_SET_PHASES, nvr, vr, values, nValues)) {
        return fmi3Error;
    }
    for (i = 0; i < nvr; i++) {
        if (ModelSetInteger(core(instance), "fmi3SetInt32", vr[i], (int)values[i]) != ModelOk) {
            return fmi3Error;
        }
    }
    return fmi3OK;
}

fmi3Status fmi3GetBoolean(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Boolean values[], size_t nValues) {
    size_t i;
    int v;
    if (!accessAllowed(instance, "fmi3GetBoolean", MODEL_ANY_PHASE, nvr, vr, values, nValues)) {
        return fmi3Error;
    }
    for (i = 0; i < nvr; i++) {
        if (ModelGetBoolean(core(instance), "fmi3GetBoolean", vr[i], &v) != ModelOk) {
            return fmi3Error;
        }
        values[i] = v ? fmi3True : fmi3False;
    }
    return fmi3OK;
}

fmi3Status fmi3SetBoolean(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Boolean values[], size_t nValues) {
    size_t i;
    if (!accessAllowed(instance, "fmi3SetBoolean", MODEL_SET_PHASES, nvr, vr, values, nValues)) {
        return fmi3Error;
    }
    for (i = 0; i < nvr; i++) {
        if (ModelSetBoolean(core(instance), "fmi3SetBoolean", vr[i], values[i] ? 1 : 0) != ModelOk) {
            return fmi3Error;
        }
    }
    return fmi3OK;
}

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, size_t valueSizes[],
                         fmi3Binary values[], size_t nValues) {
    (void)valueSizes;
    (void)values;
    (void)nValues;
    return noVariables(instance, "fmi3GetBinary", vr, nvr);
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const size_t valueSizes[],
                         const fmi3Binary values[], size_t nValues) {
    (void)valueSizes;
    (void)values;
    (void)nValues;
    return noVariables(instance, "fmi3SetBinary", vr, nvr);
}

fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Clock values[]) {
    (void)values;
    return noVariables(instance, "fmi3GetClock", vr, nvr);
}

fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Clock values[]) {
    (void)values;
    return noVariables(instance, "fmi3SetClock", vr, nvr);
}

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference valueReference, size_t *nDependencies) {
    (void)valueReference;
    (void)nDependencies;
    return notProvided(instance, "fmi3GetNumberOfVariableDependencies",
                       "variable dependencies are given in modelDescription.xml only");
}

fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent, size_t elementIndicesOfDependent[],
                                       fmi3ValueReference independents[], size_t elementIndicesOfIndependents[],
                                       fmi3DependencyKind dependencyKinds[], size_t nDependencies) {
    (void)dependent;
    (void)elementIndicesOfDependent;
    (void)independents;
    (void)elementIndicesOfIndependents;
    (void)dependencyKinds;
    (void)nDependencies;
    return notProvided(instance, "fmi3GetVariableDependencies",
                       "variable dependencies are given in modelDescription.xml only");
}

/* ---- FMU state: copies of ModelState --------------------------------------------------------- */

fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    if (!ModelAllowed(core(instance), "fmi3GetFMUState", MODEL_ANY_PHASE) ||
        !ModelGiven(core(instance), "fmi3GetFMUState", FMUState, "the FMUState pointer")) {
        return fmi3Error;
    }
    if (*FMUState == NULL) {
        *FMUState = calloc(1, sizeof(ModelState));
        if (*FMUState == NULL) {
            return (fmi3Status)ModelFail(core(instance), "fmi3GetFMUState", "out of memory");
        }
    }
    memcpy(*FMUState, &core(instance)->state, sizeof(ModelState));
    return fmi3OK;
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState) {
    if (!ModelAllowed(core(instance), "fmi3SetFMUState", MODEL_ANY_PHASE)) {
        return fmi3Error;
    }
    return (fmi3Status)ModelSetState(core(instance), "fmi3SetFMUState", (const ModelState *)FMUState);
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    if (!ModelAllowed(core(instance), "fmi3FreeFMUState", MODEL_ANY_PHASE)) {
        return fmi3Error;
    }
    if (FMUState != NULL) {
        free(*FMUState);
        *FMUState = NULL;
    }
    return fmi3OK;
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState, size_t *size) {
    (void)FMUState;
    if (!ModelAllowed(core(instance), "fmi3SerializedFMUStateSize", MODEL_ANY_PHASE) ||
        !ModelGiven(core(instance), "fmi3SerializedFMUStateSize", size, "the size pointer")) {
        return fmi3Error;
    }
    *size = sizeof(ModelState);
    return fmi3OK;
}

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState, fmi3Byte serializedState[], size_t size) {
    if (!ModelAllowed(core(instance), "fmi3SerializeFMUState", MODEL_ANY_PHASE) ||
        !ModelGiven(core(instance), "fmi3SerializeFMUState", serializedState, "the serializedState buffer")) {
        return fmi3Error;
    }
    if (FMUState == NULL || size != sizeof(ModelState)) {
        return (fmi3Status)ModelFail(core(instance), "fmi3SerializeFMUState", "NULL state or wrong buffer size");
    }
    ModelSerialize((const ModelState *)FMUState, serializedState);
    return fmi3OK;
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[], size_t size, fmi3FMUState *FMUState) {
    if (!ModelAllowed(core(instance), "fmi3DeserializeFMUState", MODEL_ANY_PHASE) ||
        !ModelGiven(core(instance), "fmi3DeserializeFMUState", FMUState, "the FMUState pointer")) {
        return fmi3Error;
    }
    if (ModelCheckSerialized(core(instance), "fmi3DeserializeFMUState", serializedState, size) != ModelOk) {
        return fmi3Error;
    }
    if (*FMUState == NULL) {
        *FMUState = calloc(1, sizeof(ModelState));
        if (*FMUState == NULL) {
            return (fmi3Status)ModelFail(core(instance), "fmi3DeserializeFMUState", "out of memory");
        }
    }
    memcpy(*FMUState, serializedState, sizeof(ModelState));
    return fmi3OK;
}

/* ---- derivatives, configuration, clocks, discrete states: not provided ------------------------ */

fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                        const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                        size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) {
    (void)unknowns;
    (void)nUnknowns;
    (void)knowns;
    (void)nKnowns;
    (void)seed;
    (void)nSeed;
    (void)sensitivity;
    (void)nSensitivity;
    return notProvided(instance, "fmi3GetDirectionalDerivative", "directional derivatives are not provided");
}

fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                    const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                    size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) {
    (void)unknowns;
    (void)nUnknowns;
    (void)knowns;
    (void)nKnowns;
    (void)seed;
    (void)nSeed;
    (void)sensitivity;
    (void)nSensitivity;
    return notProvided(instance, "fmi3GetAdjointDerivative", "adjoint derivatives are not provided");
}

fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) {
    return notProvided(instance, "fmi3EnterConfigurationMode", "there are no structural parameters");
}

fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) {
    return notProvided(instance, "fmi3ExitConfigurationMode", "there are no structural parameters");
}

fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                  fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[]) {
    (void)intervals;
    (void)qualifiers;
    return noVariables(instance, "fmi3GetIntervalDecimal", vr, nvr);
}

fmi3Status fmi3GetIntervalFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                   fmi3UInt64 counters[], fmi3UInt64 resolutions[], fmi3IntervalQualifier qualifiers[]) {
    (void)counters;
    (void)resolutions;
    (void)qualifiers;
    return noVariables(instance, "fmi3GetIntervalFraction", vr, nvr);
}

fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Float64 shifts[]) {
    (void)shifts;
    return noVariables(instance, "fmi3GetShiftDecimal", vr, nvr);
}

fmi3Status fmi3GetShiftFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                fmi3UInt64 counters[], fmi3UInt64 resolutions[]) {
    (void)counters;
    (void)resolutions;
    return noVariables(instance, "fmi3GetShiftFraction", vr, nvr);
}

fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Float64 intervals[]) {
    (void)intervals;
    return noVariables(instance, "fmi3SetIntervalDecimal", vr, nvr);
}

fmi3Status fmi3SetIntervalFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                   const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)counters;
    (void)resolutions;
    return noVariables(instance, "fmi3SetIntervalFraction", vr, nvr);
}

fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Float64 shifts[]) {
    (void)shifts;
    return noVariables(instance, "fmi3SetShiftDecimal", vr, nvr);
}

fmi3Status fmi3SetShiftFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)counters;
    (void)resolutions;
    return noVariables(instance, "fmi3SetShiftFraction", vr, nvr);
}

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) {
    return notProvided(instance, "fmi3EvaluateDiscreteStates", "there are no clocks or event mode");
}

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate, fmi3Boolean *terminateSimulation,
                                    fmi3Boolean *nominalsOfContinuousStatesChanged, fmi3Boolean *valuesOfContinuousStatesChanged,
                                    fmi3Boolean *nextEventTimeDefined, fmi3Float64 *nextEventTime) {
    (void)discreteStatesNeedUpdate;
    (void)terminateSimulation;
    (void)nominalsOfContinuousStatesChanged;
    (void)valuesOfContinuousStatesChanged;
    (void)nextEventTimeDefined;
    (void)nextEventTime;
    return notProvided(instance, "fmi3UpdateDiscreteStates", "there is no event mode (hasEventMode=false)");
}

/* ---- model exchange: not provided ------------------------------------------------------------ */

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) {
    return notProvided(instance, "fmi3EnterContinuousTimeMode", MODEL_NAME " supports co-simulation only");
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation) {
    (void)noSetFMUStatePriorToCurrentPoint;
    (void)enterEventMode;
    (void)terminateSimulation;
    return notProvided(instance, "fmi3CompletedIntegratorStep", MODEL_NAME " supports co-simulation only");
}

fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time) {
    (void)time;
    return notProvided(instance, "fmi3SetTime", MODEL_NAME " supports co-simulation only");
}

fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 continuousStates[], size_t nContinuousStates) {
    (void)continuousStates;
    (void)nContinuousStates;
    return notProvided(instance, "fmi3SetContinuousStates", MODEL_NAME " supports co-simulation only");
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[], size_t nContinuousStates) {
    (void)derivatives;
    (void)nContinuousStates;
    return notProvided(instance, "fmi3GetContinuousStateDerivatives", MODEL_NAME " supports co-simulation only");
}

fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[], size_t nEventIndicators) {
    (void)eventIndicators;
    (void)nEventIndicators;
    return notProvided(instance, "fmi3GetEventIndicators", MODEL_NAME " supports co-simulation only");
}

fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 continuousStates[], size_t nContinuousStates) {
    (void)continuousStates;
    (void)nContinuousStates;
    return notProvided(instance, "fmi3GetContinuousStates", MODEL_NAME " supports co-simulation only");
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[], size_t nContinuousStates) {
    (void)nominals;
    (void)nContinuousStates;
    return notProvided(instance, "fmi3GetNominalsOfContinuousStates", MODEL_NAME " supports co-simulation only");
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *nEventIndicators) {
    (void)nEventIndicators;
    return notProvided(instance, "fmi3GetNumberOfEventIndicators", MODEL_NAME " supports co-simulation only");
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *nContinuousStates) {
    (void)nContinuousStates;
    return notProvided(instance, "fmi3GetNumberOfContinuousStates", MODEL_NAME " supports co-simulation only");
}

/* ---- co-simulation ---------------------------------------------------------------------------- */

fmi3Status fmi3EnterStepMode(fmi3Instance instance) {
    return notProvided(instance, "fmi3EnterStepMode", "there is no event mode to leave: Step Mode follows initialisation");
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                    const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues) {
    (void)vr;
    (void)nvr;
    (void)orders;
    (void)values;
    (void)nValues;
    return notProvided(instance, "fmi3GetOutputDerivatives", "output derivatives are not provided (maxOutputDerivativeOrder=0)");
}

/** @brief 1 when all four output pointers of fmi3DoStep are given; else logs which is NULL and returns 0. */
static int doStepOutputsGiven(fmi3Instance instance, const fmi3Boolean *eventHandlingNeeded, const fmi3Boolean *terminateSimulation,
                              const fmi3Boolean *earlyReturn, const fmi3Float64 *lastSuccessfulTime) {
    return ModelGiven(core(instance), "fmi3DoStep", eventHandlingNeeded, "eventHandlingNeeded") &&
           ModelGiven(core(instance), "fmi3DoStep", terminateSimulation, "terminateSimulation") &&
           ModelGiven(core(instance), "fmi3DoStep", earlyReturn, "earlyReturn") &&
           ModelGiven(core(instance), "fmi3DoStep", lastSuccessfulTime, "lastSuccessfulTime");
}

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint, fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint, fmi3Boolean *eventHandlingNeeded,
                      fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    fmi3Status status;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!ModelAllowed(core(instance), "fmi3DoStep", PhaseStepMode) || !doStepOutputsGiven(instance, eventHandlingNeeded,
                                                                                          terminateSimulation, earlyReturn,
                                                                                          lastSuccessfulTime)) {
        return fmi3Error;
    }
    status = (fmi3Status)ModelDoStep(core(instance), "fmi3DoStep", currentCommunicationPoint, communicationStepSize);
    *eventHandlingNeeded = fmi3False;
    *terminateSimulation = fmi3False;
    *earlyReturn = fmi3False;
    *lastSuccessfulTime = core(instance)->state.time;
    return status;
}

/* ---- scheduled execution: not provided ------------------------------------------------------- */

fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference, fmi3Float64 activationTime) {
    (void)clockReference;
    (void)activationTime;
    return notProvided(instance, "fmi3ActivateModelPartition", MODEL_NAME " supports co-simulation only");
}
