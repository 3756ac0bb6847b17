/**
 * @file ImuMagPfSplit.c
 * @brief Mode 0 of the particle filter (raoBlackwell = 0, docs/magpf.md): the method's 9-state
 *        filter — predict, weigh, double-threshold splitting with the restoration network
 *        (ImuMagPfNet.c) below N_eff 2N/3, then systematic resampling if N_eff is still below —
 *        and the project's additions, each with its switch (training.models.magpf.ADDITIONS): a
 *        buffer of past samples binned over the sphere of directions (sphereBins), tempering
 *        (enableTempering), roughening of the resampled cloud (resampleRoughening) with Metropolis
 *        moves (enableMove), and the change test, inflation and gates of ImuMagPfShared.c.
 */
#include <math.h>
#include <string.h>
#include "ImuMagPfPrivate.h"

#define IMU_MAG_PF_RESAMPLE_FRACTION (2.0 / 3.0) /* N_eff threshold relative to N (steps 4, 7) */
#define IMU_MAG_PF_LN2 0.69314718055994531 /* tempering target: N_eff / N >= 1/2 per update */

/** @brief Weighted mean of the particles into pf->estimate, and the hard-iron spread. */
static void ImuMagPfEstimate(ImuMagPf *pf)
{
    int i, j;
    for (j = 0; j < IMU_MAG_PF_STATE_SIZE; j++) {
        pf->estimate[j] = 0.0;
    }
    for (i = 0; i < pf->settings.particleCount; i++) {
        for (j = 0; j < IMU_MAG_PF_STATE_SIZE; j++) {
            pf->estimate[j] += pf->weight[i] * pf->particle[i][j];
        }
    }
    ImuMagPfHardSpread(pf);
}

/** @brief Mode 0: particles around the prior calibration with the prior spreads, weights 1/N, estimate. */
void ImuMagPfDrawPrior(ImuMagPf *pf)
{
    const ImuMagPfSettings *s = &pf->settings;
    const int n = s->particleCount;
    int i, j;
    for (i = 0; i < n; i++) {
        for (j = 0; j < 3; j++) {
            pf->particle[i][j] = s->priorHardIron[j] + s->priorSpreadHard * ImuRngNormal(&pf->rng);
        }
        for (j = 0; j < 6; j++) {
            pf->particle[i][3 + j] = s->priorSoftIron[j] + s->priorSpreadSoft * ImuRngNormal(&pf->rng);
        }
        pf->weight[i] = 1.0 / (double)n;
    }
    ImuMagPfEstimate(pf);
}

/** @brief Random-walk prediction x += inflation * processNoise .* N(0, 1) (state units). */
static void ImuMagPfPredict(ImuMagPf *pf)
{
    int i, j;
    for (i = 0; i < pf->settings.particleCount; i++) {
        for (j = 0; j < IMU_MAG_PF_STATE_SIZE; j++) {
            pf->particle[i][j] += pf->inflation * pf->coefficients.processNoise[j] * ImuRngNormal(&pf->rng);
        }
    }
}

/**
 * @brief Tempering exponent alpha in (0, 1] of the log likelihoods l_i = work.logWeight: with
 *        lognormal weights N_eff/N ~ exp(-alpha^2 var_w(l)), alpha = min(1, sqrt(ln 2 / var_w(l)))
 *        keeps N_eff near N/2 or above in one update (progressive correction).
 */
static double ImuMagPfTemper(const ImuMagPf *pf)
{
    double mean = 0.0, variance = 0.0;
    int i;
    for (i = 0; i < pf->settings.particleCount; i++) {
        mean += pf->weight[i] * pf->work.logWeight[i];
    }
    for (i = 0; i < pf->settings.particleCount; i++) {
        const double d = pf->work.logWeight[i] - mean;
        variance += pf->weight[i] * d * d;
    }
    return variance > IMU_MAG_PF_LN2 ? sqrt(IMU_MAG_PF_LN2 / variance) : 1.0;
}

/** @brief Direction bin of a sample [uT] on a cube map (6 faces x k x k cells) of mag - h_p(estimate). */
static int ImuMagPfBinIndex(const ImuMagPf *pf, const double mag[3])
{
    const int k = pf->settings.sphereBins;
    const double d[3] = {mag[0] - pf->estimate[0], mag[1] - pf->estimate[1], mag[2] - pf->estimate[2]};
    const int a = fabs(d[0]) >= fabs(d[1]) ? (fabs(d[0]) >= fabs(d[2]) ? 0 : 2) : (fabs(d[1]) >= fabs(d[2]) ? 1 : 2);
    const double scale = d[a] != 0.0 ? 0.5 * k / fabs(d[a]) : 0.0;
    int u = (int)floor((d[(a + 1) % 3] * scale) + 0.5 * k), v = (int)floor((d[(a + 2) % 3] * scale) + 0.5 * k);
    u = u < 0 ? 0 : (u > k - 1 ? k - 1 : u);
    v = v < 0 ? 0 : (v > k - 1 ? k - 1 : v);
    return ((2 * a + (d[a] < 0.0)) * k + u) * k + v;
}

/** @brief Put the sample [uT] into its bin (replacing an older one); with sphereBins 0 the buffer
 *         holds the current sample only. */
static void ImuMagPfStore(ImuMagPf *pf, const double mag[3])
{
    const int b = pf->settings.sphereBins > 0 ? ImuMagPfBinIndex(pf, mag) : 0;
    if (!pf->binUsed[b]) {
        pf->binUsed[b] = 1;
        pf->binList[pf->binCount++] = b;
    }
    memcpy(pf->bin[b], mag, sizeof(pf->bin[b]));
}

/** @brief Log likelihood of the buffer for state x: -sum_b (y_b - h(x, mag_b) - mean)^2 / (2 var) [1],
 *         evaluated in the equal form y_b - h(x, mag_b) = |(I + B)(mag_b - h_p)|^2 - |h_0|^2. */
static double ImuMagPfLogLikelihood(const ImuMagPf *pf, const double x[IMU_MAG_PF_STATE_SIZE])
{
    const ImuMagPfCoefficients *c = &pf->coefficients;
    const double offset = c->fieldNormSquared + c->observationMean;
    double sum = 0.0, corrected[3];
    int s;
    for (s = 0; s < pf->binCount; s++) {
        double e;
        ImuMagPfApply(x, pf->bin[pf->binList[s]], corrected);
        e = ImuMagPfNormSquared(corrected) - offset;
        sum += e * e;
    }
    return -sum * c->halfInverseVariance;
}

/** @brief Weight update w *= p(buffer | x)^alpha (alpha = 1 with enableTempering 0); stores
 *         log p(buffer | x_i); returns alpha. */
static double ImuMagPfWeigh(ImuMagPf *pf)
{
    double alpha;
    int i;
    for (i = 0; i < pf->settings.particleCount; i++) {
        pf->work.logLikelihood[i] = ImuMagPfLogLikelihood(pf, pf->particle[i]);
        pf->work.logWeight[i] = pf->work.logLikelihood[i];
    }
    alpha = pf->settings.enableTempering ? ImuMagPfTemper(pf) : 1.0;
    for (i = 0; i < pf->settings.particleCount; i++) {
        pf->work.logWeight[i] = (pf->weight[i] > 0.0 ? log(pf->weight[i]) : -HUGE_VAL) + alpha * pf->work.logWeight[i];
    }
    ImuMagPfNormaliseLog(pf);
    return alpha;
}

/** @brief After a declared change: re-draw the particles around ImuMagPfChangeCentre with
 *         changeSpread (weights 1/N) and flush the buffer. */
static void ImuMagPfRedraw(ImuMagPf *pf)
{
    const ImuMagPfSettings *s = &pf->settings;
    double centre[IMU_MAG_PF_STATE_SIZE];
    int i, j;
    ImuMagPfChangeCentre(pf, centre);
    for (i = 0; i < s->particleCount; i++) {
        for (j = 0; j < IMU_MAG_PF_STATE_SIZE; j++) {
            pf->particle[i][j] = centre[j] + (j < 3 ? s->changeSpreadHard : s->changeSpreadSoft) * ImuRngNormal(&pf->rng);
        }
        pf->weight[i] = 1.0 / s->particleCount;
    }
    memset(pf->binUsed, 0, sizeof(pf->binUsed));
    pf->binCount = 0;
}

/**
 * @brief Systematic resampling to equal weights; with resampleRoughening the new cloud is then
 *        roughened, and with enableMove each roughened particle is a Metropolis proposal accepted with
 *        probability min(1, (p(buffer | x') / p(buffer | x))^alpha) (resample-move), else it keeps x.
 */
static void ImuMagPfResample(ImuMagPf *pf, double alpha)
{
    const int n = pf->settings.particleCount;
    double sigma[IMU_MAG_PF_STATE_SIZE], proposal[IMU_MAG_PF_STATE_SIZE];
    int k, j;
    ImuMagPfCloudSigma(pf, sigma);
    ImuMagPfSystematicParents(pf);
    for (k = 0; k < n; k++) {
        memcpy(pf->work.copy[k], pf->particle[pf->work.parent[k]], sizeof(pf->particle[0]));
        pf->work.logWeight[k] = pf->work.logLikelihood[pf->work.parent[k]];
    }
    memcpy(pf->particle, pf->work.copy, (size_t)n * sizeof(pf->particle[0]));
    for (k = 0; k < n; k++) {
        pf->weight[k] = 1.0 / n;
    }
    for (k = 0; k < n && pf->settings.resampleRoughening; k++) {
        for (j = 0; j < IMU_MAG_PF_STATE_SIZE; j++) {
            proposal[j] = pf->particle[k][j] + sigma[j] * ImuRngNormal(&pf->rng);
        }
        if (pf->settings.enableMove) {
            const double l = ImuMagPfLogLikelihood(pf, proposal);
            const double u = ImuRngUniform(&pf->rng);
            if (!(l >= pf->work.logWeight[k] || u < exp(alpha * (l - pf->work.logWeight[k])))) {
                continue;
            }
        }
        memcpy(pf->particle[k], proposal, sizeof(proposal));
    }
}

/** @brief Renormalise the weights to sum 1. */
static void ImuMagPfNormalise(ImuMagPf *pf)
{
    double sum = 0.0;
    int i;
    for (i = 0; i < pf->settings.particleCount; i++) {
        sum += pf->weight[i];
    }
    for (i = 0; i < pf->settings.particleCount; i++) {
        pf->weight[i] /= sum;
    }
}

/** @brief Take the prior calibration back: the cloud re-drawn around it, the buffer flushed, the
 *         change test disarmed and restarted. */
static void ImuMagPfSplitTakeBackPrior(ImuMagPf *pf)
{
    ImuMagPfDrawPrior(pf);
    memset(pf->binUsed, 0, sizeof(pf->binUsed));
    pf->binCount = 0;
    pf->changeArmed = 0;
    ImuMagPfPriorTakenBack(pf);
}

int ImuMagPfSplitUpdate(ImuMagPf *pf, const double mag[3])
{
    const double threshold = IMU_MAG_PF_RESAMPLE_FRACTION * pf->settings.particleCount;
    double alpha;
    int glitch;
    if (!ImuMagPfRotated(pf, mag) || ++pf->sampleCounter < pf->settings.decimation) {
        return 0;
    }
    pf->sampleCounter = 0;
    memcpy(pf->lastUsed, mag, sizeof(pf->lastUsed));
    /* the buffer keeps a reading per direction bin until that direction recurs, for good if the motion
       never returns there: an isolated glitch (the innovation average still low) stays out of it */
    glitch = ImuMagPfOutlier(pf, mag) && pf->innovationAverage <= pf->settings.changeThreshold;
    ImuMagPfAdapt(pf, mag);
    if (ImuMagPfChangeDeclared(pf, mag)) {
        ImuMagPfRedraw(pf);
        glitch = 0;
    } else if (ImuMagPfPriorExplains(pf, mag)) { /* the change was a glitch, or it returned */
        ImuMagPfSplitTakeBackPrior(pf);
        return 0;
    }
    if (!glitch) {
        ImuMagPfStore(pf, mag);
    }
    ImuMagPfPredict(pf);
    alpha = ImuMagPfWeigh(pf);
    pf->effectiveSampleSize = ImuMagPfEss(pf);
    if (pf->effectiveSampleSize < threshold && pf->settings.enableSplitting) {
        ImuMagPfNetSplit(pf, alpha);
        ImuMagPfNormalise(pf);
        pf->effectiveSampleSize = ImuMagPfEss(pf);
    }
    if (pf->effectiveSampleSize < threshold) {
        ImuMagPfResample(pf, alpha);
    }
    ImuMagPfEstimate(pf);
    return 1;
}
