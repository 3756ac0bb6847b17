/**
 * @file pf_cost_host.c
 * @brief Per-sample cost of an FMI 3 ImuFusion binary, co-simulated from C (benchmarks/pf_cost.py).
 *
 * Usage: pf_cost_host BINARY.so TOKEN SAMPLES.bin REPEATS INPUT_VRS OUTPUT_VRS [KIND:VR=VALUE ...]
 *   SAMPLES.bin  rows of float64: t [s], h [s], then one value per input value reference
 *   INPUT_VRS    comma-separated input value references (the row's order); OUTPUT_VRS likewise
 *   KIND:VR=VALUE  a parameter set before initialisation: KIND r (Float64), i (Int32), b (Boolean)
 * Each repeat instantiates, sets the parameters, initialises (start time: the first row's t) and then, per sample, sets the
 * inputs, calls doStep and gets the outputs; only that loop is timed (clock_gettime, monotonic).
 * Prints "samples N", "best_us_per_sample X" (over the repeats) and "checksum Y" (sum of the
 * last outputs, so a failed run shows). Exit status 0 on success, 1 on a failed call, 2 on bad
 * arguments or files.
 */
#define _POSIX_C_SOURCE 199309L
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "fmi3FunctionTypes.h"

#define MAX_VRS 64
#define MAX_PARAMETERS 64

/** The FMI 3 functions the host calls, looked up by name. */
typedef struct {
    fmi3InstantiateCoSimulationTYPE *instantiate;
    fmi3EnterInitializationModeTYPE *enterInit;
    fmi3ExitInitializationModeTYPE *exitInit;
    fmi3SetFloat64TYPE *setFloat64;
    fmi3SetInt32TYPE *setInt32;
    fmi3SetBooleanTYPE *setBoolean;
    fmi3GetFloat64TYPE *getFloat64;
    fmi3DoStepTYPE *doStep;
    fmi3TerminateTYPE *terminate;
    fmi3FreeInstanceTYPE *freeInstance;
} Api;

/** One parameter: kind 'r', 'i' or 'b', value reference, value. */
typedef struct {
    char kind;
    fmi3ValueReference vr;
    double value;
} Parameter;

/** @brief Look up symbol name in library, or exit 2. */
static void *symbol(void *library, const char *name)
{
    void *f = dlsym(library, name);
    if (f == NULL) {
        fprintf(stderr, "pf_cost_host: missing symbol %s\n", name);
        exit(2);
    }
    return f;
}

/** @brief Parse "a,b,c" into vrs; returns the count, or exits 2. */
static size_t parseList(const char *text, fmi3ValueReference vrs[MAX_VRS])
{
    size_t n = 0;
    const char *p = text;
    while (*p != '\0') {
        char *end;
        const unsigned long v = strtoul(p, &end, 10);
        if (end == p || n == MAX_VRS) {
            fprintf(stderr, "pf_cost_host: bad value reference list '%s'\n", text);
            exit(2);
        }
        vrs[n++] = (fmi3ValueReference)v;
        p = *end == ',' ? end + 1 : end;
    }
    return n;
}

/** @brief Parse "k:vr=value" into a parameter, or exit 2. */
static Parameter parseParameter(const char *text)
{
    Parameter q;
    unsigned long vr;
    if (sscanf(text, "%c:%lu=%lf", &q.kind, &vr, &q.value) != 3 || strchr("rib", q.kind) == NULL) {
        fprintf(stderr, "pf_cost_host: bad parameter '%s' (expected r|i|b:VR=VALUE)\n", text);
        exit(2);
    }
    q.vr = (fmi3ValueReference)vr;
    return q;
}

/** @brief Read the whole file of float64 rows; returns the values and sets *count, or exits 2. */
static double *readSamples(const char *path, size_t *count)
{
    FILE *f = fopen(path, "rb");
    long bytes;
    double *data;
    if (f == NULL || fseek(f, 0, SEEK_END) != 0 || (bytes = ftell(f)) < 0 || fseek(f, 0, SEEK_SET) != 0) {
        fprintf(stderr, "pf_cost_host: cannot read %s\n", path);
        exit(2);
    }
    data = malloc((size_t)bytes + sizeof(double));
    *count = (size_t)bytes / sizeof(double);
    if (data == NULL || fread(data, sizeof(double), *count, f) != *count) {
        fprintf(stderr, "pf_cost_host: cannot read %s\n", path);
        exit(2);
    }
    fclose(f);
    return data;
}

/** @brief Set one parameter; the FMI status. */
static fmi3Status setParameter(const Api *api, fmi3Instance s, const Parameter *q)
{
    if (q->kind == 'r') {
        return api->setFloat64(s, &q->vr, 1, &q->value, 1);
    }
    if (q->kind == 'i') {
        const fmi3Int32 v = (fmi3Int32)q->value;
        return api->setInt32(s, &q->vr, 1, &v, 1);
    }
    {
        const fmi3Boolean v = q->value != 0.0;
        return api->setBoolean(s, &q->vr, 1, &v, 1);
    }
}

/** @brief One timed co-simulation of rows [t, h, inputs...]; returns seconds, or -1 on a failed call. */
static double simulate(const Api *api, const char *token, const double *rows, size_t samples, size_t width,
                       const fmi3ValueReference *in, size_t nIn, const fmi3ValueReference *out, size_t nOut,
                       const Parameter *parameters, size_t nParameters, double *checksum)
{
    double y[MAX_VRS];
    fmi3Boolean event, terminate, early;
    fmi3Float64 last;
    struct timespec start, stop;
    size_t k, j;
    int failures = 0;
    fmi3Instance s = api->instantiate("pf_cost", token, "", fmi3False, fmi3False, fmi3False, fmi3False, NULL, 0,
                                      NULL, NULL, NULL);
    if (s == NULL) {
        return -1.0;
    }
    for (j = 0; j < nParameters; j++) {
        failures += setParameter(api, s, &parameters[j]) != fmi3OK;
    }
    failures += api->enterInit(s, fmi3False, 0.0, rows[0], fmi3False, 0.0) > fmi3Warning;
    failures += api->exitInit(s) != fmi3OK;
    clock_gettime(CLOCK_MONOTONIC, &start);
    for (k = 0; k < samples && failures == 0; k++) {
        const double *row = rows + k * width;
        failures += api->setFloat64(s, in, nIn, row + 2, nIn) > fmi3Warning;
        failures += api->doStep(s, row[0], row[1], fmi3True, &event, &terminate, &early, &last) > fmi3Warning;
        failures += api->getFloat64(s, out, nOut, y, nOut) > fmi3Warning;
    }
    clock_gettime(CLOCK_MONOTONIC, &stop);
    *checksum = 0.0;
    for (j = 0; j < nOut; j++) {
        *checksum += y[j];
    }
    api->terminate(s);
    api->freeInstance(s);
    if (failures != 0) {
        return -1.0;
    }
    return (double)(stop.tv_sec - start.tv_sec) + 1e-9 * (double)(stop.tv_nsec - start.tv_nsec);
}

int main(int argc, char **argv)
{
    fmi3ValueReference in[MAX_VRS], out[MAX_VRS];
    Parameter parameters[MAX_PARAMETERS];
    size_t nIn, nOut, nParameters = 0, count, samples, width;
    double *rows, best = -1.0, checksum = 0.0;
    int repeats, r, i;
    void *library;
    Api api;
    if (argc < 7 || argc - 7 > MAX_PARAMETERS) {
        fprintf(stderr, "usage: pf_cost_host BINARY.so TOKEN SAMPLES.bin REPEATS INPUT_VRS OUTPUT_VRS [r|i|b:VR=VALUE ...]\n");
        return 2;
    }
    library = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (library == NULL) {
        fprintf(stderr, "pf_cost_host: %s\n", dlerror());
        return 2;
    }
    *(void **)&api.instantiate = symbol(library, "fmi3InstantiateCoSimulation");
    *(void **)&api.enterInit = symbol(library, "fmi3EnterInitializationMode");
    *(void **)&api.exitInit = symbol(library, "fmi3ExitInitializationMode");
    *(void **)&api.setFloat64 = symbol(library, "fmi3SetFloat64");
    *(void **)&api.setInt32 = symbol(library, "fmi3SetInt32");
    *(void **)&api.setBoolean = symbol(library, "fmi3SetBoolean");
    *(void **)&api.getFloat64 = symbol(library, "fmi3GetFloat64");
    *(void **)&api.doStep = symbol(library, "fmi3DoStep");
    *(void **)&api.terminate = symbol(library, "fmi3Terminate");
    *(void **)&api.freeInstance = symbol(library, "fmi3FreeInstance");
    repeats = atoi(argv[4]);
    nIn = parseList(argv[5], in);
    nOut = parseList(argv[6], out);
    for (i = 7; i < argc; i++) {
        parameters[nParameters++] = parseParameter(argv[i]);
    }
    rows = readSamples(argv[3], &count);
    width = 2 + nIn;
    samples = count / width;
    if (repeats < 1 || samples == 0 || count % width != 0) {
        fprintf(stderr, "pf_cost_host: need REPEATS >= 1 and whole rows of %lu values in %s\n", (unsigned long)width, argv[3]);
        return 2;
    }
    for (r = 0; r < repeats; r++) {
        const double seconds = simulate(&api, argv[2], rows, samples, width, in, nIn, out, nOut, parameters,
                                        nParameters, &checksum);
        if (seconds < 0.0) {
            fprintf(stderr, "pf_cost_host: an FMI call failed\n");
            return 1;
        }
        best = (best < 0.0 || seconds < best) ? seconds : best;
    }
    printf("samples %lu\nbest_us_per_sample %.6f\nchecksum %.17g\n", (unsigned long)samples, 1e6 * best / (double)samples,
           checksum);
    free(rows);
    dlclose(library);
    return 0;
}
