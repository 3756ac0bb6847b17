/**
 * @file test_glue.c
 * @brief C tests of the FMU glue (model.c + both FMI wrappers) and the runtime behind it.
 *
 * Built by tests/test_fmu_robust.py together with the FMU sources and a generated
 * ImuCoefficientsData.h, with AddressSanitizer and UndefinedBehaviorSanitizer. Prints one line
 * per failed check and "N passed, M failed" at the end; the exit status is 1 if any failed.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "model.h"
#include "motion.h"

#define STEPS 400
#define STEP_SIZE 0.01 /* s */

static int passed, failed;

/** @brief Record one check: print what failed. */
static void check(int ok, const char *what, int line) {
    if (ok) {
        passed++;
    } else {
        failed++;
        printf("FAILED (line %d): %s\n", line, what);
    }
}
#define CHECK(x) check((x) != 0, #x, __LINE__)

/** Log messages received by one instance. */
typedef struct {
    int warnings;     /* status Warning */
    int errors;       /* status Error */
    int badInput;     /* category logBadInput with status Warning */
    char last[640];   /* the last message */
} LogCount;

/** @brief fmi3LogMessageCallback counting messages in the LogCount passed as environment. */
static void countLog(fmi3InstanceEnvironment environment, fmi3Status status, fmi3String category, fmi3String message) {
    LogCount *log = (LogCount *)environment;
    log->warnings += status == fmi3Warning;
    log->errors += status == fmi3Error;
    log->badInput += status == fmi3Warning && strcmp(category, "logBadInput") == 0;
    strncpy(log->last, message, sizeof log->last - 1);
}

/** @brief Sample k of the test motion (motion.h) with varying auxiliary inputs. */
static void sample(int k, double x[IMU_INPUT_COUNT]) {
    const double t = k * STEP_SIZE;
    int i;
    motionSample(t, x);
    for (i = ImuInAux1; i < IMU_INPUT_COUNT; i++) {
        x[i] = sin((i - ImuInAux1 + 1) * t); /* unused by the identity coefficients */
    }
}

static const fmi3ValueReference inputVrs[IMU_INPUT_COUNT] = IMU_INPUT_VRS;

/** @brief Instantiate and initialise an FMI 3 instance logging into log (field_norm [uT] set first). */
static fmi3Instance start(LogCount *log, double fieldNorm) {
    const fmi3ValueReference vr = vr_field_norm;
    fmi3Instance s = fmi3InstantiateCoSimulation("test", ModelGuid(), "", fmi3False, fmi3False, fmi3False, fmi3False,
                                                 NULL, 0, log, countLog, NULL);
    if (s == NULL) {
        return NULL;
    }
    fmi3SetFloat64(s, &vr, 1, &fieldNorm, 1);
    fmi3EnterInitializationMode(s, fmi3False, 0.0, 0.0, fmi3False, 0.0);
    if (fmi3ExitInitializationMode(s) != fmi3OK) {
        fmi3FreeInstance(s);
        return NULL;
    }
    return s;
}

/** @brief Set sample x, step from t [s] by h [s], read every output; the doStep status. */
static fmi3Status step(fmi3Instance s, const double x[IMU_INPUT_COUNT], double t, double h, double out[IMU_OUTPUT_COUNT]) {
    static const fmi3ValueReference outVrs[IMU_OUTPUT_COUNT] = IMU_OUTPUT_VRS;
    fmi3Boolean event, terminate, early;
    fmi3Float64 last;
    fmi3Status status;
    fmi3SetFloat64(s, inputVrs, IMU_INPUT_COUNT, x, IMU_INPUT_COUNT);
    status = fmi3DoStep(s, t, h, fmi3True, &event, &terminate, &early, &last);
    fmi3GetFloat64(s, outVrs, IMU_OUTPUT_COUNT, out, IMU_OUTPUT_COUNT);
    return status;
}

/** @brief 1 if every output is finite. */
static int allFinite(const double out[IMU_OUTPUT_COUNT]) {
    int j;
    for (j = 0; j < IMU_OUTPUT_COUNT; j++) {
        if (!isfinite(out[j])) {
            return 0;
        }
    }
    return 1;
}

/** @brief Run STEPS clean samples from sample `from`; outputs into out[STEPS - from][...]. */
static void run(fmi3Instance s, int from, double (*out)[IMU_OUTPUT_COUNT]) {
    double x[IMU_INPUT_COUNT];
    int k;
    for (k = from; k < STEPS; k++) {
        sample(k, x);
        step(s, x, k * STEP_SIZE, STEP_SIZE, out[k - from]);
    }
}

static double reference[STEPS][IMU_OUTPUT_COUNT];

/** Interleaved instances give the same outputs as one alone (no shared mutable state). */
static void testInstancesAreIndependent(void) {
    static double a[STEPS][IMU_OUTPUT_COUNT], b[STEPS][IMU_OUTPUT_COUNT];
    LogCount la = {0, 0, 0, ""}, lb = {0, 0, 0, ""}, lr = {0, 0, 0, ""};
    fmi3Instance r = start(&lr, 50.0), sa = start(&la, 50.0), sb = start(&lb, 45.0);
    double x[IMU_INPUT_COUNT];
    int k;
    CHECK(r != NULL && sa != NULL && sb != NULL);
    run(r, 0, reference);
    for (k = 0; k < STEPS; k++) {
        sample(k, x);
        step(sa, x, k * STEP_SIZE, STEP_SIZE, a[k]);
        x[ImuInMagZ] += 5.0; /* a different field for the second instance */
        step(sb, x, k * STEP_SIZE, STEP_SIZE, b[k]);
    }
    CHECK(memcmp(a, reference, sizeof a) == 0);
    CHECK(memcmp(b, reference, sizeof b) != 0);
    CHECK(la.warnings == 0 && la.errors == 0);
    fmi3FreeInstance(r);
    fmi3FreeInstance(sa);
    fmi3FreeInstance(sb);
}

/** Save at a split, run on, restore (also serialised into another instance): identical outputs. */
static void testStateRestoreIsExact(void) {
    static double out[STEPS][IMU_OUTPUT_COUNT];
    const size_t tailBytes = (STEPS - 150) * sizeof out[0];
    LogCount log = {0, 0, 0, ""};
    fmi3Instance s = start(&log, 50.0), other = start(&log, 30.0);
    fmi3FMUState initial = NULL, middle = NULL, restored = NULL;
    fmi3Byte *bytes;
    size_t size = 0;
    const int split = 150;
    CHECK(s != NULL && other != NULL);
    CHECK(fmi3GetFMUState(s, &initial) == fmi3OK);
    run(s, 0, out);
    CHECK(memcmp(out, reference, sizeof out) == 0);
    CHECK(fmi3SetFMUState(s, initial) == fmi3OK);
    run(s, STEPS - split, out); /* a different history up to the split */
    CHECK(fmi3SetFMUState(s, initial) == fmi3OK);
    run(s, STEPS - split, out);
    CHECK(fmi3SetFMUState(s, initial) == fmi3OK);
    {
        double x[IMU_INPUT_COUNT];
        int k;
        for (k = 0; k < split; k++) {
            sample(k, x);
            step(s, x, k * STEP_SIZE, STEP_SIZE, out[k]);
        }
    }
    CHECK(fmi3GetFMUState(s, &middle) == fmi3OK);
    CHECK(fmi3SerializedFMUStateSize(s, middle, &size) == fmi3OK && size == sizeof(ModelState));
    bytes = (fmi3Byte *)malloc(size);
    CHECK(fmi3SerializeFMUState(s, middle, bytes, size) == fmi3OK);
    run(s, split, out);
    CHECK(memcmp(out, reference[split], tailBytes) == 0);
    CHECK(fmi3SetFMUState(s, middle) == fmi3OK);
    run(s, split, out);
    CHECK(memcmp(out, reference[split], tailBytes) == 0);
    CHECK(fmi3DeserializeFMUState(other, bytes, size, &restored) == fmi3OK);
    CHECK(fmi3SetFMUState(other, restored) == fmi3OK);
    run(other, split, out);
    CHECK(memcmp(out, reference[split], tailBytes) == 0);
    CHECK(fmi3Reset(s) == fmi3OK); /* Reset returns to the initial state */
    CHECK(fmi3EnterInitializationMode(s, fmi3False, 0.0, 0.0, fmi3False, 0.0) == fmi3OK);
    CHECK(fmi3ExitInitializationMode(s) == fmi3OK);
    run(s, 0, out);
    CHECK(memcmp(out, reference, sizeof out) == 0);
    bytes[0] ^= 0xFF; /* no longer a state of this binary */
    CHECK(fmi3DeserializeFMUState(other, bytes, size, &restored) == fmi3Error);
    CHECK(fmi3DeserializeFMUState(other, bytes, size - 1, &restored) == fmi3Error);
    free(bytes);
    fmi3FreeFMUState(s, &initial);
    fmi3FreeFMUState(s, &middle);
    fmi3FreeFMUState(other, &restored);
    CHECK(initial == NULL && middle == NULL && restored == NULL);
    fmi3FreeInstance(s);
    fmi3FreeInstance(other);
}

/** One bad-input kind: input index (or -1 for the step size) and the value written there. */
typedef struct {
    const char *name;
    int input;   /* ImuInput, -1: step size */
    double value;
    fmi3Status expected;
} BadInput;

/** Every bad input: Warning (Discard for step size), finite outputs, one message, recovery. */
static void testBadInputIsHeld(void) {
    static const BadInput cases[] = {
        {"gyr NaN", ImuInGyrX, NAN, fmi3Warning},
        {"gyr +Inf", ImuInGyrY, INFINITY, fmi3Warning},
        {"gyr 1e300", ImuInGyrZ, 1e300, fmi3Warning},
        {"acc -Inf", ImuInAccX, -INFINITY, fmi3Warning},
        {"acc 1e6", ImuInAccZ, 1e6, fmi3Warning},
        {"mag NaN", ImuInMagY, NAN, fmi3Warning},
        {"mag saturated axis", ImuInMagX, 5000.0, fmi3Warning},
        {"temp NaN", ImuInTemp, NAN, fmi3Warning},
        {"temp 400 degC", ImuInTemp, 400.0, fmi3Warning},
        {"temp -100 degC", ImuInTemp, -100.0, fmi3Warning},
        {"step 0", -1, 0.0, fmi3Discard},
        {"step -0.01", -1, -0.01, fmi3Discard},
        {"step NaN", -1, NAN, fmi3Discard},
        {"step Inf", -1, INFINITY, fmi3Discard},
    };
    size_t c;
    for (c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        LogCount log = {0, 0, 0, ""};
        fmi3Instance s = start(&log, 50.0);
        double x[IMU_INPUT_COUNT], out[IMU_OUTPUT_COUNT], held[IMU_OUTPUT_COUNT];
        int k, ok = 1;
        for (k = 0; k < 100; k++) {
            sample(k, x);
            step(s, x, k * STEP_SIZE, STEP_SIZE, held);
        }
        for (k = 100; k < 140; k++) { /* one episode of 40 bad samples */
            double h = STEP_SIZE;
            sample(k, x);
            if (cases[c].input >= 0) {
                x[cases[c].input] = cases[c].value;
            } else {
                h = cases[c].value;
            }
            ok &= step(s, x, k * STEP_SIZE, h, out) == cases[c].expected;
            ok &= allFinite(out);
        }
        if (!ok || log.badInput != 1 || log.errors != 0) {
            printf("bad input '%s': status or outputs wrong, or %d messages: %s\n", cases[c].name, log.badInput, log.last);
        }
        CHECK(ok && log.badInput == 1 && log.errors == 0);
        if (cases[c].expected == fmi3Discard) {
            CHECK(memcmp(out, held, sizeof out) == 0); /* nothing consumed */
        }
        for (k = 140; k < 160; k++) {
            sample(k, x);
            ok &= step(s, x, k * STEP_SIZE, STEP_SIZE, out) == fmi3OK;
        }
        CHECK(ok && allFinite(out) && log.badInput == 1);
        fmi3FreeInstance(s);
    }
}

/** No field at all and huge gaps (the step size of the previous doStep): Warning, finite outputs. */
static void testZeroFieldAndHugeGap(void) {
    LogCount log = {0, 0, 0, ""};
    fmi3Instance s = start(&log, 50.0);
    double x[IMU_INPUT_COUNT], out[IMU_OUTPUT_COUNT];
    sample(0, x);
    CHECK(step(s, x, 0.0, STEP_SIZE, out) == fmi3OK);
    x[ImuInMagX] = x[ImuInMagY] = x[ImuInMagZ] = 0.0;
    CHECK(step(s, x, 0.01, 1e300, out) == fmi3Warning && allFinite(out)); /* the next sample comes 1e300 s later */
    sample(2, x);
    CHECK(step(s, x, 1e300, STEP_SIZE, out) == fmi3Warning && allFinite(out)); /* gap of 1e300 s */
    CHECK(step(s, x, 1e300, 1e12, out) == fmi3OK && allFinite(out));
    CHECK(step(s, x, 1e300, STEP_SIZE, out) == fmi3Warning && allFinite(out)); /* gap of 1e12 s */
    CHECK(log.badInput == 3);
    fmi3FreeInstance(s);
}

/** Invalid parameters: Error at initialisation naming the parameter. */
static void testInvalidParameters(void) {
    static const struct { fmi3ValueReference vr; double value; const char *name; } cases[] = {
        {vr_field_norm, 0.0, "field_norm"}, {vr_field_norm, NAN, "field_norm"},
        {vr_gyro_noise, -1.0, "gyro_noise"}, {vr_angle_noise, -0.1, "angle_noise"},
        {vr_mse_time_constant, 0.0, "mse_time_constant"}, {vr_declination, INFINITY, "declination"},
        {vr_lag_gyr, 1.5, "lag_gyr"}, {vr_lag_mag, NAN, "lag_mag"},
    };
    size_t c;
    for (c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        LogCount log = {0, 0, 0, ""};
        fmi3Instance s = fmi3InstantiateCoSimulation("bad", ModelGuid(), "", fmi3False, fmi3False, fmi3False, fmi3False,
                                                     NULL, 0, &log, countLog, NULL);
        CHECK(fmi3SetFloat64(s, &cases[c].vr, 1, &cases[c].value, 1) == fmi3OK);
        CHECK(fmi3EnterInitializationMode(s, fmi3False, 0.0, 0.0, fmi3False, 0.0) == fmi3OK);
        CHECK(fmi3ExitInitializationMode(s) == fmi3Error);
        CHECK(strstr(log.last, cases[c].name) != NULL);
        fmi3FreeInstance(s);
    }
}

/** Interfaces not provided and misuse: fmi3Error with a message, never a crash. */
static void testNotProvidedAndMisuse(void) {
    LogCount log = {0, 0, 0, ""};
    fmi3Instance s = start(&log, 50.0);
    const fmi3ValueReference vr = vr_rate_x, unknown = 9999;
    fmi3Int64 i64 = 0;
    double v = 1.0;
    size_t n = 0;
    CHECK(fmi3EnterEventMode(s) == fmi3Error);
    CHECK(fmi3GetNumberOfContinuousStates(s, &n) == fmi3Error);
    CHECK(fmi3GetInt64(s, &vr, 1, &i64, 1) == fmi3Error);
    CHECK(fmi3SetFloat64(s, &vr, 1, &v, 1) == fmi3Error);      /* outputs cannot be set */
    CHECK(fmi3GetFloat64(s, &unknown, 1, &v, 1) == fmi3Error); /* unknown value reference */
    CHECK(fmi3GetFloat64(s, &vr, 1, &v, 2) == fmi3Error);      /* nValues mismatch */
    CHECK(fmi3EnterInitializationMode(s, fmi3False, 0.0, 0.0, fmi3False, 0.0) == fmi3Error); /* wrong state */
    CHECK(log.errors == 7);
    CHECK(fmi3InstantiateCoSimulation("x", "{wrong}", "", fmi3False, fmi3False, fmi3False, fmi3False, NULL, 0, &log,
                                      countLog, NULL) == NULL);
    CHECK(fmi3InstantiateModelExchange("x", ModelGuid(), "", fmi3False, fmi3False, &log, countLog) == NULL);
    CHECK(fmi3Terminate(s) == fmi3OK);
    fmi3FreeInstance(s);
    fmi3FreeInstance(NULL);
    CHECK(fmi3DoStep(NULL, 0.0, 1.0, fmi3True, NULL, NULL, NULL, NULL) == fmi3Error);
}

int main(void) {
    testInstancesAreIndependent();
    testStateRestoreIsExact();
    testBadInputIsHeld();
    testZeroFieldAndHugeGap();
    testInvalidParameters();
    testNotProvidedAndMisuse();
    printf("%d passed, %d failed\n", passed, failed);
    return failed == 0 ? 0 : 1;
}
