/**
 * @file model.h
 * @brief FMI-free core of an FMU of this source tree, shared by the FMI 2.0 and FMI 3.0 wrappers.
 *
 * Two models share it: the ImuFusion FMU (ModelData.h, model.c) and the virtual sensor
 * (sources/sensor/: its own ModelData.h, config.h and SensorModel.c, staged in their place by
 * fmu/sensor_fmu.py). ModelCore.c holds what does not depend on the model: the state machine,
 * logging and the FMU state's serialisation; each model implements the value access, the step and
 * the hooks declared at the end of this file.
 *
 * ModelData maps value references to the runtime; bad input is sanitised by the guard the
 * batch library shares (ImuGuard.h). ModelInstance adds what both FMI versions share: the state machine, debug logging and the FMU state. The FMU
 * state is one plain struct (ModelState): get is a copy, serialize a copy sealed with a checksum,
 * set a copy after every field that indexes or sizes anything is checked or re-derived. fmi2Functions.c and
 * fmi3Functions.c only translate FMI types and callbacks to these functions.
 */
#ifndef IMU_MODEL_H
#define IMU_MODEL_H

#include <stddef.h>

#include "ImuCommon.h"
#include "ModelData.h"

/** Result of a model call; same numbering as fmi2Status and fmi3Status. */
typedef enum {
    ModelOk = 0,
    ModelWarning = 1,
    ModelDiscard = 2,
    ModelError = 3
} ModelStatus;

/** Log categories, in the order of LogCategories in modelDescription.xml. */
typedef enum {
    LogEvents,
    LogBadInput,
    LogStatusWarning,
    LogStatusError,
    MODEL_LOG_CATEGORY_COUNT
} ModelLogCategory;

/** Phases of the co-simulation state machine (one bit each; FMI 3 Step Mode = FMI 2 stepComplete). */
typedef enum {
    PhaseInstantiated = 1 << 0,
    PhaseInitialization = 1 << 1,
    PhaseStepMode = 1 << 2,
    PhaseTerminated = 1 << 3,
    PhaseError = 1 << 4
} ModelPhase;

#define MODEL_ANY_PHASE (PhaseInstantiated | PhaseInitialization | PhaseStepMode | PhaseTerminated | PhaseError)
#define MODEL_SET_PHASES (PhaseInstantiated | PhaseInitialization | PhaseStepMode)

#define MODEL_GUID_SIZE 48

/** Longest log message [bytes], NUL included. */
#define MODEL_LOG_BUFFER_SIZE 640

/** What identifies an FMU state of this binary (the start of every serialized state). */
typedef struct {
    unsigned int magic;          /* MODEL_STATE_MAGIC */
    unsigned int size;           /* sizeof(ModelState) */
    char guid[MODEL_GUID_SIZE];  /* the binary's GUID: a state only fits the build that made it */
    unsigned long long checksum; /* ModelStateChecksum of the bytes after the header; set by
                                  * ModelSerialize, checked by ModelCheckSerialized (0 in memory) */
} ModelStateHeader;

/** The FMU state: everything that evolves, so get/set/serialize are copies. */
typedef struct {
    ModelStateHeader header;
    int phase;                   /* ModelPhase */
    double time;                 /* s, current communication point */
    ModelData model;
} ModelState;

/** Logger of the importer, adapted by the wrapper; status is a ModelStatus. */
typedef void (*ModelLogCallback)(void *environment, ModelStatus status, const char *category, const char *message);

/** The FMI-independent part of one FMU instance. */
typedef struct {
    ModelLogCallback log;                  /* NULL: log nothing */
    void *environment;                     /* the wrapper's instance, passed back to log */
    int loggingOn;                         /* debug logging switched on */
    int categoryOn[MODEL_LOG_CATEGORY_COUNT];
    ModelState state;
} ModelInstance;

/** @brief The GUID (FMI 3: instantiation token) of the modelDescription.xml this binary was built for. */
IMU_HIDDEN const char *ModelGuid(void);
/** @brief Set up mi right after instantiation: start values, phase Instantiated, time 0 s. */
IMU_HIDDEN void ModelInstanceInitialise(ModelInstance *mi, ModelLogCallback log, void *environment, int loggingOn);
/** @brief Log a printf-style message: problems (status >= Warning) always, others when their category is on. */
IMU_HIDDEN void ModelLog(const ModelInstance *mi, ModelStatus status, ModelLogCategory category, const char *format, ...)
#if defined(__GNUC__) || defined(__clang__)
    __attribute__((format(printf, 4, 5)))
#endif
    ;
/** @brief 1 if mi is not NULL and function may be called in its phase; else logs and returns 0. */
IMU_HIDDEN int ModelAllowed(const ModelInstance *mi, const char *function, int phases);
/** @brief Log "function: unknown value reference vr" or "... is not a `type` variable" and return ModelError. */
IMU_HIDDEN ModelStatus ModelBadReference(const ModelInstance *mi, const char *function, unsigned int vr, const char *type);
/** @brief Log an error "function: message" and return ModelError. */
IMU_HIDDEN ModelStatus ModelFail(const ModelInstance *mi, const char *function, const char *message);
/** @brief 1 if pointer is not NULL; else logs the error "function: what is NULL" and returns 0. */
IMU_HIDDEN int ModelGiven(const ModelInstance *mi, const char *function, const void *pointer, const char *what);
/** @brief 1 if n is 0 or both the value references and the values are given; else logs and returns 0. */
IMU_HIDDEN int ModelArraysGiven(const ModelInstance *mi, const char *function, size_t n, const void *vr, const void *values);
/** @brief Switch debug logging; categories by name (none = all). Warning for an unknown name. */
IMU_HIDDEN ModelStatus ModelSetDebugLogging(ModelInstance *mi, int loggingOn, size_t n, const char *const categories[]);
/** @brief Back to the state right after instantiation (FMI Reset). */
IMU_HIDDEN void ModelReset(ModelInstance *mi);
/** @brief Enter initialisation at startTime [s]; stopTime [s] is checked when defined. */
IMU_HIDDEN ModelStatus ModelEnterInitialization(ModelInstance *mi, const char *function, double startTime,
                                                int stopTimeDefined, double stopTime);
/** @brief Check the parameters, initialise the pipeline and enter Step Mode (Error naming a bad parameter). */
IMU_HIDDEN ModelStatus ModelExitInitialization(ModelInstance *mi, const char *function);
/** @brief Terminate the simulation. */
IMU_HIDDEN ModelStatus ModelTerminate(ModelInstance *mi, const char *function);
/** @brief Read the Real (Float64) variable vr into *value. */
IMU_HIDDEN ModelStatus ModelGetReal(const ModelInstance *mi, const char *function, unsigned int vr, double *value);
/** @brief Write the Real variable vr: inputs in any phase before termination, parameters before initialisation. */
IMU_HIDDEN ModelStatus ModelSetReal(ModelInstance *mi, const char *function, unsigned int vr, double value);
/** @brief FMI 3: how many Float64 values variable vr carries: its length for a coefficient block's array
 *         parameter (VR_COEFFICIENT_BLOCKS + b), 1 for a scalar variable, 0 for an unknown one. */
IMU_HIDDEN size_t ModelFloat64Count(unsigned int vr);
/** @brief FMI 3: read the ModelFloat64Count(vr) values of vr into values (a block, or a scalar Real). */
IMU_HIDDEN ModelStatus ModelGetFloat64s(const ModelInstance *mi, const char *function, unsigned int vr, double *values);
/** @brief FMI 3: write the ModelFloat64Count(vr) values of vr (a block before initialisation, or a scalar Real). */
IMU_HIDDEN ModelStatus ModelSetFloat64s(ModelInstance *mi, const char *function, unsigned int vr, const double *values);
/** @brief Read the Boolean variable vr into *value (0 or 1). */
IMU_HIDDEN ModelStatus ModelGetBoolean(const ModelInstance *mi, const char *function, unsigned int vr, int *value);
/** @brief Write the Boolean parameter vr (before initialisation). */
IMU_HIDDEN ModelStatus ModelSetBoolean(ModelInstance *mi, const char *function, unsigned int vr, int value);
/** @brief Read the Integer (Int32) variable vr into *value. */
IMU_HIDDEN ModelStatus ModelGetInteger(const ModelInstance *mi, const char *function, unsigned int vr, int *value);
/** @brief Write the Integer parameter vr (before initialisation). */
IMU_HIDDEN ModelStatus ModelSetInteger(ModelInstance *mi, const char *function, unsigned int vr, int value);
/**
 * @brief Consume the sample whose inputs are set; the outputs become its estimate.
 * @param t time of the sample [s] (the communication point the step starts at).
 * @param h communication step size [s]: time to the next sample.
 * @return Ok; Warning while any input is bad (one log message per episode); Discard (nothing
 *         consumed) for a step size that is not finite and > 0.
 */
IMU_HIDDEN ModelStatus ModelDoStep(ModelInstance *mi, const char *function, double t, double h);
/** @brief FNV-1a 64 hash of size bytes (offset basis 14695981039346656037, prime 1099511628211):
 *         the checksum of a serialized state's body (tests/test_state_fuzz.py pins it). */
IMU_HIDDEN unsigned long long ModelStateChecksum(const void *bytes, size_t size);
/** @brief Write the sizeof(ModelState) bytes of *state with the checksum of its body into bytes. */
IMU_HIDDEN void ModelSerialize(const ModelState *state, void *bytes);
/** @brief Replace mi's state by *state after checking that it is a state of this binary and
 *         that every field that indexes or sizes anything is valid: settings and coefficients are
 *         re-derived from the state's parameters (settings and coefficient parameters), the
 *         evolving counters and indices are checked (Error naming the first bad field; mi's state
 *         is unchanged then). */
IMU_HIDDEN ModelStatus ModelSetState(ModelInstance *mi, const char *function, const ModelState *state);
/** @brief Check that size bytes are a serialized state of this binary whose checksum matches. */
IMU_HIDDEN ModelStatus ModelCheckSerialized(const ModelInstance *mi, const char *function, const void *bytes, size_t size);

/* ---- hooks every model implements (model.c, sensor/SensorModel.c) -------------------------------- */

/** @brief Kind of the model's variable vr: 'R' Real (Float64), 'B' Boolean, 'I' Integer (Int32), 0 unknown. */
IMU_HIDDEN char ModelVariableType(unsigned int vr);
/** @brief The value of parameter vr (Boolean and Integer parameters are stored as whole numbers). */
IMU_HIDDEN double ModelParameterValue(const ModelData *m, unsigned int vr);
/** @brief Store parameter vr (any type, as double) if parameters may still change; else log and return Error. */
IMU_HIDDEN ModelStatus ModelSetParameter(ModelInstance *mi, const char *function, unsigned int vr, double value);
/** @brief Every variable of m at its start value (the state right after instantiation). */
IMU_HIDDEN void ModelDataStart(ModelData *m);
/**
 * @brief Make the restored state s (its phase, `initialised` and `issues` already checked by ModelCore.c) safe to
 *        run: check every other field of s->model
 *        that indexes or sizes anything and re-derive the parameters' consequences; NULL, or what is wrong.
 */
IMU_HIDDEN const char *ModelDataRestoredProblem(ModelState *s);

#endif
