/**
 * @file ImuMagPfShared.c
 * @brief What both modes of the particle filter use (docs/magpf.md): the observation and its
 *        innovation, the change test and the re-test of the prior calibration, the field-direction
 *        tests, the weights' normalisation, N_eff and systematic resampling indices. Calls no mode.
 */
#include <math.h>
#include <string.h>
#include "ImuMagPfPrivate.h"
#include "ImuMath.h"

#define IMU_MAG_PF_CLIP_FACTOR 2.0    /* normalised innovations enter the change test clipped at 2 x threshold */
#define IMU_MAG_PF_OUTLIER_FACTOR 4.0 /* samples beyond 4 x changeThreshold (normalised innovation^2) are glitches */
#define IMU_MAG_PF_CHANGE_DIRECTIONS 2 /* field directions (minRotation apart) the evidence against a held calibration must cover */
#define IMU_MAG_PF_RETEST_DIRECTIONS 30 /* field directions (minRotation apart) the prior's agreement must cover */
#define IMU_MAG_PF_RETEST_MARGIN 1.0   /* the prior may miss by one noise variance per update more than the estimate */

/** State index of B[i][j] (soft iron b11 b12 b13 b22 b23 b33 at 3..8). */
static const int ImuMagPfSoftIndex[3][3] = {{3, 4, 5}, {4, 6, 7}, {5, 7, 8}};

/** @brief Squared norm of a 3-vector [unit^2]. */
double ImuMagPfNormSquared(const double v[3])
{
    return v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
}

/** @brief out = (I + B)(mag - h_p) [uT] for a state x (hard [uT], soft [1]). */
void ImuMagPfApply(const double x[IMU_MAG_PF_STATE_SIZE], const double mag[3], double out[3])
{
    const double d[3] = {mag[0] - x[0], mag[1] - x[1], mag[2] - x[2]};
    int i;
    for (i = 0; i < 3; i++) {
        out[i] = d[i] + x[ImuMagPfSoftIndex[i][0]] * d[0] + x[ImuMagPfSoftIndex[i][1]] * d[1] +
                 x[ImuMagPfSoftIndex[i][2]] * d[2];
    }
}

/** @brief h(x) = |mag|^2 - |(I + B)(mag - h_p)|^2 [uT^2] (equals the expanded form of the header). */
static double ImuMagPfObservation(const double x[IMU_MAG_PF_STATE_SIZE], const double mag[3])
{
    double corrected[3];
    ImuMagPfApply(x, mag, corrected);
    return ImuMagPfNormSquared(mag) - ImuMagPfNormSquared(corrected);
}

/** @brief Residual e = |h_m|^2 - |h_0|^2 - h(x) - mean of the observation noise [uT^2] of a state x. */
static double ImuMagPfResidual(const ImuMagPf *pf, const double x[IMU_MAG_PF_STATE_SIZE], const double mag[3])
{
    const ImuMagPfCoefficients *c = &pf->coefficients;
    return ImuMagPfNormSquared(mag) - c->fieldNormSquared - ImuMagPfObservation(x, mag) - c->observationMean;
}

void ImuMagPfHardSpread(ImuMagPf *pf)
{
    double largest = 0.0;
    int i, j;
    for (j = 0; j < 3; j++) {
        double variance = 0.0;
        for (i = 0; i < pf->settings.particleCount; i++) {
            const double d = pf->particle[i][j] - pf->estimate[j];
            variance += pf->weight[i] * d * d;
        }
        largest = variance > largest ? variance : largest;
    }
    pf->hardSpread = sqrt(largest);
}

void ImuMagPfClearEvidence(ImuMagPf *pf)
{
    pf->evidenceDirections = 0;
    pf->retestUpdates = 0;
    pf->retestDirections = 0;
    pf->retestPriorSum = 0.0;
    pf->retestEstimateSum = 0.0;
}

void ImuMagPfPriorState(const ImuMagPf *pf, double x[IMU_MAG_PF_STATE_SIZE])
{
    memcpy(x, pf->settings.priorHardIron, sizeof(pf->settings.priorHardIron));
    memcpy(x + 3, pf->settings.priorSoftIron, sizeof(pf->settings.priorSoftIron));
}

int ImuMagPfTurned(const ImuMagPf *pf, const double reference[3], const double mag[3])
{
    const double norm = ImuVectorNorm(mag), last = ImuVectorNorm(reference);
    return pf->settings.minRotation <= 0.0 || last <= 0.0 ||
           mag[0] * reference[0] + mag[1] * reference[1] + mag[2] * reference[2] <
               pf->coefficients.minRotationCosine * norm * last;
}

int ImuMagPfRotated(const ImuMagPf *pf, const double mag[3])
{
    return ImuMagPfTurned(pf, pf->lastUsed, mag);
}

double ImuMagPfInnovationOf(const ImuMagPf *pf, const double x[IMU_MAG_PF_STATE_SIZE], const double mag[3])
{
    const double e = ImuMagPfResidual(pf, x, mag) - pf->residualMean;
    return 2.0 * pf->coefficients.halfInverseVariance * e * e;
}

double ImuMagPfInnovation(const ImuMagPf *pf, const double mag[3])
{
    return ImuMagPfInnovationOf(pf, pf->estimate, mag);
}

double ImuMagPfClip(const ImuMagPf *pf, double z)
{
    const double clip = pf->settings.glitchClipping ? IMU_MAG_PF_CLIP_FACTOR * pf->settings.changeThreshold : 0.0;
    return clip > 0.0 && z > clip ? clip : z;
}

int ImuMagPfOutlier(const ImuMagPf *pf, const double mag[3])
{
    const double threshold = pf->settings.changeThreshold;
    return pf->settings.glitchClipping && threshold > 0.0 && pf->changeArmed && ImuMagPfInnovation(pf, mag) > IMU_MAG_PF_OUTLIER_FACTOR * threshold;
}

void ImuMagPfAdapt(ImuMagPf *pf, const double mag[3])
{
    const ImuMagPfCoefficients *c = &pf->coefficients;
    double z, clipped, ratio, prior[IMU_MAG_PF_STATE_SIZE];
    if (c->innovationRate <= 0.0) {
        return;
    }
    ImuMagPfPriorState(pf, prior); /* the prior calibration's average: the hypothesis of every re-test */
    pf->priorAverage += c->innovationRate * (ImuMagPfClip(pf, ImuMagPfInnovationOf(pf, prior, mag)) - pf->priorAverage);
    z = ImuMagPfInnovation(pf, mag);
    clipped = ImuMagPfClip(pf, z); /* one glitch cannot declare a change */
    if (pf->settings.normTimeConstant > 0.0 && clipped == z) { /* an ambient norm offset is not a change of
                                                                  the carrier; a glitch is not an ambient norm */
        pf->residualMean += (ImuMagPfResidual(pf, pf->estimate, mag) - pf->residualMean) / pf->settings.normTimeConstant;
    }
    z = clipped;
    pf->innovationAverage += c->innovationRate * (z - pf->innovationAverage);
    ratio = sqrt(pf->innovationAverage);
    pf->inflation = ratio < 1.0 ? 1.0 : (ratio > pf->settings.maxInflation ? pf->settings.maxInflation : ratio);
}

void ImuMagPfDeclareChange(ImuMagPf *pf)
{
    pf->innovationAverage = 1.0;
    pf->inflation = 1.0;
    pf->updatesSinceChange = 0;
    pf->changeArmed = 0;
    pf->changeCount++;
    pf->residualMean = 0.0;
    pf->retesting = 1;
    ImuMagPfClearEvidence(pf);
}

/**
 * Re-test of the prior calibration (from a declared change until taken back): while the average of
 * its clipped normalised innovation (ImuMagPfAdapt) stays under changeThreshold the
 * clipped innovations of prior and estimate are summed, and once the sums span
 * IMU_MAG_PF_RETEST_DIRECTIONS field directions minRotation apart with the prior missing by at most
 * IMU_MAG_PF_RETEST_MARGIN per update more than the estimate, the prior explains the data (a glitch
 * that was declared a change, a magnet that was removed).
 */
int ImuMagPfPriorExplains(ImuMagPf *pf, const double mag[3])
{
    const ImuMagPfSettings *s = &pf->settings;
    double prior[IMU_MAG_PF_STATE_SIZE], z;
    if (!pf->retesting || s->changeThreshold <= 0.0 || pf->coefficients.innovationRate <= 0.0) {
        return 0;
    }
    ImuMagPfPriorState(pf, prior);
    z = ImuMagPfClip(pf, ImuMagPfInnovationOf(pf, prior, mag));
    if (pf->priorAverage > s->changeThreshold) {
        pf->retestUpdates = 0;
        pf->retestDirections = 0;
        pf->retestPriorSum = 0.0;
        pf->retestEstimateSum = 0.0;
        return 0;
    }
    pf->retestUpdates++;
    pf->retestPriorSum += z;
    pf->retestEstimateSum += ImuMagPfClip(pf, ImuMagPfInnovation(pf, mag));
    if (pf->retestDirections == 0 || ImuMagPfTurned(pf, pf->retestDirection, mag)) {
        pf->retestDirections++;
        memcpy(pf->retestDirection, mag, sizeof(pf->retestDirection));
    }
    return pf->retestDirections >= IMU_MAG_PF_RETEST_DIRECTIONS &&
           pf->retestPriorSum <= pf->retestEstimateSum + IMU_MAG_PF_RETEST_MARGIN * pf->retestUpdates;
}

void ImuMagPfChangeCentre(const ImuMagPf *pf, double x[IMU_MAG_PF_STATE_SIZE])
{
    if (pf->priorAverage <= pf->settings.changeThreshold) { /* the change returned to it (a magnet removed) */
        ImuMagPfPriorState(pf, x);
    } else {
        memcpy(x, pf->estimate, sizeof(pf->estimate));
    }
}

void ImuMagPfPriorTakenBack(ImuMagPf *pf)
{
    pf->innovationAverage = pf->priorAverage;
    pf->inflation = 1.0;
    pf->updatesSinceChange = 0;
    pf->retesting = 0;
    ImuMagPfClearEvidence(pf);
}

/** Change test: armed once the innovation average is below changeThreshold after
 *  innovationTimeConstant updates; when armed, an average above it declares a change. To leave a
 *  held calibration the evidence must persist over field directions: the samples whose own
 *  innovation exceeds the threshold must come from IMU_MAG_PF_CHANGE_DIRECTIONS directions
 *  minRotation apart (a carrier change shows at every orientation; a stuck reading shows at one, and
 *  a short burst rarely keeps the average up). Once adapting, one suffices: a magnet brought closer
 *  is declared again at once, and a false declaration is undone by the re-test of the prior. */
int ImuMagPfChangeDeclared(ImuMagPf *pf, const double mag[3])
{
    const ImuMagPfSettings *s = &pf->settings;
    pf->updatesSinceChange++;
    if (s->changeThreshold <= 0.0) {
        return 0;
    }
    if (!pf->changeArmed) {
        pf->changeArmed = pf->updatesSinceChange >= s->innovationTimeConstant && pf->innovationAverage < s->changeThreshold;
        return 0;
    }
    if (pf->innovationAverage <= s->changeThreshold) {
        pf->evidenceDirections = 0;
        return 0;
    }
    if (ImuMagPfInnovation(pf, mag) > s->changeThreshold &&
        (pf->evidenceDirections == 0 || ImuMagPfTurned(pf, pf->evidenceDirection, mag))) {
        pf->evidenceDirections++;
        memcpy(pf->evidenceDirection, mag, sizeof(pf->evidenceDirection));
    }
    if (pf->evidenceDirections < (pf->frozen ? IMU_MAG_PF_CHANGE_DIRECTIONS : 1)) {
        return 0;
    }
    ImuMagPfDeclareChange(pf);
    return 1;
}

void ImuMagPfNormaliseLog(ImuMagPf *pf)
{
    const int n = pf->settings.particleCount;
    double largest = -HUGE_VAL, sum = 0.0;
    int i;
    for (i = 0; i < n; i++) {
        largest = pf->work.logWeight[i] > largest ? pf->work.logWeight[i] : largest;
    }
    for (i = 0; i < n; i++) {
        pf->weight[i] = exp(pf->work.logWeight[i] - largest);
        sum += pf->weight[i];
    }
    for (i = 0; i < n; i++) {
        pf->weight[i] /= sum;
    }
}

double ImuMagPfEss(const ImuMagPf *pf)
{
    double sum = 0.0;
    int i;
    for (i = 0; i < pf->settings.particleCount; i++) {
        sum += pf->weight[i] * pf->weight[i];
    }
    return 1.0 / sum;
}

/** @brief Systematic resampling indices (one uniform, offsets (U + k)/N) into work.parent. */
void ImuMagPfSystematicParents(ImuMagPf *pf)
{
    const int n = pf->settings.particleCount;
    const double start = ImuRngUniform(&pf->rng) / n;
    double cumulative = pf->weight[0];
    int i = 0, k;
    for (k = 0; k < n; k++) {
        const double target = start + (double)k / n;
        while (target > cumulative && i < n - 1) {
            i++;
            cumulative += pf->weight[i];
        }
        pf->work.parent[k] = i;
    }
}
