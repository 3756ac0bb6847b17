/**
 * @file ImuLowPass.h
 * @brief Second-order Butterworth low-pass of a vector, for a time constant and a step that may
 *        change from sample to sample.
 *
 * Cut-off fc = sqrt(2) / (2 pi tau): the step response's non-oscillating part decays with tau, so
 * tau is comparable with a first-order filter's time constant (VQF's parametrisation: Laidig & Seel,
 * Information Fusion 91, 2023). Coefficients by the bilinear transform with
 * pre-warping; direct form II transposed. The filter starts in its steady state, so a start-up
 * transient never pulls the output.
 */
#ifndef IMU_LOW_PASS_H
#define IMU_LOW_PASS_H

#include "ImuCommon.h"

/** Filter state of a 3-vector (plain struct: copy = save state). */
typedef struct {
    double state[2][3]; /* direct form II transposed delays, in the input's unit */
    double output[3];   /* the last output, in the input's unit */
    int initialised;    /* the filter has taken a step */
} ImuLowPass;

/** Coefficients of one step (direct form II transposed, b = b0 [1 2 1], a = [1 a1 a2]). */
typedef struct {
    double b0, a1, a2;
    int step;           /* the step dt > 0: 0 leaves the filter as it is */
} ImuLowPassDesign;

/** @brief The coefficients for time constant tau [s] (> 0) and step dt [s]: one design serves every
 *         filter that steps with the same tau and dt (each design costs a tan()). */
IMU_HIDDEN void ImuLowPassDesignStep(double tau, double dt, ImuLowPassDesign *d);
/**
 * @brief Filter one sample x with the coefficients d of time constant tau [s] and step dt [s]; y is
 *        the output. A step dt <= 0 changes nothing: y is the last output (x before the first step).
 *        The first step dt > 0 starts from the steady state of its x.
 */
IMU_HIDDEN void ImuLowPassApply(ImuLowPass *f, const ImuLowPassDesign *d, const double x[3], double y[3]);
/** @brief Forget the past: the next sample starts the filter in its steady state. */
IMU_HIDDEN void ImuLowPassReset(ImuLowPass *f);

#endif
