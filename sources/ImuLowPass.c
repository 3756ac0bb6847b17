/**
 * @file ImuLowPass.c
 * @brief Second-order Butterworth low-pass of a vector (ImuLowPass.h).
 */
#include <math.h>
#include "ImuLowPass.h"
#include "ImuMath.h"

#define IMU_LOW_PASS_SQRT2 1.41421356237309504880

void ImuLowPassReset(ImuLowPass *f)
{
    int i;
    for (i = 0; i < 3; i++) {
        f->state[0][i] = 0.0;
        f->state[1][i] = 0.0;
        f->output[i] = 0.0;
        f->sum[i] = 0.0;
    }
    f->meanTime = 0.0;
    f->count = 0;
    f->initialised = 0;
}

int ImuLowPassStateValid(const ImuLowPass *f)
{
    return f->count >= 0 && (f->initialised == 0 || f->initialised == 1) && isfinite(f->meanTime) && f->meanTime >= 0.0;
}

void ImuLowPassDesignStep(double tau, double dt, ImuLowPassDesign *d)
{
    /* Pre-warped analogue cut-off: c = tan(pi fc dt); b = c^2 [1 2 1] / d, a = [1, 2 (c^2 - 1), 1 - sqrt2 c + c^2] / d. */
    const double c = tan(IMU_PI * (IMU_LOW_PASS_SQRT2 / (2.0 * IMU_PI * tau)) * dt);
    const double n = c * c + IMU_LOW_PASS_SQRT2 * c + 1.0;
    d->b0 = c * c / n;
    d->a1 = 2.0 * (c * c - 1.0) / n;
    d->a2 = (1.0 - IMU_LOW_PASS_SQRT2 * c + c * c) / n;
    d->tau = tau;
    d->dt = dt;
    d->step = dt > 0.0;
}

/** @brief The averaging start: y is the mean of the samples so far; once their steps reach tau the
 *         filter starts in the steady state of that mean. */
static void ImuLowPassAverage(ImuLowPass *f, const ImuLowPassDesign *d, const double x[3], double y[3])
{
    int i;
    f->count++;
    f->meanTime += d->dt;
    for (i = 0; i < 3; i++) {
        f->sum[i] += x[i];
        y[i] = f->sum[i] / f->count;
        f->output[i] = y[i];
    }
    if (f->meanTime >= d->tau) {
        for (i = 0; i < 3; i++) {
            /* Steady state of a constant input y (DC gain 4 b0 = 1 + a1 + a2): the output is y. */
            f->state[0][i] = y[i] * (1.0 - d->b0);
            f->state[1][i] = y[i] * (d->b0 - d->a2);
        }
        f->initialised = 1;
    }
}

void ImuLowPassApply(ImuLowPass *f, const ImuLowPassDesign *d, const double x[3], double y[3])
{
    const double b0 = d->b0, a1 = d->a1, a2 = d->a2;
    int i;
    if (!d->step) {
        for (i = 0; i < 3; i++) {
            y[i] = f->count > 0 ? f->output[i] : x[i];
        }
        return;
    }
    if (!f->initialised) {
        ImuLowPassAverage(f, d, x, y);
        return;
    }
    for (i = 0; i < 3; i++) {
        y[i] = b0 * x[i] + f->state[0][i];
        f->state[0][i] = 2.0 * b0 * x[i] - a1 * y[i] + f->state[1][i];
        f->state[1][i] = b0 * x[i] - a2 * y[i];
        f->output[i] = y[i];
    }
}
