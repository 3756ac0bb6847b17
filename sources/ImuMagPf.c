/**
 * @file ImuMagPf.c
 * @brief Online hard- and soft-iron estimation by particle filter (method: docs/magpf.md).
 */
#include <math.h>
#include <string.h>
#include "ImuMagPf.h"
#include "ImuMath.h"

#define IMU_MAG_PF_TEXT(x) #x
#define IMU_MAG_PF_STRING(x) IMU_MAG_PF_TEXT(x)
#define IMU_MAG_PF_MAX_FIELD_RATIO 20.0   /* samples above 20 |h_0| are absurd (saturation, glitch) */
#define IMU_MAG_PF_MIN_FIELD_RATIO 1e-3   /* samples below 0.001 |h_0| are dropouts */
#define IMU_MAG_PF_RESAMPLE_FRACTION (2.0 / 3.0) /* N_eff threshold relative to N (steps 4, 7) */
#define IMU_MAG_PF_LN2 0.69314718055994531
#define IMU_MAG_PF_CLIP_FACTOR 2.0    /* normalised innovations enter the change test clipped at 2 x threshold */ /* tempering target: N_eff / N >= 1/2 per update */

/** State index of B[i][j] (soft iron b11 b12 b13 b22 b23 b33 at 3..8). */
static const int ImuMagPfSoftIndex[3][3] = {{3, 4, 5}, {4, 6, 7}, {5, 7, 8}};

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

/** @brief Mode 0: particles around the prior calibration with the prior spreads, weights 1/N, estimate. */
static void ImuMagPfDrawPrior(ImuMagPf *pf)
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
        return;
    }
    ImuMagPfDrawPrior(pf);
}

/** @brief Squared norm of a 3-vector [unit^2]. */
static double ImuMagPfNormSquared(const double v[3])
{
    return v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
}

/** @brief out = (I + B)(mag - h_p) [uT] for a state x (hard [uT], soft [1]). */
static void ImuMagPfApply(const double x[IMU_MAG_PF_STATE_SIZE], const double mag[3], double out[3])
{
    const double d[3] = {mag[0] - x[0], mag[1] - x[1], mag[2] - x[2]};
    int i;
    for (i = 0; i < 3; i++) {
        out[i] = d[i] + x[ImuMagPfSoftIndex[i][0]] * d[0] + x[ImuMagPfSoftIndex[i][1]] * d[1] +
                 x[ImuMagPfSoftIndex[i][2]] * d[2];
    }
}

/** @brief h(x) = |mag|^2 - |(I + B)(mag - h_p)|^2 [uT^2] (equals the expanded form of the header). */
double ImuMagPfObservation(const double x[IMU_MAG_PF_STATE_SIZE], const double mag[3])
{
    double corrected[3];
    ImuMagPfApply(x, mag, corrected);
    return ImuMagPfNormSquared(mag) - ImuMagPfNormSquared(corrected);
}

/** @brief 1 if mag [uT] is finite and its norm within (0.001, 20) |h_0|. */
static int ImuMagPfIsValidSample(const ImuMagPf *pf, const double mag[3])
{
    const double norm = ImuAllFinite(mag, 3) ? ImuVectorNorm(mag) : -1.0;
    return norm > IMU_MAG_PF_MIN_FIELD_RATIO * pf->settings.fieldNorm &&
           norm < IMU_MAG_PF_MAX_FIELD_RATIO * pf->settings.fieldNorm;
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

/** @brief Residual e = |h_m|^2 - |h_0|^2 - h(x) - mean of the observation noise [uT^2] of a state x. */
static double ImuMagPfResidual(const ImuMagPf *pf, const double x[IMU_MAG_PF_STATE_SIZE], const double mag[3])
{
    const ImuMagPfCoefficients *c = &pf->coefficients;
    return ImuMagPfNormSquared(mag) - c->fieldNormSquared - ImuMagPfObservation(x, mag) - c->observationMean;
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
    const double clip = IMU_MAG_PF_CLIP_FACTOR * pf->settings.changeThreshold;
    return clip > 0.0 && z > clip ? clip : z;
}

int ImuMagPfOutlier(const ImuMagPf *pf, const double mag[3])
{
    const double threshold = pf->settings.changeThreshold;
    return threshold > 0.0 && pf->changeArmed && ImuMagPfInnovation(pf, mag) > IMU_MAG_PF_OUTLIER_FACTOR * threshold;
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

/** @brief Weight update w *= p(buffer | x)^alpha; stores log p(buffer | x_i); returns alpha. */
static double ImuMagPfWeigh(ImuMagPf *pf)
{
    double alpha;
    int i;
    for (i = 0; i < pf->settings.particleCount; i++) {
        pf->work.logLikelihood[i] = ImuMagPfLogLikelihood(pf, pf->particle[i]);
        pf->work.logWeight[i] = pf->work.logLikelihood[i];
    }
    alpha = ImuMagPfTemper(pf);
    for (i = 0; i < pf->settings.particleCount; i++) {
        pf->work.logWeight[i] = (pf->weight[i] > 0.0 ? log(pf->weight[i]) : -HUGE_VAL) + alpha * pf->work.logWeight[i];
    }
    ImuMagPfNormaliseLog(pf);
    return alpha;
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

void ImuMagPfTakeBackPrior(ImuMagPf *pf)
{
    const double average = pf->priorAverage;
    if (pf->settings.raoBlackwell) {
        ImuMagPfRbReset(pf);
    } else {
        ImuMagPfDrawPrior(pf);
        memset(pf->binUsed, 0, sizeof(pf->binUsed));
        pf->binCount = 0;
        pf->changeArmed = 0;
    }
    pf->innovationAverage = average;
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

double ImuMagPfEss(const ImuMagPf *pf)
{
    double sum = 0.0;
    int i;
    for (i = 0; i < pf->settings.particleCount; i++) {
        sum += pf->weight[i] * pf->weight[i];
    }
    return 1.0 / sum;
}

/** @brief Mean and standard deviation (returned) of n values read with a stride. */
double ImuMagPfMoments(const double *values, int n, int stride, double *mean)
{
    double sum = 0.0, squares = 0.0;
    int s;
    for (s = 0; s < n; s++) {
        sum += values[s * stride];
    }
    *mean = sum / n;
    for (s = 0; s < n; s++) {
        const double d = values[s * stride] - *mean;
        squares += d * d;
    }
    return sqrt(squares / n);
}

void ImuMagPfCloudSigma(const ImuMagPf *pf, double sigma[IMU_MAG_PF_STATE_SIZE])
{
    const int n = pf->settings.particleCount;
    double mean;
    int j;
    for (j = 0; j < IMU_MAG_PF_STATE_SIZE; j++) {
        sigma[j] = pf->coefficients.rougheningScale * ImuMagPfMoments(&pf->particle[0][j], n, IMU_MAG_PF_STATE_SIZE, &mean);
    }
}


/**
 * @brief Systematic resampling to equal weights, then roughening of the new cloud; with enableMove
 *        each roughened particle is a Metropolis proposal accepted with probability
 *        min(1, (p(buffer | x') / p(buffer | x))^alpha) (resample-move), else it keeps x.
 */
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

/** @brief Feed one raw field sample [uT]; 1 if the filter updated, 0 if skipped or decimated. */
int ImuMagPfUpdate(ImuMagPf *pf, const double mag[3])
{
    const double threshold = IMU_MAG_PF_RESAMPLE_FRACTION * pf->settings.particleCount;
    double alpha;
    int glitch;
    if (!ImuMagPfIsValidSample(pf, mag)) {
        return 0;
    }
    if (pf->settings.raoBlackwell) {
        return ImuMagPfRbUpdate(pf, mag);
    }
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
        ImuMagPfTakeBackPrior(pf);
        return 0;
    }
    if (!glitch) {
        ImuMagPfStore(pf, mag);
    }
    ImuMagPfPredict(pf);
    alpha = ImuMagPfWeigh(pf);
    pf->effectiveSampleSize = ImuMagPfEss(pf);
    if (pf->effectiveSampleSize < threshold && pf->settings.enableSplitting) {
        ImuMagPfSplit(pf, alpha);
        ImuMagPfNormalise(pf);
        pf->effectiveSampleSize = ImuMagPfEss(pf);
    }
    if (pf->effectiveSampleSize < threshold) {
        ImuMagPfResample(pf, alpha);
    }
    ImuMagPfEstimate(pf);
    return 1;
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

/** @brief Soft-iron estimate as a row-major symmetric 3x3 matrix B [1]. */
void ImuMagPfGetSoftIronMatrix(const ImuMagPf *pf, double matrix[9])
{
    int i, j;
    for (i = 0; i < 3; i++) {
        for (j = 0; j < 3; j++) {
            matrix[3 * i + j] = pf->estimate[ImuMagPfSoftIndex[i][j]];
        }
    }
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
