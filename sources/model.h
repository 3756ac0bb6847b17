/**
 * @file model.h
 * @brief FMI-free core of the ImuFusion FMU, shared by the FMI 2.0 and FMI 3.0 wrappers.
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
#include "ImuLayout.h"
#include "ImuRuntime.h"
#include "config.h"

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

/** Kinds of bad input (one bit each); an episode of a kind lasts while its bit stays set. The
 *  input and time kinds are those of the shared guard (ImuGuard.h). */
typedef enum {
    ModelIssueGyr = ImuGuardIssueGyr,         /* gyroscope not finite or beyond IMU_GUARD_GYR_LIMIT */
    ModelIssueAcc = ImuGuardIssueAcc,         /* accelerometer not finite or beyond IMU_GUARD_ACC_LIMIT */
    ModelIssueMag = ImuGuardIssueMag,         /* magnetometer not finite or an axis saturated */
    ModelIssueMagZero = ImuGuardIssueMagZero, /* magnetometer reads (almost) no field */
    ModelIssueTemp = ImuGuardIssueTemp,       /* temperature not finite or outside the valid range */
    ModelIssueOrder = ImuGuardIssueOrder,     /* time since the previous sample not finite and > 0 */
    ModelIssueGap = ImuGuardIssueGap,         /* a gap: step longer than IMU_GUARD_GAP_STEPS nominal steps */
    ModelIssueStep = 1 << 7,    /* step size not finite and > 0: the step is discarded */
    ModelIssueOutput = ImuGuardIssueOutput, /* an output was not finite although the inputs were valid */
    ModelIssueAux = ImuGuardIssueAux,       /* an auxiliary input a correction term uses is not finite: held */
    ModelIssueCalibration = 1 << 10 /* a model input left its calibrated range (ImuRangeIssue): evaluated clamped */
} ModelIssue;

#define MODEL_ISSUE_COUNT 11

/** Every value of the model and the pipeline that produces the outputs. */
typedef struct {
    double inputs[IMU_INPUT_COUNT];     /* raw sample as set: rad/s, m/s^2, uT, degC, auxiliary inputs */
    double outputs[IMU_OUTPUT_COUNT];   /* estimate for the last consumed sample: finite, except the
                                         * corrected outputs of an absent sensor (NaN, ImuGuard.h) */
    double settings[IMU_SETTING_COUNT]; /* parameters in user units (ImuLayout.h order) */
    double coefficients[IMU_COEFFICIENT_COUNT]; /* the coefficient parameters (contract/coefficient_parameters.py):
                                         * start = the compiled-in ImuCoefficientsData.h */
    int issues;                         /* ModelIssue bits of the last step */
    double stepSize;                    /* s, communicationStepSize of the last doStep: the time from
                                         * the last consumed sample to the next (ImuGuardStep) */
    int initialised;                    /* 1 once settings are applied: parameters are locked */
    ImuRuntime runtime;                 /* the guarded pipeline (ImuRuntime.h, shared with the batch library) */
} ModelData;

#define MODEL_GUID_SIZE 48

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

#endif
