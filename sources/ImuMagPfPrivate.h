/**
 * @file ImuMagPfPrivate.h
 * @brief What the files of the particle filter share, by the file that defines it; not part of
 *        the pipeline's interface (ImuMagPf.h). Dependencies one way: ImuMagPf.c (facade) ->
 *        ImuMagPfSplit.c (mode 0) -> ImuMagPfNet.c, and ImuMagPfRb.c (mode 1); both modes ->
 *        ImuMagPfShared.c, which calls no mode.
 */
#ifndef IMU_MAG_PF_PRIVATE_H
#define IMU_MAG_PF_PRIVATE_H

#include "ImuMagPf.h"

/* ImuMagPfShared.c: used by both modes */
/** @brief Squared norm of a 3-vector [unit^2]. */
IMU_HIDDEN double ImuMagPfNormSquared(const double v[3]);
/** @brief out = (I + B)(mag - h_p) [uT] for a state x (hard [uT], soft [1]). */
IMU_HIDDEN void ImuMagPfApply(const double x[IMU_MAG_PF_STATE_SIZE], const double mag[3], double out[3]);
/** @brief pf->hardSpread from the particles, their weights and the estimate. */
IMU_HIDDEN void ImuMagPfHardSpread(ImuMagPf *pf);
/** @brief The prior calibration as a state x (priorHardIron [uT], priorSoftIron [1]). */
IMU_HIDDEN void ImuMagPfPriorState(const ImuMagPf *pf, double x[IMU_MAG_PF_STATE_SIZE]);
/** @brief Restart the evidence of a change and the re-test of the prior (the prior unproven). */
IMU_HIDDEN void ImuMagPfClearEvidence(ImuMagPf *pf);
/** @brief 1 if minRotation is 0 or the direction of mag [uT] is more than minRotation away from the
 *         last used sample (the first sample always counts). */
IMU_HIDDEN int ImuMagPfRotated(const ImuMagPf *pf, const double mag[3]);
/** @brief 1 if minRotation is 0 or the direction of mag [uT] is more than minRotation away from that of
 *         reference [uT] (or reference is zero). */
IMU_HIDDEN int ImuMagPfTurned(const ImuMagPf *pf, const double reference[3], const double mag[3]);
/** @brief Normalised innovation squared (y - h(x_estimate) - 3 sigma^2)^2 / var of a sample mag [uT]. */
IMU_HIDDEN double ImuMagPfInnovation(const ImuMagPf *pf, const double mag[3]);
/** @brief The same for a state x (hard [uT], soft [1]), the averaged residual of the estimate removed. */
IMU_HIDDEN double ImuMagPfInnovationOf(const ImuMagPf *pf, const double x[IMU_MAG_PF_STATE_SIZE], const double mag[3]);
/** @brief A normalised innovation clipped at IMU_MAG_PF_CLIP_FACTOR (ImuMagPfShared.c) x changeThreshold (as it enters the tests);
 *         z itself with glitchClipping 0. */
IMU_HIDDEN double ImuMagPfClip(const ImuMagPf *pf, double z);
/** @brief 1 if the change test is armed and the sample's normalised innovation exceeds
 *         IMU_MAG_PF_OUTLIER_FACTOR (ImuMagPfShared.c) x changeThreshold (a glitch: kept out of the power sums); 0 with glitchClipping 0. */
IMU_HIDDEN int ImuMagPfOutlier(const ImuMagPf *pf, const double mag[3]);
/** @brief Innovation average (inputs clipped at 2 x changeThreshold) and noise inflation from one sample [uT]. */
IMU_HIDDEN void ImuMagPfAdapt(ImuMagPf *pf, const double mag[3]);
/** @brief Count a change of environment and restart the innovation average and the change test. */
IMU_HIDDEN void ImuMagPfDeclareChange(ImuMagPf *pf);
/** @brief Change test on the innovation average of the sample mag [uT]: a change is declared once,
 *         while the average is above changeThreshold, the samples whose own innovation exceeded it
 *         cover IMU_MAG_PF_CHANGE_DIRECTIONS directions (a held calibration) or one (adapting);
 *         1 (counters reset, change counted, re-test of the prior started) if declared. */
IMU_HIDDEN int ImuMagPfChangeDeclared(ImuMagPf *pf, const double mag[3]);
/** @brief Re-test of the prior calibration after a declared change, one update with sample mag [uT]:
 *         1 once it explains the data from IMU_MAG_PF_RETEST_DIRECTIONS directions as well as the
 *         estimate (IMU_MAG_PF_RETEST_MARGIN). */
IMU_HIDDEN int ImuMagPfPriorExplains(ImuMagPf *pf, const double mag[3]);
/** @brief Centre x of the cloud after a declared change: the prior calibration if its innovation
 *         average is under changeThreshold (it explains the recent data the estimate does not: the
 *         change returned to it, a magnet removed), else the estimate. */
IMU_HIDDEN void ImuMagPfChangeCentre(const ImuMagPf *pf, double x[IMU_MAG_PF_STATE_SIZE]);
/** @brief After a mode re-drew its particles around the prior calibration: the innovation average
 *         restarts from the prior's, the inflation at 1, the change test and its evidence anew. */
IMU_HIDDEN void ImuMagPfPriorTakenBack(ImuMagPf *pf);
/** @brief Weights from the log weights in work.logWeight (max-subtracted, normalised). */
IMU_HIDDEN void ImuMagPfNormaliseLog(ImuMagPf *pf);
/** @brief Effective sample size 1 / sum w^2 of the current weights [particles]. */
IMU_HIDDEN double ImuMagPfEss(const ImuMagPf *pf);
/** @brief Systematic resampling indices (one uniform, offsets (U + k)/N) into work.parent. */
IMU_HIDDEN void ImuMagPfSystematicParents(ImuMagPf *pf);

/* ImuMagPfNet.c: steps 5-6 of mode 0 */
/** @brief Roughening sigma per state component: K N^(-1/9) x (unweighted) cloud standard deviation. */
IMU_HIDDEN void ImuMagPfCloudSigma(const ImuMagPf *pf, double sigma[IMU_MAG_PF_STATE_SIZE]);
/** @brief Steps 5-6: splitting with network-based diversity restoration (alpha: tempering exponent). */
IMU_HIDDEN void ImuMagPfNetSplit(ImuMagPf *pf, double alpha);

/* ImuMagPfSplit.c: mode 0, the method's 9-state filter */
/** @brief Mode 0 reset: particles around the prior calibration with the prior spreads, weights 1/N,
 *         and the estimate. */
IMU_HIDDEN void ImuMagPfDrawPrior(ImuMagPf *pf);
/** @brief Mode 0: one valid sample [uT]; 1 if the filter updated, 0 if skipped or decimated. */
IMU_HIDDEN int ImuMagPfSplitUpdate(ImuMagPf *pf, const double mag[3]);

/* ImuMagPfRb.c: mode 1, Rao-Blackwellised */
/** @brief Rao-Blackwellised mode: draw the prior particles (ImuMagPfRb.c). */
IMU_HIDDEN void ImuMagPfRbReset(ImuMagPf *pf);
/** @brief Rao-Blackwellised mode: one valid sample [uT]; 1 if the particles were updated. */
IMU_HIDDEN int ImuMagPfRbUpdate(ImuMagPf *pf, const double mag[3]);

#endif
