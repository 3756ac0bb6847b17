/**
 * @file cosim_driver.c
 * @brief Loads an FMI 3 ImuFusion binary with dlopen and co-simulates it: for valgrind memcheck.
 *
 * Usage: cosim_driver BINARY.so INSTANTIATION_TOKEN. Two instances run 500 steps each, with a
 * stretch of NaN and saturated input, an FMU state saved, serialised, restored and freed, and a
 * failed initialisation. Exit status 0 when every call returned the expected status.
 */
#include <dlfcn.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "fmi3FunctionTypes.h"
#include "config.h"

#define STEPS 500

/** The FMI 3 functions the driver calls, looked up by name. */
typedef struct {
    fmi3InstantiateCoSimulationTYPE *instantiate;
    fmi3EnterInitializationModeTYPE *enterInit;
    fmi3ExitInitializationModeTYPE *exitInit;
    fmi3SetFloat64TYPE *setFloat64;
    fmi3GetFloat64TYPE *getFloat64;
    fmi3DoStepTYPE *doStep;
    fmi3GetFMUStateTYPE *getState;
    fmi3SetFMUStateTYPE *setState;
    fmi3FreeFMUStateTYPE *freeState;
    fmi3SerializedFMUStateSizeTYPE *stateSize;
    fmi3SerializeFMUStateTYPE *serialize;
    fmi3DeserializeFMUStateTYPE *deserialize;
    fmi3TerminateTYPE *terminate;
    fmi3FreeInstanceTYPE *freeInstance;
} Api;

/** @brief Print every message the FMU logs. */
static void printLog(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category, fmi3String message) {
    (void)env;
    printf("[%d] %s: %s\n", (int)status, category, message);
}

/** @brief Look up symbol name in library, or exit. */
static void *symbol(void *library, const char *name) {
    void *f = dlsym(library, name);
    if (f == NULL) {
        printf("missing symbol %s\n", name);
        exit(2);
    }
    return f;
}

/** @brief Run one instance for STEPS samples with bad input in steps 200..219; 0 on success. */
static int simulate(const Api *api, const char *token, int withState) {
    const fmi3ValueReference inputs[10] = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9};
    fmi3ValueReference outputs[20];
    double x[10], y[20], last;
    fmi3Boolean event, terminate, early;
    fmi3FMUState state = NULL, restored = NULL;
    fmi3Byte *bytes = NULL;
    size_t size = 0;
    int k, failures = 0;
    fmi3Instance s = api->instantiate("driver", token, "", fmi3False, fmi3False, fmi3False, fmi3False, NULL, 0, NULL,
                                      printLog, NULL);
    if (s == NULL) {
        return 1;
    }
    for (k = 0; k < 20; k++) {
        outputs[k] = (fmi3ValueReference)(10 + k);
    }
    failures += api->enterInit(s, fmi3False, 0.0, 0.0, fmi3False, 0.0) != fmi3OK;
    failures += api->exitInit(s) != fmi3OK;
    for (k = 0; k < STEPS; k++) {
        const double t = 0.01 * k;
        fmi3Status expected = fmi3OK;
        x[0] = 0.1 * sin(t); x[1] = 0.2; x[2] = -0.1;
        x[3] = 0.3; x[4] = -0.2; x[5] = -9.8;
        x[6] = 20.0 * cos(0.2 * t); x[7] = -20.0 * sin(0.2 * t); x[8] = 40.0; x[9] = 25.0;
        if (k >= 200 && k < 220) {
            x[1] = NAN;
            x[7] = 1e7;
            expected = fmi3Warning;
        }
        if (withState && k == 300) {
            failures += api->getState(s, &state) != fmi3OK;
            failures += api->stateSize(s, state, &size) != fmi3OK;
            bytes = (fmi3Byte *)malloc(size);
            failures += api->serialize(s, state, bytes, size) != fmi3OK;
            failures += api->deserialize(s, bytes, size, &restored) != fmi3OK;
            failures += api->setState(s, restored) != fmi3OK;
        }
        failures += api->setFloat64(s, inputs, 10, x, 10) != fmi3OK;
        failures += api->doStep(s, t, 0.01, fmi3True, &event, &terminate, &early, &last) != expected;
        failures += api->getFloat64(s, outputs, 20, y, 20) != fmi3OK;
    }
    failures += api->terminate(s) != fmi3OK;
    if (withState) {
        api->freeState(s, &state);
        api->freeState(s, &restored);
        free(bytes);
    }
    api->freeInstance(s);
    return failures;
}

/** @brief An instance whose initialisation fails on a bad parameter (field_norm = -1 uT); 0 if it does. */
static int failInitialisation(const Api *api, const char *token) {
    const fmi3ValueReference fieldNorm = vr_field_norm;
    const double bad = -1.0;
    int failures = 0;
    fmi3Instance s = api->instantiate("bad", token, "", fmi3False, fmi3False, fmi3False, fmi3False, NULL, 0, NULL,
                                      printLog, NULL);
    failures += s == NULL;
    failures += api->setFloat64(s, &fieldNorm, 1, &bad, 1) != fmi3OK;
    failures += api->enterInit(s, fmi3False, 0.0, 0.0, fmi3False, 0.0) != fmi3OK;
    failures += api->exitInit(s) != fmi3Error;
    api->freeInstance(s);
    return failures;
}

int main(int argc, char **argv) {
    Api api;
    void *library;
    int failures;
    if (argc != 3) {
        printf("usage: %s BINARY.so INSTANTIATION_TOKEN\n", argv[0]);
        return 2;
    }
    library = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (library == NULL) {
        printf("cannot load %s: %s\n", argv[1], dlerror());
        return 2;
    }
    *(void **)&api.instantiate = symbol(library, "fmi3InstantiateCoSimulation");
    *(void **)&api.enterInit = symbol(library, "fmi3EnterInitializationMode");
    *(void **)&api.exitInit = symbol(library, "fmi3ExitInitializationMode");
    *(void **)&api.setFloat64 = symbol(library, "fmi3SetFloat64");
    *(void **)&api.getFloat64 = symbol(library, "fmi3GetFloat64");
    *(void **)&api.doStep = symbol(library, "fmi3DoStep");
    *(void **)&api.getState = symbol(library, "fmi3GetFMUState");
    *(void **)&api.setState = symbol(library, "fmi3SetFMUState");
    *(void **)&api.freeState = symbol(library, "fmi3FreeFMUState");
    *(void **)&api.stateSize = symbol(library, "fmi3SerializedFMUStateSize");
    *(void **)&api.serialize = symbol(library, "fmi3SerializeFMUState");
    *(void **)&api.deserialize = symbol(library, "fmi3DeserializeFMUState");
    *(void **)&api.terminate = symbol(library, "fmi3Terminate");
    *(void **)&api.freeInstance = symbol(library, "fmi3FreeInstance");
    failures = simulate(&api, argv[2], 1) + simulate(&api, argv[2], 0) + failInitialisation(&api, argv[2]);
    dlclose(library);
    printf("driver: %d failures\n", failures);
    return failures == 0 ? 0 : 1;
}
