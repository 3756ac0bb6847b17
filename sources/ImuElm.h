/**
 * @file ImuElm.h
 * @brief Extreme learning machine (field form): distorted field -> true field [uT].
 *
 * y_n = sum_j beta_j g(w_j . x_n + b_j) with g = tanh or the logistic sigmoid, no output bias;
 * x_n = 2 (x - inMin) / (inMax - inMin) - 1 and y = outMin + (y_n + 1) (outMax - outMin) / 2.
 * Trained by training/models/elm.py (growing ELM with back-tuning, docs/elm.md).
 *
 * Calibrated range: [inMin, inMax] per axis is the box of fields the network was fitted on. A
 * field outside it is clamped into the box, the network's correction y(xc) - xc is evaluated there
 * and added to the field itself: inside the box this is y(x) unchanged; outside, the correction at
 * the box edge is applied instead of an extrapolated network, and ImuElmApply reports the excursion.
 *
 * Block layout (IMU_ELM_BLOCK doubles, training.models.elm.to_block):
 *   [0]  enabled (0: the field passes through unchanged, 1: apply)
 *   [1]  activation (ImuElmActivation: 0 tanh, 1 sigmoid)
 *   [2]  L, hidden nodes, integer 1..IMU_ELM_MAX_HIDDEN
 *   [3..5]   inMin [uT]      [6..8]   inMax [uT]
 *   [9..11]  outMin [uT]     [12..14] outMax [uT]
 *   [15 ..]                      w, IMU_ELM_MAX_HIDDEN rows of 3 (node j: w[3j..3j+2])
 *   [15 + 3 MAX ..]              b, IMU_ELM_MAX_HIDDEN
 *   [15 + 4 MAX .. 15 + 7 MAX)   beta, IMU_ELM_MAX_HIDDEN rows of 3 (node j: beta[3j..3j+2])
 * Entries of nodes j >= L are zero. Every entry must be finite; min < max when enabled.
 */
#ifndef IMU_ELM_H
#define IMU_ELM_H

#include "ImuCommon.h"

/** Compile-time maximum of hidden nodes. */
#define IMU_ELM_MAX_HIDDEN 64
/** Header length of the block: enabled, activation, L, inMin, inMax, outMin, outMax. */
#define IMU_ELM_HEADER 15
/** Length of one ELM block [doubles]. */
#define IMU_ELM_BLOCK (IMU_ELM_HEADER + 7 * IMU_ELM_MAX_HIDDEN)

/** Hidden-node activation. */
typedef enum {
    ImuElmTanh = 0,
    ImuElmSigmoid = 1,
} ImuElmActivation;

/** Trained field-form ELM with its normalisation folded into scale and offset coefficients. */
typedef struct {
    int enabled;                                /* 0: pass-through */
    ImuElmActivation activation;
    int hidden;                                 /* L */
    double inMin[3];                            /* uT */
    double inMax[3];                            /* uT, the calibrated box is [inMin, inMax] */
    double inScale[3];                          /* 1/uT, 2 / (inMax - inMin) */
    double outMin[3];                           /* uT */
    double outHalfSpan[3];                      /* uT, (outMax - outMin) / 2 */
    double w[IMU_ELM_MAX_HIDDEN][3];            /* input weights (normalised units) */
    double b[IMU_ELM_MAX_HIDDEN];               /* biases */
    double beta[IMU_ELM_MAX_HIDDEN][3];         /* output weights (normalised units) */
} ImuElm;

/**
 * @brief Unpack one IMU_ELM_BLOCK-long block (layout above) into elm.
 * @return 0, or -1 if an entry is not finite, enabled is not 0/1 or (when enabled) the
 *         activation code is unknown, L is not an integer in 1..IMU_ELM_MAX_HIDDEN or a
 *         min >= max.
 */
IMU_HIDDEN int ImuElmFromBlock(ImuElm *elm, const double *block);
/** @brief Map a distorted field in [uT] to the corrected field out [uT] (in and out may alias); a
 *         field outside the calibrated box gets the correction of its clamped value.
 *  @return 1 if the field was inside the box (or the ELM is disabled, or the field not finite), 0 if clamped. */
IMU_HIDDEN int ImuElmApply(const ImuElm *elm, const double in[3], double out[3]);

#endif
