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

void ImuGuardInitialOutputs(double declination, double out[IMU_OUTPUT_COUNT])
{
    int i;
    for (i = 0; i < IMU_OUTPUT_COUNT; i++) {
        out[i] = 0.0;
    }
    out[ImuOutQw] = 1.0;
    out[ImuOutHeading] = declination;
}

void ImuGuardReset(ImuGuard *g, double declination)
{
    memset(g, 0, sizeof *g);
    g->lastValidTemp = NAN;
    ImuGuardInitialOutputs(declination, g->held);
}

/** @brief Time [s] of the sample at t [s] for the pipeline: jumps beyond IMU_GUARD_MAX_GAP are cut
 *         to it; sets the ImuGuardIssueOrder / ImuGuardIssueGap bits in *issues. */
static double ImuGuardTime(ImuGuard *g, double t, int *issues)
{
    if (g->hasSample && !(t > g->lastSampleTime)) {
        *issues |= ImuGuardIssueOrder;
        return t - g->timeShift;
    }
    if (g->hasSample && t - g->lastSampleTime > IMU_GUARD_MAX_GAP) {
        *issues |= ImuGuardIssueGap;
        g->timeShift += (t - g->lastSampleTime) - IMU_GUARD_MAX_GAP;
    }
    g->lastSampleTime = t;
    g->hasSample = 1;
    return t - g->timeShift;
}

int ImuGuardInputs(ImuGuard *g, double fieldNorm, double t, const double raw[IMU_INPUT_COUNT],
                   double in[IMU_INPUT_COUNT], double *tPipeline)
{
    const double *mag = &raw[ImuInMagX];
    int issues = 0, i;
    memcpy(in, raw, IMU_INPUT_COUNT * sizeof raw[0]);
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
    for (i = 0; i < 3; i++) {
        if (issues & (1 << i)) {
            in[ImuInGyrX + 3 * i] = in[ImuInGyrX + 3 * i + 1] = in[ImuInGyrX + 3 * i + 2] = NAN;
        }
    }
    if (issues & ImuGuardIssueMagZero) {
        in[ImuInMagX] = in[ImuInMagY] = in[ImuInMagZ] = NAN;
    }
    if (raw[ImuInTemp] >= IMU_GUARD_TEMP_MIN && raw[ImuInTemp] <= IMU_GUARD_TEMP_MAX) {
        g->lastValidTemp = raw[ImuInTemp];
    } else {
        issues |= ImuGuardIssueTemp;
        in[ImuInTemp] = g->lastValidTemp;
    }
    *tPipeline = ImuGuardTime(g, t, &issues);
    return issues;
}

int ImuGuardOutputs(ImuGuard *g, double out[IMU_OUTPUT_COUNT])
{
    int j, bad = 0;
    for (j = 0; j < IMU_OUTPUT_COUNT; j++) {
        if (isfinite(out[j])) {
            g->held[j] = out[j];
        } else {
            out[j] = g->held[j];
            bad = 1;
        }
    }
    return bad;
}
