/**
 * @file state_fuzz.c
 * @brief Restore mutated serialized FMU states into FMI 3 instances (tests/test_state_fuzz.py).
 *
 * Built with the FMU sources (FMI 3 wrapper) and a generated ImuCoefficientsData.h, under
 * AddressSanitizer + UndefinedBehaviorSanitizer by the test. Three modes:
 *   state_fuzz layout          one line "member offset size" per field of ModelState that
 *                              indexes, sizes or switches something (the fields the test edits)
 *   state_fuzz base OUT        run an instance (particle filter on) for BASE_STEPS samples and
 *                              write its serialized state to OUT
 *   state_fuzz restore IN      IN holds records [8-byte little-endian size, bytes]; each is
 *                              deserialized and set into a fresh initialised instance that then
 *                              runs RESTORED_STEPS samples. One line per record:
 *                              "rejected <message>", "finite", "nonfinite" (an output not
 *                              finite) or "steperror" (doStep returned Error: a restored phase
 *                              that does not step); a crash or sanitizer report aborts the program.
 */
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "model.h"
#include "motion.h"

#define BASE_STEPS 300
#define RESTORED_STEPS 100
#define STEP_SIZE 0.01 /* s */

/** The last Error message an instance logged. */
typedef struct {
    char last[640];
} ErrorLog;

/** @brief fmi3LogMessageCallback keeping the last Error message. */
static void keepError(fmi3InstanceEnvironment environment, fmi3Status status, fmi3String category, fmi3String message) {
    ErrorLog *log = (ErrorLog *)environment;
    (void)category;
    if (status == fmi3Error) {
        strncpy(log->last, message, sizeof log->last - 1);
    }
}

/** @brief Sample k of the test motion (motion.h) with a hard iron of (3, -2, 0) uT. */
static void sample(int k, double x[IMU_INPUT_COUNT]) {
    motionSample(k * STEP_SIZE, x);
    x[6] += 3.0;
    x[7] -= 2.0;
}

/** @brief Instantiate and initialise an FMI 3 instance with the particle filter on (sphere bins 2). */
static fmi3Instance start(ErrorLog *log) {
    const fmi3ValueReference flag = vr_enable_pf;
    const fmi3Boolean on = fmi3True;
    const fmi3ValueReference bins = vr_pf_sphere_bins;
    const fmi3Int32 two = 2;
    fmi3Instance s = fmi3InstantiateCoSimulation("fuzz", ModelGuid(), "", fmi3False, fmi3False, fmi3False, fmi3False,
                                                 NULL, 0, log, keepError, NULL);
    if (s == NULL || fmi3SetBoolean(s, &flag, 1, &on, 1) != fmi3OK || fmi3SetInt32(s, &bins, 1, &two, 1) != fmi3OK
        || fmi3EnterInitializationMode(s, fmi3False, 0.0, 0.0, fmi3False, 0.0) != fmi3OK
        || fmi3ExitInitializationMode(s) != fmi3OK) {
        fprintf(stderr, "cannot initialise an instance: %s\n", log->last);
        exit(2);
    }
    return s;
}

/** @brief Step samples from..to-1 from time t0 [s]; 1 if every output of every step was finite,
 *         0 if one was not, -1 if a doStep returned Error. */
static int run(fmi3Instance s, int from, int to, double t0) {
    static const fmi3ValueReference inputVrs[IMU_INPUT_COUNT] = IMU_INPUT_VRS;
    static const fmi3ValueReference outVrs[IMU_OUTPUT_COUNT] = IMU_OUTPUT_VRS;
    double x[IMU_INPUT_COUNT], out[IMU_OUTPUT_COUNT];
    fmi3Boolean event, terminate, early;
    fmi3Float64 last;
    int k, j, finite = 1;
    for (k = from; k < to; k++) {
        sample(k, x);
        fmi3SetFloat64(s, inputVrs, IMU_INPUT_COUNT, x, IMU_INPUT_COUNT);
        if (fmi3DoStep(s, t0 + (k - from) * STEP_SIZE, STEP_SIZE, fmi3True, &event, &terminate, &early, &last) == fmi3Error) {
            return -1;
        }
        fmi3GetFloat64(s, outVrs, IMU_OUTPUT_COUNT, out, IMU_OUTPUT_COUNT);
        for (j = 0; j < IMU_OUTPUT_COUNT; j++) {
            finite &= isfinite(out[j]) != 0;
        }
    }
    return finite;
}

#define FIELD(member) printf("%s %lu %lu\n", #member, (unsigned long)offsetof(ModelState, member), \
                             (unsigned long)sizeof(((ModelState *)0)->member))

/** @brief Print the fields the test edits: every int of the state that indexes, sizes or switches
 *         something, and the parameters (doubles) that size the particle filter. */
static void layout(void) {
    FIELD(phase);
    FIELD(time);
    FIELD(model.initialised);
    FIELD(model.issues);
    FIELD(model.stepSize);
    FIELD(model.runtime.guard.hasSample);
    FIELD(model.runtime.guard.present);
    FIELD(model.runtime.guard.held[0]);
    FIELD(model.runtime.guard.clock);
    FIELD(model.runtime.guard.stepCount);
    FIELD(model.runtime.guard.stepHead);
    FIELD(model.runtime.guard.steps[0]);
    FIELD(model.settings[ImuSetAttitudeMode]);
    FIELD(model.settings[ImuSetPfParticles]);
    FIELD(model.settings[ImuSetPfDecimation]);
    FIELD(model.settings[ImuSetPfSphereBins]);
    FIELD(model.settings[ImuSetEnablePf]);
    FIELD(model.runtime.pipeline.settings.attitudeMode);
    FIELD(model.runtime.pipeline.settings.enablePf);
    FIELD(model.runtime.pipeline.settings.enablePsoBp);
    FIELD(model.runtime.pipeline.settings.enableElm);
    FIELD(model.runtime.pipeline.settings.pf.particleCount);
    FIELD(model.runtime.pipeline.settings.pf.decimation);
    FIELD(model.runtime.pipeline.settings.pf.hiddenUnits);
    FIELD(model.runtime.pipeline.settings.pf.sphereBins);
    FIELD(model.runtime.pipeline.coefficients.thermal[0].degree);
    FIELD(model.runtime.pipeline.coefficients.thermal[2].enabled);
    FIELD(model.runtime.pipeline.coefficients.terms.count);
    FIELD(model.runtime.pipeline.coefficients.terms.target[0]);
    FIELD(model.runtime.pipeline.coefficients.terms.a[0]);
    FIELD(model.runtime.pipeline.coefficients.terms.b[0]);
    FIELD(model.runtime.pipeline.coefficients.elm.enabled);
    FIELD(model.runtime.pipeline.coefficients.elm.hidden);
    FIELD(model.runtime.pipeline.coefficients.elm.activation);
    FIELD(model.runtime.pipeline.coefficients.psobp.mode);
    FIELD(model.runtime.pipeline.coefficients.psobp.hidden);
    FIELD(model.runtime.pipeline.attitude.settings.mode);
    FIELD(model.runtime.pipeline.attitude.tiltInitialised);
    FIELD(model.runtime.pipeline.attitude.nominalStep);
    FIELD(model.runtime.pipeline.attitude.accLowPass.count);
    FIELD(model.runtime.pipeline.attitude.accLowPass.meanTime);
    FIELD(model.runtime.pipeline.attitude.accLowPass.initialised);
    FIELD(model.runtime.pipeline.attitude.motionBias.rotatedBias.count);
    FIELD(model.runtime.pipeline.attitude.motionBias.rotation[1].count);
    FIELD(model.runtime.pipeline.align.count);
    FIELD(model.runtime.pipeline.align.head);
    FIELD(model.runtime.pipeline.align.time[0]);
    FIELD(model.runtime.pipeline.terms.started);
    FIELD(model.runtime.pipeline.terms.lastTime);
    FIELD(model.runtime.pipeline.pf.settings.particleCount);
    FIELD(model.runtime.pipeline.pf.settings.decimation);
    FIELD(model.runtime.pipeline.pf.settings.sphereBins);
    FIELD(model.runtime.pipeline.pf.settings.hiddenUnits);
    FIELD(model.runtime.pipeline.pf.settings.raoBlackwell);
    FIELD(model.runtime.pipeline.pf.rng.hasSpare);
    FIELD(model.runtime.pipeline.pf.sampleCounter);
    FIELD(model.runtime.pipeline.pf.binUsed[5]);
    FIELD(model.runtime.pipeline.pf.binList[0]);
    FIELD(model.runtime.pipeline.pf.binCount);
    FIELD(model.runtime.pipeline.pf.evidenceDirections);
    FIELD(model.runtime.pipeline.pf.retestDirections);
    FIELD(model.runtime.pipeline.pf.work.parent[0]);
    FIELD(model.runtime.pipeline.psobp.started);
    FIELD(model.runtime.pipeline.psobp.tau);
    FIELD(model.runtime.pipeline.psobp.time);
}

/** @brief Write the serialized state of an instance that ran BASE_STEPS samples to path. */
static int base(const char *path) {
    ErrorLog log = {{0}};
    fmi3Instance s = start(&log);
    fmi3FMUState state = NULL;
    size_t size = 0;
    unsigned char *bytes;
    FILE *f = fopen(path, "wb");
    if (f == NULL || run(s, 0, BASE_STEPS, 0.0) != 1 || fmi3GetFMUState(s, &state) != fmi3OK
        || fmi3SerializedFMUStateSize(s, state, &size) != fmi3OK || (bytes = malloc(size)) == NULL) {
        fprintf(stderr, "%s: cannot make the base state\n", path);
        return 2;
    }
    fmi3SerializeFMUState(s, state, bytes, size);
    fwrite(bytes, 1, size, f);
    fclose(f);
    free(bytes);
    fmi3FreeFMUState(s, &state);
    fmi3FreeInstance(s);
    return 0;
}

/** @brief Restore one record of n bytes into a fresh instance and print the outcome line. */
static void restoreOne(const unsigned char *bytes, size_t n) {
    ErrorLog log = {{0}};
    fmi3Instance s = start(&log);
    fmi3FMUState state = NULL;
    int outcome;
    if (fmi3DeserializeFMUState(s, bytes, n, &state) != fmi3OK || fmi3SetFMUState(s, state) != fmi3OK) {
        printf("rejected %s\n", log.last);
    } else {
        outcome = run(s, BASE_STEPS, BASE_STEPS + RESTORED_STEPS, BASE_STEPS * STEP_SIZE);
        printf("%s\n", outcome == 1 ? "finite" : outcome == 0 ? "nonfinite" : "steperror");
    }
    fmi3FreeFMUState(s, &state);
    fmi3FreeInstance(s);
}

/** @brief Restore every record of the file at path. */
static int restore(const char *path) {
    FILE *f = fopen(path, "rb");
    unsigned char header[8];
    if (f == NULL) {
        fprintf(stderr, "%s: cannot open\n", path);
        return 2;
    }
    while (fread(header, 1, sizeof header, f) == sizeof header) {
        size_t n = 0, i;
        unsigned char *bytes;
        for (i = 0; i < sizeof header; i++) {
            n |= (size_t)header[i] << (8 * i);
        }
        bytes = malloc(n > 0 ? n : 1);
        if (bytes == NULL || fread(bytes, 1, n, f) != n) {
            fprintf(stderr, "%s: truncated record\n", path);
            return 2;
        }
        restoreOne(bytes, n);
        free(bytes);
    }
    fclose(f);
    return 0;
}

int main(int argc, char **argv) {
    if (argc == 2 && strcmp(argv[1], "layout") == 0) {
        layout();
        return 0;
    }
    if (argc == 3 && strcmp(argv[1], "base") == 0) {
        return base(argv[2]);
    }
    if (argc == 3 && strcmp(argv[1], "restore") == 0) {
        return restore(argv[2]);
    }
    fprintf(stderr, "usage: state_fuzz layout | base OUT | restore IN\n");
    return 2;
}
