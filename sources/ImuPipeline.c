/**
 * @file ImuPipeline.c
 * @brief The per-sample processing chain: thermal compensation -> time alignment -> correction
 *        terms -> magnetometer stages -> mounting (sensor -> body axes) -> attitude fusion.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>
#include "ImuPipeline.h"
#include "ImuMath.h"
#include "ImuQuaternion.h"

/** @brief Unpack a flat coefficient array; 0, -1 on bad size/version, or -(2 + b) when block b (in
 *         IMU_COEFFICIENT_BLOCKS order: 1..3 the thermal blocks, 4 terms, 5 elm, 6 psobp) is invalid. */
int ImuCoefficientsFromArray(ImuCoefficients *c, const double *a, size_t n)
{
    int i;
    if (a == NULL || n != IMU_COEFFICIENT_COUNT || a[0] != IMU_LAYOUT_VERSION) {
        return -1;
    }
    memset(c, 0, sizeof *c); /* padding too: the struct is part of the FMU state, whose bytes are checksummed */
    for (i = 0; i < 3; i++) {
        if (ImuThermalFromBlock(&c->thermal[i], a + IMU_OFFSET_THERMAL + i * IMU_THERMAL_BLOCK) != 0) {
            return -(2 + 1 + i);
        }
    }
    if (ImuTermsFromBlock(&c->terms, a + IMU_OFFSET_TERMS) != 0) {
        return -(2 + 4);
    }
    if (ImuElmFromBlock(&c->elm, a + IMU_OFFSET_ELM) != 0) {
        return -(2 + 5);
    }
    if (ImuPsoBpFromBlock(&c->psobp, a + IMU_OFFSET_PSOBP, IMU_PSOBP_BLOCK) != 0) {
        return -(2 + 6);
    }
    return 0;
}

/** @brief A 0/1 switch from a setting value; -1 (rejected by the settings check) otherwise. */
static int ImuPipelineFlag(double value)
{
    return value == 0.0 ? 0 : (value == 1.0 ? 1 : -1);
}

/** @brief Integer value of a setting; -1 (rejected by the checks) when it is not a whole number in [0, 2^31). */
static int ImuPipelineInteger(double value)
{
    return (isfinite(value) && value == floor(value) && value >= 0.0 && value < 2147483648.0) ? (int)value : -1;
}

/** @brief Particle-filter settings: its internal defaults (ImuMagPfSettingsDefault), then the FMU
 *         parameters in their units (radians for pf_min_rotation): the one mapping from the settings
 *         array to the filter, which the batch library reaches through ImuRuntimeSettings. */
static void ImuPipelinePfSettings(ImuMagPfSettings *pf, const double *a)
{
    ImuMagPfSettingsDefault(pf, ImuPipelineFlag(a[ImuSetPfAdditions]));
    pf->fieldNorm = a[ImuSetFieldNorm];
    pf->particleCount = ImuPipelineInteger(a[ImuSetPfParticles]);
    pf->measurementNoise = a[ImuSetPfMeasurementNoise];
    pf->processNoiseHard = a[ImuSetPfProcessNoiseHard];
    pf->processNoiseSoft = a[ImuSetPfProcessNoiseSoft];
    pf->priorSpreadHard = a[ImuSetPfPriorSpreadHard];
    pf->priorSpreadSoft = a[ImuSetPfPriorSpreadSoft];
    pf->decimation = ImuPipelineInteger(a[ImuSetPfDecimation]);
    pf->seed = ImuPipelineInteger(a[ImuSetPfSeed]) < 0 ? 0U : (uint64_t)ImuPipelineInteger(a[ImuSetPfSeed]);
    pf->highThreshold = a[ImuSetPfThresholdHigh];
    pf->lowThreshold = a[ImuSetPfThresholdLow];
    pf->sphereBins = ImuPipelineInteger(a[ImuSetPfSphereBins]);
    pf->raoBlackwell = ImuPipelineFlag(a[ImuSetPfRaoBlackwell]);
    pf->minRotation = a[ImuSetPfMinRotation];
    pf->changeSpreadHard = a[ImuSetPfChangeSpreadHard];
    pf->holdPrior = ImuPipelineFlag(a[ImuSetPfHoldPrior]);
    pf->settleSpread = a[ImuSetPfSettleSpread];
}

/** @brief Unpack a flat settings array (enable_thermal other than 0/1 becomes -1); 0 or -1 on bad size. */
int ImuPipelineSettingsFromArray(ImuPipelineSettings *s, const double *a, size_t n)
{
    if (a == NULL || n != IMU_SETTING_COUNT) {
        return -1;
    }
    memset(s, 0, sizeof *s); /* padding too: the struct is part of the FMU state, whose bytes are checksummed */
    memcpy(s->values, a, sizeof s->values);
    s->declination = a[ImuSetDeclination];
    s->fieldNorm = a[ImuSetFieldNorm];
    s->gyroNoise = a[ImuSetGyroNoise];
    s->gyroBiasResidual = a[ImuSetGyroBiasResidual];
    s->mseTimeConstant = a[ImuSetMseTimeConstant];
    s->angleNoise = a[ImuSetAngleNoise];
    s->enableThermal = ImuPipelineFlag(a[ImuSetEnableThermal]);
    s->attitudeMode = ImuPipelineFlag(a[ImuSetAttitudeMode]);
    s->fieldDip = a[ImuSetFieldDip];
    s->tauAcc = a[ImuSetTauAcc];
    s->tauMag = a[ImuSetTauMag];
    s->restGyroThreshold = a[ImuSetRestGyroThreshold];
    s->restAccThreshold = a[ImuSetRestAccThreshold];
    s->magRejectTime = a[ImuSetMagRejectTime];
    s->gyroHold = ImuPipelineFlag(a[ImuSetGyroHold]);
    s->magHeading = ImuPipelineFlag(a[ImuSetMagHeading]);
    s->motionBias = ImuPipelineFlag(a[ImuSetMotionBias]);
    s->accNormTolerance = a[ImuSetAccNormTolerance];
    s->enableElm = ImuPipelineFlag(a[ImuSetEnableElm]);
    s->enablePf = ImuPipelineFlag(a[ImuSetEnablePf]);
    s->pfSeed = ImuPipelineInteger(a[ImuSetPfSeed]);
    s->enablePsoBp = ImuPipelineFlag(a[ImuSetEnablePsobp]);
    s->psobpClamp = ImuPipelineFlag(a[ImuSetPsobpClamp]);
    s->thermalContinuation = ImuPipelineFlag(a[ImuSetThermalContinuation]);
    s->learning.enabled = ImuPipelineFlag(a[ImuSetBiasLearning]);
    s->learning.rate = a[ImuSetBiasLearningRate];
    s->learning.limit = a[ImuSetBiasLearningLimit];
    s->learning.gyroThreshold = a[ImuSetRestGyroThreshold];
    s->learning.accThreshold = a[ImuSetRestAccThreshold];
    s->eulerAdditions = ImuPipelineInteger(a[ImuSetEulerAdditions]);
    s->align.lag[0] = a[ImuSetLagGyr];
    s->align.lag[1] = a[ImuSetLagAcc];
    s->align.lag[2] = a[ImuSetLagMag];
    s->mountValid = ImuMountFromCodes(&s->mount, &a[ImuSetMountX]) == 0;
    if (!s->mountValid) {
        ImuMountIdentity(&s->mount);
    }
    ImuPipelinePfSettings(&s->pf, a);
    return 0;
}

/** @brief 1 if value [the setting's unit] lies in the declared range r (NaN never does), else 0. */
static int ImuPipelineInRange(double value, const ImuSettingRange *r)
{
    const int aboveMin = (r->flags & IMU_RANGE_MIN_OPEN) ? value > r->min : value >= r->min;
    const int belowMax = (r->flags & IMU_RANGE_MAX_OPEN) ? value < r->max : value <= r->max;
    return aboveMin && belowMax && (!(r->flags & IMU_RANGE_WHOLE) || value == floor(value))
           && (!(r->flags & IMU_RANGE_NONZERO) || value != 0.0);
}

/** @brief The message of the first setting outside its declared range (ImuLayout.h
 *         IMU_SETTING_RANGES, generated from the variable table), or NULL. */
static const char *ImuPipelineCheckRanges(const double values[IMU_SETTING_COUNT])
{
    static const ImuSettingRange ranges[IMU_SETTING_COUNT] = IMU_SETTING_RANGES;
    int i;
    for (i = 0; i < IMU_SETTING_COUNT; i++) {
        if (!ImuPipelineInRange(values[i], &ranges[i])) {
            return ranges[i].problem;
        }
    }
    return NULL;
}

/** @brief Check settings; -1 with *message naming the setting and its range, else 0. */
int ImuPipelineSettingsCheck(const ImuPipelineSettings *s, const char **message)
{
    const char *problem = ImuPipelineCheckRanges(s->values);
    if (problem != NULL) {
        /* problem names the setting and its declared range */
    } else if (ImuMagPfSettingsCheck(&s->pf, &problem) != 0) {
        /* problem names the particle-filter settings that are only valid together */
    } else if (!s->mountValid) {
        problem = "mount_x, mount_y, mount_z must each name a sensor axis with its sign (1 = +x, 2 = +y, "
                  "3 = +z, -1 = -x, -2 = -y, -3 = -z), three different axes that stay right-handed";
    }
    if (message != NULL) {
        *message = problem;
    }
    return problem == NULL ? 0 : -1;
}

/** @brief The attitude filter's settings from the pipeline settings. */
static void ImuPipelineAttitudeSettings(const ImuPipelineSettings *s, ImuAttitudeSettings *a)
{
    memset(a, 0, sizeof *a); /* padding too: the FMU state's bytes are checksummed */
    a->gyroNoise = s->gyroNoise;
    a->gyroBiasResidual = s->gyroBiasResidual;
    a->mseTimeConstant = s->mseTimeConstant;
    a->angleNoise = s->angleNoise;
    a->fieldNorm = s->fieldNorm;
    a->mode = s->attitudeMode;
    a->fieldDip = s->fieldDip;
    a->tauAcc = s->tauAcc;
    a->tauMag = s->tauMag;
    a->restGyroThreshold = s->restGyroThreshold;
    a->restAccThreshold = s->restAccThreshold;
    a->magRejectTime = s->magRejectTime;
    a->gyroHold = s->gyroHold;
    a->magHeading = s->magHeading;
    a->motionBias = s->motionBias;
    a->accNormTolerance = s->accNormTolerance;
    a->eulerAdditions = s->eulerAdditions; /* checked against its declared range (0..all bits) */
}

void ImuPipelineConfigure(ImuPipeline *p, const ImuPipelineSettings *s, const ImuCoefficients *c)
{
    p->settings = *s;
    p->coefficients = *c;
    ImuPipelineAttitudeSettings(s, &p->attitude.settings);
    if (s->enablePf) {
        (void)ImuMagPfConfigure(&p->pf, &s->pf); /* checked by ImuPipelineSettingsCheck */
    }
    p->psobp.tau = c->psobp.tau;
}

/** @brief Set settings and coefficients and reset the state. */
void ImuPipelineInitialise(ImuPipeline *p, const ImuPipelineSettings *s, const ImuCoefficients *c)
{
    if (s->enablePf) {
        memset(&p->pf, 0, sizeof p->pf); /* as ImuMagPfInitialise: no stale particle survives */
    }
    ImuPipelineConfigure(p, s, c);
    ImuPipelineReset(p);
}

/** @brief Return to the state right after ImuPipelineInitialise. */
void ImuPipelineReset(ImuPipeline *p)
{
    ImuAttitudeReset(&p->attitude);
    ImuAlignReset(&p->align);
    ImuTermsReset(&p->terms);
    ImuPsoBpInitialise(&p->psobp, &p->coefficients.psobp);
    ImuBiasLearningReset(&p->learning, &p->settings.learning);
    if (p->settings.enablePf) {
        ImuMagPfReset(&p->pf);
    }
    p->rangeIssues = 0;
}

const char *ImuPipelineStateProblem(const ImuPipeline *p, double clock)
{
    if (!ImuAlignStateValid(&p->align, clock)) {
        return "the time-alignment buffer's count or head is outside 0..63, or its times are not finite and "
               "increasing up to the newest, which must equal the guard's clock";
    }
    if (!ImuAttitudeStateValid(&p->attitude)) {
        return "the attitude filter's flags, nominal step, low-pass counts or motion-bias covariance are invalid";
    }
    if (!ImuTermsStateValid(&p->terms, clock)) {
        return "the correction terms' times are not finite, ordered and no later than the guard's clock";
    }
    if (!ImuPsoBpStateValid(&p->psobp, clock)) {
        return "the PSO-BP stage's time is not finite and no later than the guard's clock";
    }
    if (p->settings.enablePf && !ImuMagPfStateValid(&p->pf)) {
        return "the particle filter's bin list, bin count or sample counter does not fit its settings";
    }
    if (!ImuBiasLearningStateValid(&p->learning, &p->settings.learning)) {
        return "the learnt gyro bias exceeds bias_learning_limit, or its steps, sums or rest counters are out of range";
    }
    return NULL;
}

/** @brief A gap [s]: restart the attitude corrections, empty the time-alignment buffer and restart the rest
 *         detection of the bias learning (what it learnt is kept). */
void ImuPipelineGap(ImuPipeline *p, double gap)
{
    ImuAttitudeRestart(&p->attitude, gap);
    ImuAlignReset(&p->align);
    ImuBiasLearningRestart(&p->learning);
}

/** @brief Normalised temperature [1] of the gyro gain/bias model the learnt bias is a polynomial in (0 when
 *         the model is off). */
static double ImuPipelineLearningTemperature(const ImuPipeline *p, double temperature)
{
    const ImuThermalCoefficients *gyro = &p->coefficients.thermal[0];
    return p->settings.enableThermal && gyro->enabled ? ImuThermalNormalisedTemperature(gyro, temperature) : 0.0;
}

/** @brief Gain/bias temperature compensation of the three raw triads into out[rate..field];
 *         returns the ImuRangeThermal* bits of the triads whose temperature was outside their range. */
static int ImuPipelineThermal(const ImuPipeline *p, const double in[IMU_INPUT_COUNT], double temperature,
                              double out[IMU_OUTPUT_COUNT])
{
    int i, issues = 0;
    for (i = 0; i < 3; i++) {
        const double *raw = &in[ImuInGyrX + 3 * i];
        double *corrected = &out[ImuOutRateX + 3 * i];
        if (p->settings.enableThermal) {
            if (!ImuThermalApply(&p->coefficients.thermal[i], raw, temperature, p->settings.thermalContinuation,
                                 corrected)) {
                issues |= ImuRangeThermalGyr << i;
            }
        } else {
            corrected[0] = raw[0];
            corrected[1] = raw[1];
            corrected[2] = raw[2];
        }
    }
    return issues;
}

/** @brief Subtract the diagnosed correction terms from the compensated triads out[rate..field];
 *         aux are the sample's auxiliary inputs. Returns ImuRangeTerms if a regressor was clamped, else 0.
 *         A model without terms computes no signals (3 % of the default chain's time). */
static int ImuPipelineTerms(ImuPipeline *p, double t, double temperature, const double aux[IMU_TERMS_AUX_COUNT],
                            double out[IMU_OUTPUT_COUNT])
{
    double signals[IMU_TERM_SIGNAL_COUNT];
    if (p->coefficients.terms.count == 0) {
        return 0;
    }
    ImuTermsSignals(&p->terms, t, &out[ImuOutRateX], temperature, aux, signals);
    return ImuTermsApply(&p->coefficients.terms, signals, &out[ImuOutRateX]) ? 0 : ImuRangeTerms;
}

/** @brief Online hard/soft-iron filter on the compensated field out[field] and its diagnostic outputs. */
static void ImuPipelineMagPf(ImuPipeline *p, double out[IMU_OUTPUT_COUNT])
{
    double soft[6];
    int i;
    if (!p->settings.enablePf) {
        for (i = ImuOutHardIronX; i <= ImuOutPfNeff; i++) {
            out[i] = 0.0;
        }
        return;
    }
    ImuMagPfUpdate(&p->pf, &out[ImuOutFieldX]);
    ImuMagPfCompensate(&p->pf, &out[ImuOutFieldX], &out[ImuOutFieldX]);
    ImuMagPfGetHardIron(&p->pf, &out[ImuOutHardIronX]);
    ImuMagPfGetSoftIron(&p->pf, soft);
    out[ImuOutSoftIronXx] = soft[0];
    out[ImuOutSoftIronYy] = soft[3];
    out[ImuOutSoftIronZz] = soft[5];
    out[ImuOutPfNeff] = ImuMagPfGetEffectiveSampleSize(&p->pf);
}

/** @brief Turn the calibrated triads and the particle filter's estimates in out[] from sensor into body axes. */
static void ImuPipelineMount(const ImuMount *m, double out[IMU_OUTPUT_COUNT])
{
    ImuMountVector(m, &out[ImuOutRateX]);
    ImuMountVector(m, &out[ImuOutAccelX]);
    ImuMountVector(m, &out[ImuOutFieldX]);
    ImuMountVector(m, &out[ImuOutHardIronX]);
    ImuMountDiagonal(m, &out[ImuOutSoftIronXx]);
}

/** @brief out[q_sensor] = out[q] * q(sensor -> body): the attitude of the sensor axes (sensor -> NED). */
static void ImuPipelineSensorAttitude(const ImuMount *m, double out[IMU_OUTPUT_COUNT])
{
    double turn[4];
    ImuMountQuaternion(m, turn);
    ImuQuaternionMultiply(&out[ImuOutQW], turn, &out[ImuOutQSensorW]);
}

/** @brief The field the attitude filter may use: out[field], or NaN while the particle filter has not
 *         settled after a change (its estimate is still wide). */
static const double *ImuPipelineHeadingField(const ImuPipeline *p, const double out[IMU_OUTPUT_COUNT])
{
    static const double unsettled[3] = {NAN, NAN, NAN};
    return p->settings.enablePf && !ImuMagPfSettled(&p->pf) ? unsettled : &out[ImuOutFieldX];
}

/** @brief Process one sample at time t [s] since the first, dt [s] after the previous one: raw inputs
 *         in (ImuLayout.h units) -> outputs out. */
void ImuPipelineUpdate(ImuPipeline *p, double t, double dt, double nominalStep, const double in[IMU_INPUT_COUNT],
                       double out[IMU_OUTPUT_COUNT])
{
    const double temperature = in[ImuInTemp];
    double tn;
    p->rangeIssues = ImuPipelineThermal(p, in, temperature, out);
    ImuPsoBpUpdate(&p->psobp, t, temperature);
    if (p->settings.enablePsoBp && !ImuPsoBpCorrect(&p->coefficients.psobp, &p->psobp, p->settings.psobpClamp, &out[ImuOutRateX])) {
        p->rangeIssues |= ImuRangePsoBp;
    }
    tn = ImuPipelineLearningTemperature(p, temperature);
    ImuBiasLearningCorrect(&p->learning, &p->settings.learning, tn, &out[ImuOutRateX]);
    ImuBiasLearningUpdate(&p->learning, &p->settings.learning, temperature, tn, &out[ImuOutRateX],
                          &out[ImuOutAccelX], dt);
    out[ImuOutBiasLearningShift] = p->settings.learning.enabled ? ImuBiasLearningShift(&p->learning, tn) : 0.0;
    if (ImuAlignUpdate(&p->align, &p->settings.align, t, &out[ImuOutRateX])) {
        p->rangeIssues |= ImuRangeLag;
    }
    p->rangeIssues |= ImuPipelineTerms(p, t, temperature, &in[ImuInAux1], out);
    ImuPipelineMagPf(p, out);
    if (p->settings.enableElm && !ImuElmApply(&p->coefficients.elm, &out[ImuOutFieldX], &out[ImuOutFieldX])) {
        p->rangeIssues |= ImuRangeElm;
    }
    out[ImuOutCalibrationValid] = p->rangeIssues == 0 ? 1.0 : 0.0;
    ImuPipelineMount(&p->settings.mount, out);
    ImuAttitudeUpdate(&p->attitude, &out[ImuOutRateX], &out[ImuOutAccelX], ImuPipelineHeadingField(p, out), dt,
                      nominalStep);
    ImuAttitudeGetEuler(&p->attitude, &out[ImuOutRoll]);
    out[ImuOutHeading] = ImuWrapAngle(out[ImuOutYaw] + p->settings.declination);
    ImuAttitudeGetQuaternion(&p->attitude, &out[ImuOutQW]);
    ImuPipelineSensorAttitude(&p->settings.mount, out);
    ImuAttitudeGetGains(&p->attitude, &out[ImuOutGainRoll]);
    out[ImuOutMagDisturbed] = ImuAttitudeMagDisturbed(&p->attitude) ? 1.0 : 0.0;
}

/** @brief The end of the NUL-terminated text in a buffer of size bytes; *left = bytes from there on (>= 1). */
static char *ImuPipelineTail(char *text, size_t size, size_t *left)
{
    const size_t used = strlen(text);
    *left = size - used;
    return text + used;
}

void ImuPipelineDescribeRanges(const ImuPipeline *p, int issues, char *text, size_t size)
{
    static const char *const triads[3] = {"gyroscope", "accelerometer", "magnetometer"};
    const ImuCoefficients *c = &p->coefficients;
    size_t left;
    char *tail;
    int i;
    if (size == 0) {
        return;
    }
    text[0] = '\0';
    for (i = 0; i < 3; i++) {
        if (issues & (ImuRangeThermalGyr << i)) {
            tail = ImuPipelineTail(text, size, &left);
            snprintf(tail, left, "%s gain/bias model (temperature [%g, %g] degC); ", triads[i], c->thermal[i].tMin,
                     c->thermal[i].tMax);
        }
    }
    if (issues & ImuRangePsoBp) {
        tail = ImuPipelineTail(text, size, &left);
        snprintf(tail, left, "PSO-BP network (temperature [%g, %g] degC, rate [%g, %g] degC/s); ", c->psobp.tMin,
                 c->psobp.tMax, c->psobp.rMin, c->psobp.rMax);
    }
    if (issues & ImuRangeTerms) {
        tail = ImuPipelineTail(text, size, &left);
        snprintf(tail, left, "%s", "correction terms (a regressor outside its fitted [lo, hi]); ");
    }
    if (issues & ImuRangeElm) {
        tail = ImuPipelineTail(text, size, &left);
        snprintf(tail, left, "ELM field model (field outside its box x [%g, %g], y [%g, %g], z [%g, %g] uT); ",
                 c->elm.inMin[0], c->elm.inMax[0], c->elm.inMin[1], c->elm.inMax[1], c->elm.inMin[2], c->elm.inMax[2]);
    }
    if (issues & ImuRangeLag) {
        tail = ImuPipelineTail(text, size, &left);
        snprintf(tail, left, "time alignment (lag_gyr %g, lag_acc %g, lag_mag %g s: one reaches beyond the %d buffered "
                 "samples, and the oldest is used); ", p->settings.align.lag[0], p->settings.align.lag[1],
                 p->settings.align.lag[2], IMU_ALIGN_CAPACITY);
    }
    if (strlen(text) >= 2 && text[strlen(text) - 2] == ';') {
        text[strlen(text) - 2] = '\0';
    }
}
