/**
 * @file win_host.c
 * @brief Loads the FMU's Windows DLL with LoadLibrary and co-simulates it like fmu.cosim.run_fmu
 *        (tests/test_fmu_win64.py runs it under wine).
 *
 * Usage: win_host FMI_VERSION DLL TOKEN [STATE_SAMPLE]
 *
 * FMI_VERSION is 2 or 3, DLL the path of binaries/<platform>/<modelIdentifier>.dll, TOKEN the
 * model description's GUID / instantiationToken. The current directory holds the data the test
 * writes, raw little-endian:
 *   vr_in.bin    uint32 value references of the inputs (their number sets the row width below)
 *   vr_out.bin   uint32 value references of the outputs
 *   samples.bin  N rows of doubles [t_k (s), h_k (s), inputs at the vr_in references]
 * The host instantiates one co-simulation instance (logger to stderr, logging off as fmpy does),
 * starts the experiment at t_0, initialises, then per sample k sets the inputs, calls
 * doStep(t_k, h_k) and gets the outputs into row k of outputs.bin (N rows of doubles at the vr_out
 * references). With STATE_SAMPLE k it also saves the FMU state before sample k (get, serialize,
 * free), and after the last sample restores it (deserialize, set) and runs samples k..N-1 again
 * into replay.bin. doStep may return OK, Warning or Discard (as for run_fmu).
 * Exit status: 0 done, 1 an FMI call failed, 2 bad usage or data files.
 */
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <windows.h>

#include "fmi2FunctionTypes.h"
#include "fmi3FunctionTypes.h"

/** The FMI functions the host calls, for the FMU's version, looked up by name. */
typedef struct {
    int version;
    void *instance;
    fmi2InstantiateTYPE *instantiate2;
    fmi2SetupExperimentTYPE *setupExperiment2;
    fmi2EnterInitializationModeTYPE *enterInit2;
    fmi2ExitInitializationModeTYPE *exitInit2;
    fmi2SetRealTYPE *setReal2;
    fmi2GetRealTYPE *getReal2;
    fmi2DoStepTYPE *doStep2;
    fmi2GetFMUstateTYPE *getState2;
    fmi2SetFMUstateTYPE *setState2;
    fmi2FreeFMUstateTYPE *freeState2;
    fmi2SerializedFMUstateSizeTYPE *stateSize2;
    fmi2SerializeFMUstateTYPE *serialize2;
    fmi2DeSerializeFMUstateTYPE *deserialize2;
    fmi2TerminateTYPE *terminate2;
    fmi2FreeInstanceTYPE *freeInstance2;
    fmi3InstantiateCoSimulationTYPE *instantiate3;
    fmi3EnterInitializationModeTYPE *enterInit3;
    fmi3ExitInitializationModeTYPE *exitInit3;
    fmi3SetFloat64TYPE *setFloat64;
    fmi3GetFloat64TYPE *getFloat64;
    fmi3DoStepTYPE *doStep3;
    fmi3GetFMUStateTYPE *getState3;
    fmi3SetFMUStateTYPE *setState3;
    fmi3FreeFMUStateTYPE *freeState3;
    fmi3SerializedFMUStateSizeTYPE *stateSize3;
    fmi3SerializeFMUStateTYPE *serialize3;
    fmi3DeserializeFMUStateTYPE *deserialize3;
    fmi3TerminateTYPE *terminate3;
    fmi3FreeInstanceTYPE *freeInstance3;
} Fmu;

/** A serialized FMU state. */
typedef struct {
    char *bytes;
    size_t size;
} State;

/** @brief fmi2CallbackLogger: print the FMU's message to stderr. */
static void logger2(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                    fmi2String message, ...) {
    va_list args;
    (void)env;
    fprintf(stderr, "[%d] %s %s: ", (int)status, name, category);
    va_start(args, message);
    vfprintf(stderr, message, args);
    va_end(args);
    fputc('\n', stderr);
}

/** @brief fmi3LogMessageCallback: print the FMU's message to stderr. */
static void logger3(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category, fmi3String message) {
    (void)env;
    fprintf(stderr, "[%d] %s: %s\n", (int)status, category, message);
}

/** @brief Print what failed and exit with status code. */
static void fail(int code, const char *what, const char *detail) {
    fprintf(stderr, "win_host: %s%s%s\n", what, detail[0] != '\0' ? ": " : "", detail);
    exit(code);
}

/** @brief Exit with status 1 unless the FMI call `what` returned OK (or Warning/Discard when tolerated). */
static void check(int status, const char *what, int tolerated) {
    if (status != 0 && !(tolerated && status <= 2)) {
        char code[16];
        sprintf(code, "status %d", status);
        fail(1, what, code);
    }
}

/** @brief The address of function name in library, or exit. */
static FARPROC symbol(HMODULE library, const char *name) {
    FARPROC f = GetProcAddress(library, name);
    if (f == NULL) {
        fail(2, "the DLL does not export", name);
    }
    return f;
}

/* Set field to the DLL's function fn, of the FMI headers' type fnTYPE (through void (*)(void),
 * the function pointer type that converts to any other without a warning). */
#define LOOKUP(field, fn) (fmu->field = (fn##TYPE *)(void (*)(void))symbol(library, #fn))

/** @brief Load dll and look up the FMI `version` functions the host calls. */
static void load(Fmu *fmu, int version, const char *dll) {
    HMODULE library = LoadLibraryA(dll);
    if (library == NULL) {
        fail(2, "LoadLibrary failed for", dll);
    }
    memset(fmu, 0, sizeof(*fmu));
    fmu->version = version;
    if (version == 2) {
        LOOKUP(instantiate2, fmi2Instantiate);
        LOOKUP(setupExperiment2, fmi2SetupExperiment);
        LOOKUP(enterInit2, fmi2EnterInitializationMode);
        LOOKUP(exitInit2, fmi2ExitInitializationMode);
        LOOKUP(setReal2, fmi2SetReal);
        LOOKUP(getReal2, fmi2GetReal);
        LOOKUP(doStep2, fmi2DoStep);
        LOOKUP(getState2, fmi2GetFMUstate);
        LOOKUP(setState2, fmi2SetFMUstate);
        LOOKUP(freeState2, fmi2FreeFMUstate);
        LOOKUP(stateSize2, fmi2SerializedFMUstateSize);
        LOOKUP(serialize2, fmi2SerializeFMUstate);
        LOOKUP(deserialize2, fmi2DeSerializeFMUstate);
        LOOKUP(terminate2, fmi2Terminate);
        LOOKUP(freeInstance2, fmi2FreeInstance);
    } else {
        LOOKUP(instantiate3, fmi3InstantiateCoSimulation);
        LOOKUP(enterInit3, fmi3EnterInitializationMode);
        LOOKUP(exitInit3, fmi3ExitInitializationMode);
        LOOKUP(setFloat64, fmi3SetFloat64);
        LOOKUP(getFloat64, fmi3GetFloat64);
        LOOKUP(doStep3, fmi3DoStep);
        LOOKUP(getState3, fmi3GetFMUState);
        LOOKUP(setState3, fmi3SetFMUState);
        LOOKUP(freeState3, fmi3FreeFMUState);
        LOOKUP(stateSize3, fmi3SerializedFMUStateSize);
        LOOKUP(serialize3, fmi3SerializeFMUState);
        LOOKUP(deserialize3, fmi3DeserializeFMUState);
        LOOKUP(terminate3, fmi3Terminate);
        LOOKUP(freeInstance3, fmi3FreeInstance);
    }
}

/** fmi2CallbackFunctions: the logger above and the C runtime's allocator. */
static const fmi2CallbackFunctions callbacks2 = {logger2, calloc, free, NULL, NULL};

/** @brief Instantiate (no resources: the FMU has none and ignores the location), start the
 *  experiment at startTime (s) and initialise. */
static void initialise(Fmu *fmu, const char *token, double startTime) {
    if (fmu->version == 2) {
        fmu->instance = fmu->instantiate2("ImuFusion", fmi2CoSimulation, token, NULL, &callbacks2, fmi2False, fmi2False);
        if (fmu->instance == NULL) {
            fail(1, "fmi2Instantiate returned NULL", "");
        }
        check(fmu->setupExperiment2(fmu->instance, fmi2False, 0.0, startTime, fmi2False, 0.0), "fmi2SetupExperiment", 0);
        check(fmu->enterInit2(fmu->instance), "fmi2EnterInitializationMode", 0);
        check(fmu->exitInit2(fmu->instance), "fmi2ExitInitializationMode", 0);
    } else {
        fmu->instance = fmu->instantiate3("ImuFusion", token, NULL, fmi3False, fmi3False, fmi3False, fmi3False, NULL, 0,
                                          NULL, logger3, NULL);
        if (fmu->instance == NULL) {
            fail(1, "fmi3InstantiateCoSimulation returned NULL", "");
        }
        check(fmu->enterInit3(fmu->instance, fmi3False, 0.0, startTime, fmi3False, 0.0), "fmi3EnterInitializationMode", 0);
        check(fmu->exitInit3(fmu->instance), "fmi3ExitInitializationMode", 0);
    }
}

/** @brief Set the inputs x at vrIn, doStep(t, h) (s), get the outputs y at vrOut. */
static void step(Fmu *fmu, const uint32_t *vrIn, size_t nIn, const double *x, double t, double h,
                 const uint32_t *vrOut, size_t nOut, double *y) {
    if (fmu->version == 2) {
        check(fmu->setReal2(fmu->instance, vrIn, nIn, x), "fmi2SetReal", 0);
        check(fmu->doStep2(fmu->instance, t, h, fmi2True), "fmi2DoStep", 1);
        check(fmu->getReal2(fmu->instance, vrOut, nOut, y), "fmi2GetReal", 0);
    } else {
        fmi3Boolean event, terminate, early;
        fmi3Float64 last;
        check(fmu->setFloat64(fmu->instance, vrIn, nIn, x, nIn), "fmi3SetFloat64", 0);
        check(fmu->doStep3(fmu->instance, t, h, fmi3True, &event, &terminate, &early, &last), "fmi3DoStep", 1);
        check(fmu->getFloat64(fmu->instance, vrOut, nOut, y, nOut), "fmi3GetFloat64", 0);
    }
}

/** @brief The FMU's current state, serialized (get, serialize, free). */
static State saveState(Fmu *fmu) {
    State s = {NULL, 0};
    if (fmu->version == 2) {
        fmi2FMUstate state = NULL;
        check(fmu->getState2(fmu->instance, &state), "fmi2GetFMUstate", 0);
        check(fmu->stateSize2(fmu->instance, state, &s.size), "fmi2SerializedFMUstateSize", 0);
        s.bytes = malloc(s.size);
        if (s.bytes == NULL) {
            fail(2, "out of memory", "");
        }
        check(fmu->serialize2(fmu->instance, state, (fmi2Byte *)s.bytes, s.size), "fmi2SerializeFMUstate", 0);
        check(fmu->freeState2(fmu->instance, &state), "fmi2FreeFMUstate", 0);
    } else {
        fmi3FMUState state = NULL;
        check(fmu->getState3(fmu->instance, &state), "fmi3GetFMUState", 0);
        check(fmu->stateSize3(fmu->instance, state, &s.size), "fmi3SerializedFMUStateSize", 0);
        s.bytes = malloc(s.size);
        if (s.bytes == NULL) {
            fail(2, "out of memory", "");
        }
        check(fmu->serialize3(fmu->instance, state, (fmi3Byte *)s.bytes, s.size), "fmi3SerializeFMUState", 0);
        check(fmu->freeState3(fmu->instance, &state), "fmi3FreeFMUState", 0);
    }
    return s;
}

/** @brief Make s the FMU's current state (deserialize, set, free). */
static void restoreState(Fmu *fmu, const State *s) {
    if (fmu->version == 2) {
        fmi2FMUstate state = NULL;
        check(fmu->deserialize2(fmu->instance, (const fmi2Byte *)s->bytes, s->size, &state), "fmi2DeSerializeFMUstate", 0);
        check(fmu->setState2(fmu->instance, state), "fmi2SetFMUstate", 0);
        check(fmu->freeState2(fmu->instance, &state), "fmi2FreeFMUstate", 0);
    } else {
        fmi3FMUState state = NULL;
        check(fmu->deserialize3(fmu->instance, (const fmi3Byte *)s->bytes, s->size, &state), "fmi3DeserializeFMUState", 0);
        check(fmu->setState3(fmu->instance, state), "fmi3SetFMUState", 0);
        check(fmu->freeState3(fmu->instance, &state), "fmi3FreeFMUState", 0);
    }
}

/** @brief Terminate and free the instance. */
static void finish(Fmu *fmu) {
    if (fmu->version == 2) {
        check(fmu->terminate2(fmu->instance), "fmi2Terminate", 0);
        fmu->freeInstance2(fmu->instance);
    } else {
        check(fmu->terminate3(fmu->instance), "fmi3Terminate", 0);
        fmu->freeInstance3(fmu->instance);
    }
}

/** @brief The whole file path as a malloc'ed buffer of *count items of itemSize bytes, or exit. */
static void *readFile(const char *path, size_t itemSize, size_t *count) {
    FILE *f = fopen(path, "rb");
    char *data;
    long size;
    if (f == NULL || fseek(f, 0, SEEK_END) != 0 || (size = ftell(f)) <= 0 || fseek(f, 0, SEEK_SET) != 0) {
        fail(2, "cannot read", path);
    }
    if ((size_t)size % itemSize != 0 || (data = malloc((size_t)size)) == NULL ||
        fread(data, 1, (size_t)size, f) != (size_t)size) {
        fail(2, "malformed", path);
    }
    fclose(f);
    *count = (size_t)size / itemSize;
    return data;
}

/** @brief Write count doubles to path, or exit. */
static void writeFile(const char *path, const double *values, size_t count) {
    FILE *f = fopen(path, "wb");
    if (f == NULL || fwrite(values, sizeof(double), count, f) != count || fclose(f) != 0) {
        fail(2, "cannot write", path);
    }
}

int main(int argc, char **argv) {
    Fmu fmu;
    State state = {NULL, 0};
    size_t nIn, nOut, nValues, nSamples, width, k, stateSample = 0;
    uint32_t *vrIn, *vrOut;
    double *samples, *outputs;
    int version = argc >= 4 ? atoi(argv[1]) : 0;
    int replay = argc == 5;
    if ((version != 2 && version != 3) || argc > 5) {
        fail(2, "usage", "win_host FMI_VERSION(2|3) DLL TOKEN [STATE_SAMPLE]");
    }
    vrIn = readFile("vr_in.bin", sizeof(uint32_t), &nIn);
    vrOut = readFile("vr_out.bin", sizeof(uint32_t), &nOut);
    width = 2 + nIn;
    samples = readFile("samples.bin", width * sizeof(double), &nSamples);
    nValues = nSamples * nOut;
    outputs = malloc(nValues * sizeof(double));
    if (replay) {
        stateSample = (size_t)strtoul(argv[4], NULL, 10);
        if (stateSample >= nSamples) {
            fail(2, "STATE_SAMPLE must be below the number of samples", argv[4]);
        }
    }
    if (outputs == NULL) {
        fail(2, "out of memory", "");
    }
    load(&fmu, version, argv[2]);
    initialise(&fmu, argv[3], samples[0]);
    for (k = 0; k < nSamples; k++) {
        const double *row = samples + k * width;
        if (replay && k == stateSample) {
            state = saveState(&fmu);
        }
        step(&fmu, vrIn, nIn, row + 2, row[0], row[1], vrOut, nOut, outputs + k * nOut);
    }
    writeFile("outputs.bin", outputs, nValues);
    if (replay) {
        restoreState(&fmu, &state);
        for (k = stateSample; k < nSamples; k++) {
            const double *row = samples + k * width;
            step(&fmu, vrIn, nIn, row + 2, row[0], row[1], vrOut, nOut, outputs + (k - stateSample) * nOut);
        }
        writeFile("replay.bin", outputs, (nSamples - stateSample) * nOut);
        free(state.bytes);
    }
    finish(&fmu);
    free(vrIn);
    free(vrOut);
    free(samples);
    free(outputs);
    return 0;
}
