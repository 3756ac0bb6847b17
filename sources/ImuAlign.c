/**
 * @file ImuAlign.c
 * @brief Time alignment of the compensated triads (see ImuAlign.h).
 */
#include <math.h>
#include <stddef.h>
#include "ImuAlign.h"
#include "ImuMath.h"

enum { ImuAlignGyr = 0, ImuAlignMag = 2 }; /* triad indices: the gyro rotates the magnetometer */

/** @brief Buffer index of the sample `age` samples before the newest (0 = newest). */
static int ImuAlignIndex(const ImuAlignState *s, int age)
{
    return (s->head - age + IMU_ALIGN_CAPACITY) % IMU_ALIGN_CAPACITY;
}

int ImuAlignStateValid(const ImuAlignState *s, double clock)
{
    int age;
    if (!(s->count >= 0 && s->count <= IMU_ALIGN_CAPACITY && s->head >= 0 && s->head < IMU_ALIGN_CAPACITY)) {
        return 0;
    }
    for (age = 0; age < s->count; age++) {
        const double t = s->time[ImuAlignIndex(s, age)];
        const double later = age == 0 ? clock : s->time[ImuAlignIndex(s, age - 1)];
        if (!(isfinite(t) && (age == 0 ? t == later : t < later))) {
            return 0;
        }
    }
    return 1;
}

void ImuAlignReset(ImuAlignState *s)
{
    int j, i;
    for (j = 0; j < IMU_ALIGN_CAPACITY; j++) {
        s->time[j] = 0.0;
        for (i = 0; i < 9; i++) {
            s->x[j][i] = 0.0;
        }
    }
    s->count = 0;
    s->head = IMU_ALIGN_CAPACITY - 1;
}

/** @brief Buffer the sample (t [s], x[9]); 0 without buffering it when t is not finite or does not increase. */
static int ImuAlignPush(ImuAlignState *s, double t, const double x[9])
{
    int i;
    if (!isfinite(t) || (s->count > 0 && !(t > s->time[s->head]))) {
        return 0;
    }
    s->head = (s->head + 1) % IMU_ALIGN_CAPACITY;
    s->time[s->head] = t;
    for (i = 0; i < 9; i++) {
        s->x[s->head][i] = x[i];
    }
    if (s->count < IMU_ALIGN_CAPACITY) {
        s->count++;
    }
    return 1;
}

/** @brief out = a + w (b - a) per axis (any unit); exactly a for w = 0. */
static void ImuAlignLerp(const double a[3], const double b[3], double w, double out[3])
{
    int i;
    for (i = 0; i < 3; i++) {
        out[i] = w == 0.0 ? a[i] : a[i] + w * (b[i] - a[i]);
    }
}

/** @brief Triad `triad` at time tau [s], interpolated between the buffered samples around it;
 *         the oldest buffered sample when the buffer does not reach back to tau. */
static void ImuAlignAt(const ImuAlignState *s, double tau, int triad, double out[3])
{
    int age, newer = s->head;
    for (age = 1; age < s->count; age++) {
        const int older = ImuAlignIndex(s, age);
        if (s->time[older] <= tau) {
            const double w = (tau - s->time[older]) / (s->time[newer] - s->time[older]);
            ImuAlignLerp(&s->x[older][3 * triad], &s->x[newer][3 * triad], w, out);
            return;
        }
        newer = older;
    }
    out[0] = s->x[newer][3 * triad];
    out[1] = s->x[newer][3 * triad + 1];
    out[2] = s->x[newer][3 * triad + 2];
}

/** @brief theta [rad] = integral of the buffered gyro over [tau, newest time] (trapezoid, partial
 *         first interval interpolated, intervals with a non-finite end skipped, buffered span only). */
static void ImuAlignRotation(const ImuAlignState *s, double tau, double theta[3])
{
    int age, i, newer = s->head;
    theta[0] = theta[1] = theta[2] = 0.0;
    for (age = 1; age < s->count && s->time[newer] > tau; age++) {
        const int older = ImuAlignIndex(s, age);
        const double *w0 = &s->x[older][3 * ImuAlignGyr], *w1 = &s->x[newer][3 * ImuAlignGyr];
        double partial[3], start = s->time[older];
        if (start < tau) {
            ImuAlignLerp(w0, w1, (tau - start) / (s->time[newer] - start), partial);
            w0 = partial;
            start = tau;
        }
        if (ImuAllFinite(w0, 3) && ImuAllFinite(w1, 3)) {
            for (i = 0; i < 3; i++) {
                theta[i] += 0.5 * (w0[i] + w1[i]) * (s->time[newer] - start);
            }
        }
        newer = older;
    }
}

/** @brief Advance the world-fixed vector v (body axes, any unit) over the last `lag` [s]: v <- exp(-[theta x]) v. */
static void ImuAlignAdvance(const ImuAlignState *s, double lag, double v[3])
{
    double theta[3], r[9], rotated[3];
    ImuAlignRotation(s, s->time[s->head] - lag, theta);
    ImuMatrixExp(theta, -1.0, r);
    ImuMatrixVector(r, v, rotated);
    v[0] = rotated[0];
    v[1] = rotated[1];
    v[2] = rotated[2];
}

/** @brief Extrapolate the triad v (its unit) by lag [s] along its chord: v <- 2 v(t) - v(t - lag). */
static void ImuAlignExtrapolate(const ImuAlignState *s, double lag, int triad, double v[3])
{
    double past[3];
    int i;
    ImuAlignAt(s, s->time[s->head] - lag, triad, past);
    for (i = 0; i < 3; i++) {
        v[i] = 2.0 * v[i] - past[i];
    }
}

int ImuAlignUpdate(ImuAlignState *s, const ImuAlignSettings *settings, double t, double x[9])
{
    int i, beyond = 0;
    if (!ImuAlignPush(s, t, x)) {
        return 0;
    }
    for (i = 0; i < 3; i++) {
        const double lag = settings->lag[i];
        double *triad = &x[3 * i];
        beyond = beyond || (s->count == IMU_ALIGN_CAPACITY && t - fabs(lag) < s->time[ImuAlignIndex(s, s->count - 1)]);
        if (lag < 0.0) {
            ImuAlignAt(s, t + lag, i, triad);
        } else if (lag > 0.0 && i == ImuAlignMag) {
            ImuAlignAdvance(s, lag, triad);
        } else if (lag > 0.0) {
            ImuAlignExtrapolate(s, lag, i, triad);
        }
    }
    return beyond;
}
