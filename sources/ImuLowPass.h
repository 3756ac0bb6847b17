/**
 * @file ImuLowPass.h
 * @brief Second-order Butterworth low-pass of a vector, for a time constant and a step that may
 *        change from sample to sample.
 *
 * Cut-off fc = sqrt(2) / (2 pi tau): the step response's non-oscillating part decays with tau, so
 * tau is comparable with a first-order filter's time constant (VQF's parametrisation: Laidig & Seel,
 * Information Fusion 91, 2023). Coefficients by the bilinear transform with
 * pre-warping; direct form II transposed. For its first tau seconds the output is the mean of the
 * samples so far; then the filter starts in the steady state of that mean (VQF's start: one sample,
 * which may carry a linear acceleration, does not set the start; no start-up transient pulls the
 * output). Simulated hand-held motion, the attitude's restart after an hour-long gap: roll RMSE from
 * 5 s after it 0.98 deg when the filter started from the restart's first sample, 0.85 deg with the
 * averaging start, as in the run without the gap (docs/fmu.md, "Time steps").
 */
#ifndef IMU_LOW_PASS_H
#define IMU_LOW_PASS_H

#include "ImuCommon.h"

/** Filter state of a 3-vector (plain struct: copy = save state). */
typedef struct {
    double state[2][3]; /* direct form II transposed delays, in the input's unit */
    double output[3];   /* the last output, in the input's unit */
    double sum[3];      /* the sum of the samples of the averaging start, in the input's unit */
    double meanTime;    /* s, the steps summed in the averaging start */
    int count;          /* samples averaged in the start (0: none yet) */
    int initialised;    /* the filter runs (after the averaging start) */
} ImuLowPass;

/** Coefficients of one step (direct form II transposed, b = b0 [1 2 1], a = [1 a1 a2]). */
typedef struct {
    double b0, a1, a2;
    double tau;         /* s, the time constant: also the length of the averaging start */
    double dt;          /* s, the step */
    int step;           /* the step dt > 0: 0 leaves the filter as it is */
} ImuLowPassDesign;

/** @brief The coefficients for time constant tau [s] (> 0) and step dt [s]: one design serves every
 *         filter that steps with the same tau and dt (each design costs a tan()). */
IMU_HIDDEN void ImuLowPassDesignStep(double tau, double dt, ImuLowPassDesign *d);
/**
 * @brief Filter one sample x with the coefficients d of time constant tau [s] and step dt [s]; y is
 *        the output. A step dt <= 0 changes nothing: y is the last output (x before the first step).
 *        Until the steps dt > 0 sum to tau, y is the mean of their samples; the step that reaches
 *        tau starts the filter in the steady state of that mean.
 */
IMU_HIDDEN void ImuLowPassApply(ImuLowPass *f, const ImuLowPassDesign *d, const double x[3], double y[3]);
/** @brief Forget the past: the next sample starts the averaging anew. */
IMU_HIDDEN void ImuLowPassReset(ImuLowPass *f);
/** @brief 1 if f is a state the filter can reach (a restored FMU state): count >= 0, initialised 0 or
 *         1, meanTime finite and >= 0; else 0 (a negative count would divide by zero). */
IMU_HIDDEN int ImuLowPassStateValid(const ImuLowPass *f);

#endif
