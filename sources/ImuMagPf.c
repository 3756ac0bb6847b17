/**
 * @file ImuMagPf.c
 * @brief Online hard- and soft-iron estimation by particle filter (method: docs/magpf.md): the
 *        facade the pipeline and the batch library call (settings, initialise/configure/reset,
 *        update dispatch, compensation, getters).
 *
 * Files, dependencies one way (a file calls only files listed below it):
 *   ImuMagPf.c        this facade, interface ImuMagPf.h -> both modes, ImuMagPfShared.c
 *   ImuMagPfSplit.c   mode 0, the method's 9-state filter -> ImuMagPfNet.c, ImuMagPfShared.c
 *   ImuMagPfRb.c      mode 1, Rao-Blackwellised (ImuMagMoments.c) -> ImuMagPfShared.c
 *   ImuMagPfNet.c     mode 0's double-threshold splitting and back-propagation restoration network
 *   ImuMagPfShared.c  what both modes use: observation and innovation, change test, re-test of
 *                     the prior calibration, field-direction tests, N_eff, resampling indices
 * ImuMagPfPrivate.h declares what these files share; ImuMagPf.h is the pipeline's interface.
 */
#include <math.h>
#include <string.h>
#include "ImuMagPfPrivate.h"
#include "ImuMath.h"

#define IMU_MAG_PF_TEXT(x) #x
#define IMU_MAG_PF_STRING(x) IMU_MAG_PF_TEXT(x)
#define IMU_MAG_PF_RNG_STREAM 54U    /* PCG32 stream selector of the filter */
#define IMU_MAG_PF_MAX_FIELD_RATIO 20.0   /* samples above 20 |h_0| are absurd (saturation, glitch) */
#define IMU_MAG_PF_MIN_FIELD_RATIO 1e-3   /* samples below 0.001 |h_0| are dropouts */

/** @brief Default settings (docs/magpf.md: prior = a trained calibration) for a field norm [uT]. */
void ImuMagPfSettingsDefault(ImuMagPfSettings *settings, double fieldNorm)
{
    int j;
    settings->particleCount = 128;
    settings->highThreshold = 2.0;
    settings->lowThreshold = 0.5;
    settings->measurementNoise = 0.3;
    settings->processNoiseHard = 0.01;
    settings->processNoiseSoft = 2e-4;
    settings->priorSpreadHard = 3.0;
    settings->priorSpreadSoft = 0.02;
    for (j = 0; j < 3; j++) {
        settings->priorHardIron[j] = 0.0;
    }
    for (j = 0; j < 6; j++) {
        settings->priorSoftIron[j] = 0.0;
    }
    settings->roughening = 0.2;
    settings->innovationTimeConstant = 5.0;
    settings->maxInflation = 20.0;
    settings->decimation = 16;
    settings->minRotation = 0.5;
    settings->hiddenUnits = 5;
    settings->trainingEpochs = 20;
    settings->learningRate = 0.1;
    settings->maxTries = 3;
    settings->enableSplitting = 1;
    settings->enableMove = 1;
    settings->sphereBins = 2;
    settings->changeThreshold = 25.0;
    settings->changeSpreadHard = 30.0;
    settings->changeSpreadSoft = 0.01;
    settings->raoBlackwell = 1;
    settings->holdPrior = 1;
    settings->normTimeConstant = 300.0;
    settings->settleSpread = 1.0;
    settings->seed = 1U;
    settings->fieldNorm = fieldNorm;
}

/** @brief Message for the first invalid count or threshold setting, or NULL. */
static const char *ImuMagPfCheckCounts(const ImuMagPfSettings *s)
{
    if (s->particleCount < 2 || s->particleCount > IMU_MAG_PF_MAX_PARTICLES) {
        return "pf_particles (particleCount) must be in 2.." IMU_MAG_PF_STRING(IMU_MAG_PF_MAX_PARTICLES)
               " (IMU_MAG_PF_MAX_PARTICLES)";
    }
    if (!(s->highThreshold > 1.0 && s->highThreshold <= 100.0)) {
        return "pf_threshold_high (highThreshold, omega1, relative to 1/N) must be in (1, 100]";
    }
    if (!(s->lowThreshold > 0.0 && s->lowThreshold < 1.0)) {
        return "pf_threshold_low (lowThreshold, omega2, relative to 1/N) must be in (0, 1)";
    }
    if (s->decimation < 1 || s->decimation > 1000) {
        return "pf_decimation (decimation) must be in 1..1000";
    }
    if (s->hiddenUnits < 1 || s->hiddenUnits > IMU_MAG_PF_MAX_HIDDEN) {
        return "hiddenUnits must be in 1.." IMU_MAG_PF_STRING(IMU_MAG_PF_MAX_HIDDEN);
    }
    if (s->trainingEpochs < 1 || s->trainingEpochs > 200) {
        return "trainingEpochs must be in 1..200";
    }
    if (s->maxTries < 1 || s->maxTries > 20) {
        return "maxTries must be in 1..20";
    }
    if (s->enableSplitting != 0 && s->enableSplitting != 1) {
        return "enableSplitting must be 0 or 1";
    }
    if (s->enableMove != 0 && s->enableMove != 1) {
        return "enableMove must be 0 or 1";
    }
    if (s->raoBlackwell != 0 && s->raoBlackwell != 1) {
        return "pf_rao_blackwell (raoBlackwell) must be 0 or 1";
    }
    if (s->holdPrior != 0 && s->holdPrior != 1) {
        return "pf_hold_prior (holdPrior) must be 0 or 1";
    }
    if (s->sphereBins < 0 || s->sphereBins > IMU_MAG_PF_MAX_BIN_SIDE) {
        return "pf_sphere_bins (sphereBins) must be in 0.." IMU_MAG_PF_STRING(IMU_MAG_PF_MAX_BIN_SIDE) " (IMU_MAG_PF_MAX_BIN_SIDE)";
    }
    return NULL;
}

/** @brief Message for the first invalid noise, prior or field setting, or NULL. */
static const char *ImuMagPfCheckValues(const ImuMagPfSettings *s)
{
    if (!(s->measurementNoise > 0.0 && s->measurementNoise <= 100.0)) {
        return "pf_measurement_noise (measurementNoise) must be in (0, 100] uT";
    }
    if (!(s->processNoiseHard >= 0.0 && s->processNoiseHard <= 100.0)) {
        return "pf_process_noise_hard (processNoiseHard) must be in [0, 100] uT per update";
    }
    if (!(s->processNoiseSoft >= 0.0 && s->processNoiseSoft <= 1.0)) {
        return "pf_process_noise_soft (processNoiseSoft) must be in [0, 1] per update";
    }
    if (!(s->priorSpreadHard >= 0.0 && s->priorSpreadHard <= 1e4)) {
        return "pf_prior_spread_hard (priorSpreadHard) must be in [0, 1e4] uT";
    }
    if (!(s->priorSpreadSoft >= 0.0 && s->priorSpreadSoft <= 1.0)) {
        return "pf_prior_spread_soft (priorSpreadSoft) must be in [0, 1]";
    }
    if (!ImuAllFinite(s->priorHardIron, 3) || !ImuAllFinite(s->priorSoftIron, 6)) {
        return "priorHardIron and priorSoftIron must be finite";
    }
    if (!(s->roughening >= 0.0 && s->roughening <= 10.0)) {
        return "roughening must be in [0, 10]";
    }
    if (!(s->innovationTimeConstant >= 0.0 && s->innovationTimeConstant <= 1e6)) {
        return "innovationTimeConstant must be in [0, 1e6] updates (0: off)";
    }
    if (!(s->maxInflation >= 1.0 && s->maxInflation <= 1e3)) {
        return "maxInflation must be in [1, 1000]";
    }
    if (!(s->minRotation >= 0.0 && s->minRotation <= 90.0)) {
        return "pf_min_rotation (minRotation) must be in [0, 90] deg";
    }
    if (!(s->learningRate > 0.0 && s->learningRate <= 10.0)) {
        return "learningRate must be in (0, 10]";
    }
    if (!(s->changeThreshold == 0.0 || (s->changeThreshold >= 2.0 && s->changeThreshold <= 1e6))) {
        return "changeThreshold must be 0 (off) or in [2, 1e6]";
    }
    if (!(s->changeSpreadHard >= 0.0 && s->changeSpreadHard <= 1e4)) {
        return "pf_change_spread_hard (changeSpreadHard) must be in [0, 1e4] uT";
    }
    if (!(s->changeSpreadSoft >= 0.0 && s->changeSpreadSoft <= 1.0)) {
        return "changeSpreadSoft must be in [0, 1]";
    }
    if (!(s->settleSpread >= 0.0 && s->settleSpread <= 1e4)) {
        return "pf_settle_spread (settleSpread) must be in [0, 1e4] uT (0: always settled)";
    }
    if (!(s->normTimeConstant >= 0.0 && s->normTimeConstant <= 1e6)) {
        return "normTimeConstant must be in [0, 1e6] updates (0: off)";
    }
    if (!(s->fieldNorm > 0.0 && s->fieldNorm <= 1e4)) {
        return "fieldNorm must be in (0, 1e4] uT";
    }
    if (s->raoBlackwell && !(s->priorSpreadHard > 0.0 && s->changeSpreadHard > 0.0)) {
        return "pf_prior_spread_hard (priorSpreadHard) and pf_change_spread_hard (changeSpreadHard) must be > 0 uT when pf_rao_blackwell is 1";
    }
    return NULL;
}

/** @brief 0 if the settings are valid, else -1 with *message naming the setting and its range. */
int ImuMagPfSettingsCheck(const ImuMagPfSettings *settings, const char **message)
{
    const char *text = ImuMagPfCheckCounts(settings);
    if (text == NULL) {
        text = ImuMagPfCheckValues(settings);
    }
    if (message != NULL) {
        *message = text;
    }
    return text == NULL ? 0 : -1;
}

/** @brief Derive the coefficients (observation noise moments, absolute thresholds) from settings. */
static void ImuMagPfDerive(ImuMagPf *pf)
{
    const ImuMagPfSettings *s = &pf->settings;
    ImuMagPfCoefficients *c = &pf->coefficients;
    const double variance = s->measurementNoise * s->measurementNoise;
    int j;
    c->fieldNormSquared = s->fieldNorm * s->fieldNorm;
    c->observationMean = 3.0 * variance;
    c->halfInverseVariance = 0.5 / (4.0 * c->fieldNormSquared * variance + 6.0 * variance * variance);
    c->highWeight = s->highThreshold / (double)s->particleCount;
    c->lowWeight = s->lowThreshold / (double)s->particleCount;
    c->rougheningScale = s->roughening * pow((double)s->particleCount, -1.0 / IMU_MAG_PF_STATE_SIZE);
    for (j = 0; j < IMU_MAG_PF_STATE_SIZE; j++) {
        c->processNoise[j] = j < 3 ? s->processNoiseHard : s->processNoiseSoft;
    }
    c->innovationRate = s->innovationTimeConstant > 0.0 ? 1.0 / s->innovationTimeConstant : 0.0;
    c->minRotationCosine = cos(s->minRotation * IMU_PI / 180.0);
}

int ImuMagPfConfigure(ImuMagPf *pf, const ImuMagPfSettings *settings)
{
    if (ImuMagPfSettingsCheck(settings, NULL) != 0) {
        return -1;
    }
    pf->settings = *settings;
    ImuMagPfDerive(pf);
    return 0;
}

/** @brief Check settings, derive coefficients and reset; 0, or -1 (filter untouched) if invalid. */
int ImuMagPfInitialise(ImuMagPf *pf, const ImuMagPfSettings *settings)
{
    if (ImuMagPfSettingsCheck(settings, NULL) != 0) {
        return -1;
    }
    memset(pf, 0, sizeof(*pf));
    (void)ImuMagPfConfigure(pf, settings);
    ImuMagPfReset(pf);
    return 0;
}

int ImuMagPfStateValid(const ImuMagPf *pf)
{
    const int k = pf->settings.sphereBins;
    const int bins = k > 0 ? 6 * k * k : 1;
    int i, used = 0;
    if (bins > IMU_MAG_PF_MAX_BINS || pf->binCount < 0 || pf->binCount > bins
        || pf->sampleCounter < 0 || pf->sampleCounter >= pf->settings.decimation) {
        return 0;
    }
    for (i = 0; i < IMU_MAG_PF_MAX_BINS; i++) {
        if (pf->binUsed[i] != 0 && (pf->binUsed[i] != 1 || i >= bins)) {
            return 0;
        }
        used += pf->binUsed[i];
    }
    for (i = 0; i < pf->binCount; i++) {
        if (pf->binList[i] < 0 || pf->binList[i] >= bins || !pf->binUsed[pf->binList[i]]) {
            return 0;
        }
    }
    return used == pf->binCount; /* binCount grows only when an unused bin fills: it stays <= bins */
}

/** @brief Reseed the generator and draw the prior particles (weights 1/N). */
void ImuMagPfReset(ImuMagPf *pf)
{
    const ImuMagPfSettings *s = &pf->settings;
    ImuRngSeed(&pf->rng, s->seed, IMU_MAG_PF_RNG_STREAM);
    pf->effectiveSampleSize = (double)s->particleCount;
    pf->innovationAverage = 1.0;
    pf->priorAverage = 1.0;
    pf->inflation = 1.0;
    pf->sampleCounter = 0;
    pf->lastUsed[0] = pf->lastUsed[1] = pf->lastUsed[2] = 0.0;
    memset(pf->binUsed, 0, sizeof(pf->binUsed));
    pf->binCount = 0;
    pf->updatesSinceChange = 0;
    pf->changeArmed = 0;
    pf->changeCount = 0;
    pf->frozen = 0;
    pf->residualMean = 0.0;
    pf->retesting = 0;
    ImuMagPfClearEvidence(pf);
    if (s->raoBlackwell) {
        ImuMagPfRbReset(pf);
    } else {
        ImuMagPfDrawPrior(pf);
    }
}

/** @brief 1 if mag [uT] is finite and its norm within (0.001, 20) |h_0|. */
static int ImuMagPfIsValidSample(const ImuMagPf *pf, const double mag[3])
{
    const double norm = ImuAllFinite(mag, 3) ? ImuVectorNorm(mag) : -1.0;
    return norm > IMU_MAG_PF_MIN_FIELD_RATIO * pf->settings.fieldNorm &&
           norm < IMU_MAG_PF_MAX_FIELD_RATIO * pf->settings.fieldNorm;
}

/** @brief Feed one raw field sample [uT]; 1 if the filter updated, 0 if skipped or decimated. */
int ImuMagPfUpdate(ImuMagPf *pf, const double mag[3])
{
    if (!ImuMagPfIsValidSample(pf, mag)) {
        return 0;
    }
    return pf->settings.raoBlackwell ? ImuMagPfRbUpdate(pf, mag) : ImuMagPfSplitUpdate(pf, mag);
}

/** @brief h_c = (I + B)(mag - h_p) [uT] with the current estimate. */
void ImuMagPfCompensate(const ImuMagPf *pf, const double mag[3], double out[3])
{
    ImuMagPfApply(pf->estimate, mag, out);
}

int ImuMagPfSettled(const ImuMagPf *pf)
{
    return pf->frozen || pf->settings.settleSpread <= 0.0 || pf->hardSpread < pf->settings.settleSpread;
}

/** @brief Hard-iron estimate h_p [uT]. */
void ImuMagPfGetHardIron(const ImuMagPf *pf, double hardIron[3])
{
    memcpy(hardIron, pf->estimate, 3 * sizeof(double));
}

/** @brief Soft-iron estimate [1] as b11 b12 b13 b22 b23 b33. */
void ImuMagPfGetSoftIron(const ImuMagPf *pf, double softIron[6])
{
    memcpy(softIron, pf->estimate + 3, 6 * sizeof(double));
}

/** @brief Effective sample size 1 / sum w^2 after the last update [particles]. */
double ImuMagPfGetEffectiveSampleSize(const ImuMagPf *pf)
{
    return pf->effectiveSampleSize;
}

/** @brief Number of changes of environment declared since the reset. */
int ImuMagPfGetChangeCount(const ImuMagPf *pf)
{
    return pf->changeCount;
}
