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
#include <stddef.h>
#include <string.h>
#include "ImuMagPfPrivate.h"
#include "ImuMath.h"

#define IMU_MAG_PF_TEXT(x) #x
#define IMU_MAG_PF_STRING(x) IMU_MAG_PF_TEXT(x)
#define IMU_MAG_PF_RNG_STREAM 54U    /* PCG32 stream selector of the filter */
#define IMU_MAG_PF_MAX_FIELD_RATIO 20.0   /* samples above 20 |h_0| are absurd (saturation, glitch) */
#define IMU_MAG_PF_MIN_FIELD_RATIO 1e-3   /* samples below 0.001 |h_0| are dropouts */

/** @brief One internal setting: its snake_case name (the batch library's and Python's), unit,
 *         place in ImuMagPfSettings, kind, default and value in the method as its source describes it. */
typedef struct {
    const char *name;
    const char *unit;
    size_t offset;   /* bytes into ImuMagPfSettings */
    int integer;     /* 1: an int field, 0: a double field */
    double value;    /* default [unit] */
    double source;   /* [unit] with pf_additions = 0: the default, or the value that switches a project
                      * addition off (training.models.magpf.ADDITIONS; a test pins the two) */
} ImuMagPfInternalSetting;

#define IMU_MAG_PF_FIELD(field) offsetof(ImuMagPfSettings, field)
#define IMU_MAG_PF_ELEMENT(field, k) (offsetof(ImuMagPfSettings, field) + (k) * sizeof(double))

/** The settings the FMU does not expose, with their defaults (docs/magpf.md: prior = a trained
 *  calibration, so zero prior hard and soft iron around the calibrated field): the one list of
 *  them, in the order of the batch library's second settings array. */
static const ImuMagPfInternalSetting ImuMagPfInternal[IMU_MAG_PF_INTERNAL_COUNT] = {
    {"prior_hard_iron_x", "uT", IMU_MAG_PF_ELEMENT(priorHardIron, 0), 0, 0.0, 0.0},
    {"prior_hard_iron_y", "uT", IMU_MAG_PF_ELEMENT(priorHardIron, 1), 0, 0.0, 0.0},
    {"prior_hard_iron_z", "uT", IMU_MAG_PF_ELEMENT(priorHardIron, 2), 0, 0.0, 0.0},
    {"prior_soft_iron_xx", "1", IMU_MAG_PF_ELEMENT(priorSoftIron, 0), 0, 0.0, 0.0},
    {"prior_soft_iron_xy", "1", IMU_MAG_PF_ELEMENT(priorSoftIron, 1), 0, 0.0, 0.0},
    {"prior_soft_iron_xz", "1", IMU_MAG_PF_ELEMENT(priorSoftIron, 2), 0, 0.0, 0.0},
    {"prior_soft_iron_yy", "1", IMU_MAG_PF_ELEMENT(priorSoftIron, 3), 0, 0.0, 0.0},
    {"prior_soft_iron_yz", "1", IMU_MAG_PF_ELEMENT(priorSoftIron, 4), 0, 0.0, 0.0},
    {"prior_soft_iron_zz", "1", IMU_MAG_PF_ELEMENT(priorSoftIron, 5), 0, 0.0, 0.0},
    {"roughening", "1", IMU_MAG_PF_FIELD(roughening), 0, 0.2, 0.2},
    {"innovation_time_constant", "updates", IMU_MAG_PF_FIELD(innovationTimeConstant), 0, 5.0, 0.0},
    {"max_inflation", "1", IMU_MAG_PF_FIELD(maxInflation), 0, 20.0, 1.0},
    {"hidden_units", "1", IMU_MAG_PF_FIELD(hiddenUnits), 1, 5.0, 5.0},
    {"training_epochs", "1", IMU_MAG_PF_FIELD(trainingEpochs), 1, 20.0, 20.0},
    {"learning_rate", "1", IMU_MAG_PF_FIELD(learningRate), 0, 0.1, 0.1},
    {"max_tries", "1", IMU_MAG_PF_FIELD(maxTries), 1, 3.0, 3.0},
    {"enable_splitting", "0/1", IMU_MAG_PF_FIELD(enableSplitting), 1, 1.0, 1.0},
    {"change_threshold", "1", IMU_MAG_PF_FIELD(changeThreshold), 0, 25.0, 0.0},
    {"change_spread_soft", "1", IMU_MAG_PF_FIELD(changeSpreadSoft), 0, 0.01, 0.01},
    {"enable_move", "0/1", IMU_MAG_PF_FIELD(enableMove), 1, 1.0, 0.0},
    {"norm_time_constant", "updates", IMU_MAG_PF_FIELD(normTimeConstant), 0, 300.0, 0.0},
    {"enable_tempering", "0/1", IMU_MAG_PF_FIELD(enableTempering), 1, 1.0, 0.0},
    {"resample_roughening", "0/1", IMU_MAG_PF_FIELD(resampleRoughening), 1, 1.0, 0.0},
    {"glitch_clipping", "0/1", IMU_MAG_PF_FIELD(glitchClipping), 1, 1.0, 0.0},
    {"update_growth", "1", IMU_MAG_PF_FIELD(updateGrowth), 0, 0.05, 0.05},
    {"update_innovation", "1", IMU_MAG_PF_FIELD(updateInnovation), 0, 2.0, 2.0},
};

int ImuMagPfInternalInfo(size_t index, const char **name, const char **unit, double *value, double *source)
{
    if (index >= IMU_MAG_PF_INTERNAL_COUNT) {
        return -1;
    }
    *name = ImuMagPfInternal[index].name;
    *unit = ImuMagPfInternal[index].unit;
    *value = ImuMagPfInternal[index].value;
    *source = ImuMagPfInternal[index].source;
    return 0;
}

void ImuMagPfSetInternal(ImuMagPfSettings *settings, size_t index, double value)
{
    const ImuMagPfInternalSetting *e = &ImuMagPfInternal[index];
    char *field = (char *)settings + e->offset;
    if (e->integer) {
        /* a whole number in [0, 2^31), else -1, which every integer setting's check rejects */
        const int n = (isfinite(value) && value == floor(value) && value >= 0.0 && value < 2147483648.0)
                          ? (int)value : -1;
        memcpy(field, &n, sizeof n);
    } else {
        memcpy(field, &value, sizeof value);
    }
}

void ImuMagPfSettingsDefault(ImuMagPfSettings *settings, int additions)
{
    size_t i;
    memset(settings, 0, sizeof *settings);
    for (i = 0; i < IMU_MAG_PF_INTERNAL_COUNT; i++) {
        ImuMagPfSetInternal(settings, i, additions ? ImuMagPfInternal[i].value : ImuMagPfInternal[i].source);
    }
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
        return "hidden_units (hiddenUnits) must be in 1.." IMU_MAG_PF_STRING(IMU_MAG_PF_MAX_HIDDEN);
    }
    if (s->trainingEpochs < 1 || s->trainingEpochs > 200) {
        return "training_epochs (trainingEpochs) must be in 1..200";
    }
    if (s->maxTries < 1 || s->maxTries > 20) {
        return "max_tries (maxTries) must be in 1..20";
    }
    if (s->enableSplitting != 0 && s->enableSplitting != 1) {
        return "enable_splitting (enableSplitting) must be 0 or 1";
    }
    if (s->enableMove != 0 && s->enableMove != 1) {
        return "enable_move (enableMove) must be 0 or 1";
    }
    if (s->enableTempering != 0 && s->enableTempering != 1) {
        return "enable_tempering (enableTempering) must be 0 or 1";
    }
    if (s->resampleRoughening != 0 && s->resampleRoughening != 1) {
        return "resample_roughening (resampleRoughening) must be 0 or 1";
    }
    if (s->glitchClipping != 0 && s->glitchClipping != 1) {
        return "glitch_clipping (glitchClipping) must be 0 or 1";
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
        return "prior_hard_iron_* and prior_soft_iron_* (priorHardIron, priorSoftIron) must be finite";
    }
    if (!(s->roughening >= 0.0 && s->roughening <= 10.0)) {
        return "roughening must be in [0, 10]";
    }
    if (!(s->innovationTimeConstant >= 0.0 && s->innovationTimeConstant <= 1e6)) {
        return "innovation_time_constant (innovationTimeConstant) must be in [0, 1e6] updates (0: off)";
    }
    if (!(s->maxInflation >= 1.0 && s->maxInflation <= 1e3)) {
        return "max_inflation (maxInflation) must be in [1, 1000]";
    }
    if (!(s->minRotation >= 0.0 && s->minRotation <= 0.5 * IMU_PI)) {
        return "pf_min_rotation (minRotation) must be in [0, pi/2] rad";
    }
    if (!(s->learningRate > 0.0 && s->learningRate <= 10.0)) {
        return "learning_rate (learningRate) must be in (0, 10]";
    }
    if (!(s->changeThreshold == 0.0 || (s->changeThreshold >= 2.0 && s->changeThreshold <= 1e6))) {
        return "change_threshold (changeThreshold) must be 0 (off) or in [2, 1e6]";
    }
    if (!(s->changeSpreadHard >= 0.0 && s->changeSpreadHard <= 1e4)) {
        return "pf_change_spread_hard (changeSpreadHard) must be in [0, 1e4] uT";
    }
    if (!(s->changeSpreadSoft >= 0.0 && s->changeSpreadSoft <= 1.0)) {
        return "change_spread_soft (changeSpreadSoft) must be in [0, 1]";
    }
    if (!(s->settleSpread >= 0.0 && s->settleSpread <= 1e4)) {
        return "pf_settle_spread (settleSpread) must be in [0, 1e4] uT (0: always settled)";
    }
    if (!(s->normTimeConstant >= 0.0 && s->normTimeConstant <= 1e6)) {
        return "norm_time_constant (normTimeConstant) must be in [0, 1e6] updates (0: off)";
    }
    if (!(s->updateGrowth >= 0.0 && s->updateGrowth <= 10.0)) {
        return "update_growth (updateGrowth) must be in [0, 10] (0: an update whenever a sample was added)";
    }
    if (!(s->updateInnovation >= 1.0 && s->updateInnovation <= 1e6)) {
        return "update_innovation (updateInnovation) must be in [1, 1e6]";
    }
    if (!(s->fieldNorm > 0.0 && s->fieldNorm <= 1e4)) {
        return "field_norm (fieldNorm) must be in (0, 1e4] uT";
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
    c->minRotationCosine = cos(s->minRotation);
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
