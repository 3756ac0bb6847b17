/**
 * @file ImuGuard.c
 * @brief Input, time and output guard around ImuPipelineUpdate (see ImuGuard.h).
 */
#include "ImuGuard.h"

#include <math.h>
#include <string.h>

/* ImuGuardInputs relies on the triad issue bits being 1 << triad (gyr, acc, mag). */
typedef char ImuGuardCheckTriadBits[(ImuGuardIssueGyr == 1 && ImuGuardIssueAcc == 2 && ImuGuardIssueMag == 4) ? 1 : -1];

/** @brief 1 if every one of the n values is finite and |value| < limit (same unit as x). */
static int ImuGuardWithinLimit(const double *x, int n, double limit)
{
    int i;
    for (i = 0; i < n; i++) {
        if (!(fabs(x[i]) < limit)) { /* also false for NaN */
            return 0;
        }
    }
    return 1;
}

/** @brief 1 if every one of the n values is NaN (a sensor that was not recorded). */
static int ImuGuardAllNan(const double *x, int n)
{
    int i;
    for (i = 0; i < n; i++) {
        if (!isnan(x[i])) {
            return 0;
        }
    }
    return 1;
}

void ImuGuardInitialOutputs(double declination, const ImuMount *mount, double out[IMU_OUTPUT_COUNT])
{
    int i;
    for (i = 0; i < IMU_OUTPUT_COUNT; i++) {
        out[i] = 0.0;
    }
    out[ImuOutQW] = 1.0;
    ImuMountQuaternion(mount, &out[ImuOutQSensorW]);
    out[ImuOutHeading] = declination;
}

void ImuGuardReset(ImuGuard *g, double declination, const ImuMount *mount)
{
    int i;
    memset(g, 0, sizeof *g);
    g->lastValidTemp = NAN;
    for (i = 0; i < IMU_TERMS_AUX_COUNT; i++) {
        g->lastValidAux[i] = NAN;
    }
    ImuGuardInitialOutputs(declination, mount, g->held);
}

int ImuGuardAbsent(const ImuGuard *g)
{
    return IMU_GUARD_SENSORS & ~g->present;
}

/** @brief The ImuGuardIssue bits of the raw triads and temperature (fieldNorm [uT] scales the
 *         magnetometer limits). */
static int ImuGuardSensorIssues(double fieldNorm, const double raw[IMU_INPUT_COUNT])
{
    const double *mag = &raw[ImuInMagX];
    int issues = 0;
    if (!ImuGuardWithinLimit(&raw[ImuInGyrX], 3, IMU_GUARD_GYR_LIMIT)) {
        issues |= ImuGuardIssueGyr;
    }
    if (!ImuGuardWithinLimit(&raw[ImuInAccX], 3, IMU_GUARD_ACC_LIMIT)) {
        issues |= ImuGuardIssueAcc;
    }
    if (!ImuGuardWithinLimit(mag, 3, IMU_GUARD_MAG_SATURATION * fieldNorm)) {
        issues |= ImuGuardIssueMag;
    } else if (!(sqrt(mag[0] * mag[0] + mag[1] * mag[1] + mag[2] * mag[2]) >= IMU_GUARD_MAG_MINIMUM * fieldNorm)) {
        issues |= ImuGuardIssueMagZero;
    }
    if (!(raw[ImuInTemp] >= IMU_GUARD_TEMP_MIN && raw[ImuInTemp] <= IMU_GUARD_TEMP_MAX)) {
        issues |= ImuGuardIssueTemp;
    }
    return issues;
}

/** @brief Mark the sensors with a valid sample present; clear the issue bits of the sensors that
 *         have never delivered one and read all-NaN (absent, not bad). Returns the issues left. */
static int ImuGuardPresence(ImuGuard *g, const double raw[IMU_INPUT_COUNT], int issues)
{
    static const int first[] = {ImuInGyrX, ImuInAccX, ImuInMagX, ImuInTemp};
    static const int count[] = {3, 3, 3, 1};
    static const int bit[] = {ImuGuardIssueGyr, ImuGuardIssueAcc, ImuGuardIssueMag, ImuGuardIssueTemp};
    int s;
    for (s = 0; s < 4; s++) {
        const int bad = bit[s] == ImuGuardIssueMag ? (ImuGuardIssueMag | ImuGuardIssueMagZero) : bit[s];
        if (!(issues & bad)) {
            g->present |= bit[s];
        } else if (!(g->present & bit[s]) && ImuGuardAllNan(&raw[first[s]], count[s])) {
            issues &= ~bad;
        }
    }
    return issues;
}

/** @brief Sanitise raw into in: bad or absent triads NaN, a bad temperature the last valid one
 *         (NaN while the sensor is absent); returns the issue bits (fieldNorm [uT]). */
static int ImuGuardInputs(ImuGuard *g, double fieldNorm, const double raw[IMU_INPUT_COUNT], double in[IMU_INPUT_COUNT])
{
    const int found = ImuGuardSensorIssues(fieldNorm, raw);
    int i;
    memcpy(in, raw, IMU_INPUT_COUNT * sizeof raw[0]);
    for (i = 0; i < 3; i++) {
        if (found & (1 << i)) {
            in[ImuInGyrX + 3 * i] = in[ImuInGyrX + 3 * i + 1] = in[ImuInGyrX + 3 * i + 2] = NAN;
        }
    }
    if (found & ImuGuardIssueMagZero) {
        in[ImuInMagX] = in[ImuInMagY] = in[ImuInMagZ] = NAN;
    }
    if (found & ImuGuardIssueTemp) {
        in[ImuInTemp] = g->lastValidTemp;
    } else {
        g->lastValidTemp = raw[ImuInTemp];
    }
    return ImuGuardPresence(g, raw, found);
}

/** @brief Hold each auxiliary input that a correction term of `terms` uses at its last finite value
 *         while it is not finite (NaN before a first one: its terms are skipped); returns
 *         ImuGuardIssueAux if one was not finite, else 0. An unused auxiliary input is never an issue. */
static int ImuGuardAux(ImuGuard *g, const ImuTermsCoefficients *terms, double in[IMU_INPUT_COUNT])
{
    int i, issues = 0;
    for (i = 0; i < IMU_TERMS_AUX_COUNT; i++) {
        double *x = &in[ImuInAux1 + i];
        if (!ImuTermsUseSignal(terms, ImuSigAux1 + i)) {
            continue;
        }
        if (isfinite(*x)) {
            g->lastValidAux[i] = *x;
        } else {
            *x = g->lastValidAux[i];
            issues = ImuGuardIssueAux;
        }
    }
    return issues;
}

double ImuGuardNominalStep(const ImuGuard *g)
{
    double sorted[IMU_GUARD_STEP_HISTORY];
    int i, j;
    for (i = 0; i < g->stepCount; i++) { /* insertion sort: at most IMU_GUARD_STEP_HISTORY entries */
        const double x = g->steps[i];
        for (j = i; j > 0 && sorted[j - 1] > x; j--) {
            sorted[j] = sorted[j - 1];
        }
        sorted[j] = x;
    }
    return g->stepCount > 0 ? sorted[g->stepCount / 2] : 0.0;
}

int ImuGuardStepsValid(const ImuGuard *g)
{
    int i;
    if (g->stepCount < 0 || g->stepCount > IMU_GUARD_STEP_HISTORY || g->stepHead < 0 || g->stepHead >= IMU_GUARD_STEP_HISTORY
        || (g->stepCount < IMU_GUARD_STEP_HISTORY && g->stepHead != g->stepCount)) {
        return 0;
    }
    for (i = 0; i < g->stepCount; i++) {
        if (!(g->steps[i] > 0.0 && g->steps[i] <= IMU_GUARD_MAX_STEP)) {
            return 0;
        }
    }
    return 1;
}

int ImuGuardClockValid(const ImuGuard *g)
{
    const double nominal = ImuGuardNominalStep(g);
    return g->clock >= 0.0 && isfinite(g->clock)
           && (nominal == 0.0 || fabs((g->clock + nominal) - g->clock - nominal) <= 0.01 * nominal);
}

/** @brief Remember step [s] (finite, > 0; at most IMU_GUARD_MAX_STEP counts) in the step history. */
static void ImuGuardRememberStep(ImuGuard *g, double step)
{
    g->steps[g->stepHead] = fmin(step, IMU_GUARD_MAX_STEP);
    g->stepHead = (g->stepHead + 1) % IMU_GUARD_STEP_HISTORY;
    if (g->stepCount < IMU_GUARD_STEP_HISTORY) {
        g->stepCount++;
    }
}

/**
 * @brief Integration step [s] of the sample that follows the previous one after `step` [s]: 0 for
 *        the first sample, a step that is not finite and > 0 (ImuGuardIssueOrder) and a gap
 *        (ImuGuardIssueGap: longer than IMU_GUARD_GAP_STEPS nominal steps, or IMU_GUARD_MAX_STEP;
 *        nothing is integrated across it). Advances the clock by the steps that are finite and
 *        > 0, gaps included (at most IMU_GUARD_MAX_STEP each), remembers them for the nominal step
 *        and sets the issue bits in *issues; *nominal [s] is the nominal step before this sample.
 */
static double ImuGuardTime(ImuGuard *g, double step, int *issues, double *nominal)
{
    *nominal = ImuGuardNominalStep(g);
    if (!g->hasSample) {
        g->hasSample = 1;
        return 0.0;
    }
    if (!(step > 0.0 && isfinite(step))) {
        *issues |= ImuGuardIssueOrder;
        return 0.0;
    }
    g->clock += fmin(step, IMU_GUARD_MAX_STEP); /* the clock stays fine-grained after absurd gaps */
    ImuGuardRememberStep(g, step);
    if (step > IMU_GUARD_MAX_STEP || (*nominal > 0.0 && step > IMU_GUARD_GAP_STEPS * *nominal)) {
        *issues |= ImuGuardIssueGap;
        return 0.0;
    }
    return step;
}

/** @brief 1 if output j is a corrected output of a sensor in `absent` (IMU_GUARD_SENSORS bits). */
static int ImuGuardAbsentOutput(int absent, int j)
{
    return ((absent & ImuGuardIssueGyr) && j >= ImuOutRateX && j <= ImuOutRateZ)
           || ((absent & ImuGuardIssueAcc) && j >= ImuOutAccelX && j <= ImuOutAccelZ)
           || ((absent & ImuGuardIssueMag) && j >= ImuOutFieldX && j <= ImuOutFieldZ);
}

/** @brief Absent sensors' corrected outputs become NaN; other non-finite entries of out (ImuLayout.h
 *         units) the last finite ones; remembers out. Returns 1 if an entry was held, else 0. */
static int ImuGuardOutputs(ImuGuard *g, double out[IMU_OUTPUT_COUNT])
{
    const int absent = ImuGuardAbsent(g);
    int j, bad = 0;
    for (j = 0; j < IMU_OUTPUT_COUNT; j++) {
        if (ImuGuardAbsentOutput(absent, j)) {
            out[j] = NAN;
        } else if (isfinite(out[j])) {
            g->held[j] = out[j];
        } else {
            out[j] = g->held[j];
            bad = 1;
        }
    }
    return bad;
}

int ImuGuardStep(ImuGuard *g, ImuPipeline *p, double step, const double raw[IMU_INPUT_COUNT],
                 double out[IMU_OUTPUT_COUNT])
{
    double in[IMU_INPUT_COUNT];
    int issues = ImuGuardInputs(g, p->settings.fieldNorm, raw, in) | ImuGuardAux(g, &p->coefficients.terms, in);
    double nominal;
    const double dt = ImuGuardTime(g, step, &issues, &nominal);
    if (issues & ImuGuardIssueGap) {
        ImuPipelineGap(p, step);
    }
    ImuPipelineUpdate(p, g->clock, dt, nominal, in, out);
    if (ImuGuardOutputs(g, out) && issues == 0) {
        issues |= ImuGuardIssueOutput;
    }
    return issues;
}
