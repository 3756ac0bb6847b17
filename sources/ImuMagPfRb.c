/**
 * @file ImuMagPfRb.c
 * @brief Rao-Blackwellised mode of the magnetometer particle filter (raoBlackwell = 1, docs/magpf.md).
 *
 * The particles carry the hard iron h_p only; the soft iron is integrated out exactly given h_p
 * (ImuMagMoments.h) from the power sums of every valid sample since the reset or the last change.
 * Each filter update moves the weighted cloud from the target of the previous update,
 * pi_old(h_p) = p(old samples | h_p) p(h_p), to the new one, pi_new, through bridging targets
 * pi_old^(1 - g) pi_new^g: g grows as far as N_eff >= N/2 allows (bisection), the weights take the
 * increment, N_eff < 2N/3 triggers systematic resampling and Metropolis moves (random walk with
 * the weighted cloud covariance x 2.38^2/3) that leave pi_g invariant; at most
 * IMU_MAG_PF_BRIDGE_STEPS steps per update, the last one with g = 1 (adaptive tempering of a
 * resample-move sequential Monte Carlo sampler); an update that did not resample makes one
 * Metropolis sweep with pi_new. The cloud moves only when the sums gained information
 * (ImuMagPfRbInformative: updateGrowth, updateInnovation); the change test runs every update.
 * A change of environment restarts the sums with a hard-iron prior around the estimate
 * (changeSpreadHard) and a soft-iron prior at the estimate
 * (changeSpreadSoft), as does an update in which no particle keeps an admissible soft iron (around
 * the prior calibration if none around the estimate does). After a change the prior calibration is
 * re-tested against the data and taken back once it explains them as well as the estimate
 * (ImuMagPfPriorExplains).
 */
#include <math.h>
#include <string.h>
#include "ImuMagPfPrivate.h"

#define IMU_MAG_PF_BRIDGE_STEPS 8       /* bridging steps per update, the last with g = 1 */
#define IMU_MAG_PF_BISECTIONS 40        /* bisection steps of the next bridging exponent */
#define IMU_MAG_PF_MIN_BRIDGE_STEP 1e-6 /* smallest increase of g per step */
#define IMU_MAG_PF_MOVE_SWEEPS 2        /* Metropolis sweeps after each resampling */
#define IMU_MAG_PF_IDLE_SWEEPS 1        /* Metropolis sweeps of an update that did not resample */
#define IMU_MAG_PF_MOVE_SCALE (2.38 * 2.38 / 3.0) /* random-walk scale for 3 dimensions (Gelman et al. 1996) */
#define IMU_MAG_PF_MOVE_FLOOR 1e-10     /* uT^2 added to the proposal covariance diagonal */
#define IMU_MAG_PF_MAX_SOFT 0.3         /* admissible |eigenvalue of B| */
#define IMU_MAG_PF_MIN_SOFT_SPREAD 1e-4 /* smallest prior sigma of the entries of M */

/** @brief Priors of a segment: hard iron around centre [uT], soft iron M around softMean. */
static void ImuMagPfRbSetPrior(ImuMagPf *pf, const double centre[3], double spread,
                               const double softMean[IMU_MAG_SOFT_COUNT], double softSpread)
{
    const ImuMagPfCoefficients *c = &pf->coefficients;
    ImuMagMarginalPrior *prior = &pf->rb.prior;
    int j;
    for (j = 0; j < 3; j++) {
        prior->hardCentre[j] = centre[j] - pf->settings.priorHardIron[j];
    }
    prior->hardSpread = spread;
    memcpy(prior->softMean, softMean, sizeof(prior->softMean));
    prior->softSpread = softSpread > IMU_MAG_PF_MIN_SOFT_SPREAD ? softSpread : IMU_MAG_PF_MIN_SOFT_SPREAD;
    prior->offset = c->fieldNormSquared + c->observationMean;
    prior->variance = 0.5 / c->halfInverseVariance;
    prior->minEigen = (1.0 - IMU_MAG_PF_MAX_SOFT) * (1.0 - IMU_MAG_PF_MAX_SOFT);
    prior->maxEigen = (1.0 + IMU_MAG_PF_MAX_SOFT) * (1.0 + IMU_MAG_PF_MAX_SOFT);
}

/** @brief Log target of a hard iron [uT] under the power sums; soft receives M's posterior mean. */
static double ImuMagPfRbEvaluate(const ImuMagPf *pf, const double sums[IMU_MAG_MOMENT_COUNT], const double hard[3],
                                 double soft[IMU_MAG_SOFT_COUNT])
{
    const double p[3] = {hard[0] - pf->settings.priorHardIron[0], hard[1] - pf->settings.priorHardIron[1],
                         hard[2] - pf->settings.priorHardIron[2]};
    double logTarget;
    (void)ImuMagMarginal(sums, p, &pf->rb.prior, &logTarget, soft);
    return logTarget;
}

/** @brief Particles around centre [uT] with sigma spread, weights 1/N, targets under previousMoments. */
static void ImuMagPfRbDraw(ImuMagPf *pf, const double centre[3], double spread)
{
    const int n = pf->settings.particleCount;
    int i, j;
    for (i = 0; i < n; i++) {
        for (j = 0; j < 3; j++) {
            pf->particle[i][j] = centre[j] + spread * ImuRngNormal(&pf->rng);
        }
        pf->rb.previousLog[i] = ImuMagPfRbEvaluate(pf, pf->rb.previousMoments, pf->particle[i], pf->particle[i] + 3);
        pf->weight[i] = 1.0 / n;
    }
}

/** @brief Weighted mean hard iron and B = sqrt(I + mean M) - I into pf->estimate. */
static void ImuMagPfRbEstimate(ImuMagPf *pf)
{
    double m[IMU_MAG_SOFT_COUNT] = {0.0};
    int i, j;
    for (j = 0; j < 3; j++) {
        pf->estimate[j] = 0.0;
    }
    for (i = 0; i < pf->settings.particleCount; i++) {
        for (j = 0; j < 3; j++) {
            pf->estimate[j] += pf->weight[i] * pf->particle[i][j];
        }
        for (j = 0; j < IMU_MAG_SOFT_COUNT; j++) {
            m[j] += pf->weight[i] * pf->particle[i][3 + j];
        }
    }
    ImuMagSoftFromQuadratic(m, pf->estimate + 3);
    ImuMagPfHardSpread(pf);
}

void ImuMagPfRbReset(ImuMagPf *pf)
{
    const ImuMagPfSettings *s = &pf->settings;
    double softMean[IMU_MAG_SOFT_COUNT];
    memset(pf->rb.moments, 0, sizeof(pf->rb.moments));
    memset(pf->rb.previousMoments, 0, sizeof(pf->rb.previousMoments));
    ImuMagQuadraticFromSoft(s->priorSoftIron, softMean);
    ImuMagPfRbSetPrior(pf, s->priorHardIron, s->priorSpreadHard, softMean, 2.0 * s->priorSpreadSoft);
    ImuMagPfRbDraw(pf, s->priorHardIron, s->priorSpreadHard);
    ImuMagPfRbEstimate(pf);
    pf->frozen = s->holdPrior;
    pf->changeArmed = pf->frozen; /* the held calibration is the baseline: a prior the data contradict is a change */
    if (pf->frozen) { /* the held calibration is the prior itself, not the mean of its draw */
        memcpy(pf->estimate, s->priorHardIron, sizeof(s->priorHardIron));
        memcpy(pf->estimate + 3, s->priorSoftIron, sizeof(s->priorSoftIron));
    }
}

/** @brief Take the prior calibration back: restart from it (held again with holdPrior), the
 *         change test restarted. */
static void ImuMagPfRbTakeBackPrior(ImuMagPf *pf)
{
    ImuMagPfRbReset(pf);
    ImuMagPfPriorTakenBack(pf);
}

/** @brief New segment after a change: sums restart at the current sample, priors around a state
 *         (hard iron [uT] then soft iron b11..b33: the estimate, or the prior calibration). */
static void ImuMagPfRbRestart(ImuMagPf *pf, const double mag[3], const double state[IMU_MAG_PF_STATE_SIZE])
{
    const ImuMagPfSettings *s = &pf->settings;
    const double u[3] = {mag[0] - s->priorHardIron[0], mag[1] - s->priorHardIron[1], mag[2] - s->priorHardIron[2]};
    double softMean[IMU_MAG_SOFT_COUNT], centre[3];
    memcpy(centre, state, sizeof(centre));
    ImuMagQuadraticFromSoft(state + 3, softMean);
    memset(pf->rb.moments, 0, sizeof(pf->rb.moments));
    memset(pf->rb.previousMoments, 0, sizeof(pf->rb.previousMoments));
    ImuMagMomentsAdd(pf->rb.moments, u);
    ImuMagPfRbSetPrior(pf, centre, s->changeSpreadHard, softMean, 2.0 * s->changeSpreadSoft);
    ImuMagPfRbDraw(pf, centre, s->changeSpreadHard);
}

/** @brief Targets of every particle under the current sums (work.logLikelihood); 1 if one with
 *         weight > 0 is admissible under both the previous and the current sums. */
static int ImuMagPfRbWeighNew(ImuMagPf *pf)
{
    int i, usable = 0;
    for (i = 0; i < pf->settings.particleCount; i++) {
        pf->work.logLikelihood[i] = ImuMagPfRbEvaluate(pf, pf->rb.moments, pf->particle[i], pf->particle[i] + 3);
        usable |= pf->weight[i] > 0.0 && pf->work.logLikelihood[i] > -HUGE_VAL && pf->rb.previousLog[i] > -HUGE_VAL;
    }
    return usable;
}

/** @brief Log weight of particle i after raising the bridging exponent by step (-inf if inadmissible). */
static double ImuMagPfRbLogWeight(const ImuMagPf *pf, int i, double step)
{
    const double now = pf->work.logLikelihood[i], before = pf->rb.previousLog[i];
    if (!(pf->weight[i] > 0.0 && now > -HUGE_VAL && before > -HUGE_VAL)) {
        return -HUGE_VAL;
    }
    return log(pf->weight[i]) + step * (now - before);
}

/** @brief Log weight of every particle (work.logWeight) and its log-target increment (work.logSpare) such
 *         that ImuMagPfRbLogWeight(pf, i, step) = logWeight[i] + step logSpare[i] (an inadmissible
 *         particle: -inf and 0), so that the bisection takes no logarithm. */
static void ImuMagPfRbIncrements(ImuMagPf *pf)
{
    int i;
    for (i = 0; i < pf->settings.particleCount; i++) {
        const double now = pf->work.logLikelihood[i], before = pf->rb.previousLog[i];
        const int usable = pf->weight[i] > 0.0 && now > -HUGE_VAL && before > -HUGE_VAL;
        pf->work.logWeight[i] = usable ? log(pf->weight[i]) : -HUGE_VAL;
        pf->work.logSpare[i] = usable ? now - before : 0.0;
    }
}

/** @brief N_eff the weights would have after raising the exponent by step [particles] (after
 *         ImuMagPfRbIncrements). */
static double ImuMagPfRbEssAfter(const ImuMagPf *pf, double step)
{
    const int n = pf->settings.particleCount;
    const double *base = pf->work.logWeight, *increment = pf->work.logSpare;
    double largest = -HUGE_VAL, sum = 0.0, squares = 0.0;
    int i;
    for (i = 0; i < n; i++) {
        const double l = base[i] + step * increment[i];
        largest = l > largest ? l : largest;
    }
    for (i = 0; i < n; i++) {
        const double w = exp(base[i] + step * increment[i] - largest);
        sum += w;
        squares += w * w;
    }
    return sum * sum / squares;
}

/** @brief Next bridging exponent after g: 1 when N_eff stays >= N/2 (or on the last step), else the
 *         largest exponent that keeps N_eff >= N/2 (bisection). */
static double ImuMagPfRbNextExponent(ImuMagPf *pf, double g, int step)
{
    const double half = 0.5 * pf->settings.particleCount;
    double low = g, high = 1.0;
    int k;
    if (step >= IMU_MAG_PF_BRIDGE_STEPS) {
        return 1.0;
    }
    ImuMagPfRbIncrements(pf);
    if (ImuMagPfRbEssAfter(pf, 1.0 - g) >= half) {
        return 1.0;
    }
    for (k = 0; k < IMU_MAG_PF_BISECTIONS; k++) {
        const double middle = 0.5 * (low + high);
        if (ImuMagPfRbEssAfter(pf, middle - g) >= half) {
            low = middle;
        } else {
            high = middle;
        }
    }
    return low > g + IMU_MAG_PF_MIN_BRIDGE_STEP ? low : g + IMU_MAG_PF_MIN_BRIDGE_STEP;
}

/** @brief Lower Cholesky factor of the weighted hard-iron covariance x IMU_MAG_PF_MOVE_SCALE [uT]. */
static void ImuMagPfRbProposal(const ImuMagPf *pf, double factor[3][3])
{
    double mean[3] = {0.0, 0.0, 0.0}, cov[3][3] = {{0.0}};
    int i, j, k;
    for (i = 0; i < pf->settings.particleCount; i++) {
        for (j = 0; j < 3; j++) {
            mean[j] += pf->weight[i] * pf->particle[i][j];
        }
    }
    for (i = 0; i < pf->settings.particleCount; i++) {
        for (j = 0; j < 3; j++) {
            for (k = 0; k < 3; k++) {
                cov[j][k] += pf->weight[i] * (pf->particle[i][j] - mean[j]) * (pf->particle[i][k] - mean[k]);
            }
        }
    }
    for (j = 0; j < 3; j++) {
        double d = IMU_MAG_PF_MOVE_SCALE * cov[j][j] + IMU_MAG_PF_MOVE_FLOOR;
        for (k = 0; k < j; k++) {
            d -= factor[j][k] * factor[j][k];
        }
        factor[j][j] = d > 0.0 ? sqrt(d) : sqrt(IMU_MAG_PF_MOVE_FLOOR);
        for (i = j + 1; i < 3; i++) {
            double s = IMU_MAG_PF_MOVE_SCALE * cov[i][j];
            for (k = 0; k < j; k++) {
                s -= factor[i][k] * factor[j][k];
            }
            factor[i][j] = s / factor[j][j];
        }
        for (k = j + 1; k < 3; k++) {
            factor[j][k] = 0.0;
        }
    }
}

/** @brief Systematic resampling of particles and both targets to equal weights. */
static void ImuMagPfRbResample(ImuMagPf *pf)
{
    const int n = pf->settings.particleCount;
    int k;
    ImuMagPfSystematicParents(pf);
    for (k = 0; k < n; k++) {
        memcpy(pf->work.copy[k], pf->particle[pf->work.parent[k]], sizeof(pf->particle[0]));
        pf->work.logWeight[k] = pf->work.logLikelihood[pf->work.parent[k]];
        pf->work.logSpare[k] = pf->rb.previousLog[pf->work.parent[k]];
    }
    memcpy(pf->particle, pf->work.copy, (size_t)n * sizeof(pf->particle[0]));
    memcpy(pf->work.logLikelihood, pf->work.logWeight, (size_t)n * sizeof(double));
    memcpy(pf->rb.previousLog, pf->work.logSpare, (size_t)n * sizeof(double));
    for (k = 0; k < n; k++) {
        pf->weight[k] = 1.0 / n;
    }
}

/** @brief Metropolis sweeps with target pi_g (log: before + g (now - before)) and proposal x + F z. */
static void ImuMagPfRbMove(ImuMagPf *pf, double g, double factor[3][3], int sweeps)
{
    double proposal[3], soft[IMU_MAG_SOFT_COUNT], softBefore[IMU_MAG_SOFT_COUNT];
    int sweep, k, j;
    for (sweep = 0; sweep < sweeps; sweep++) {
        for (k = 0; k < pf->settings.particleCount; k++) {
            double z[3], before, now, accept, u;
            for (j = 0; j < 3; j++) {
                z[j] = ImuRngNormal(&pf->rng);
            }
            for (j = 0; j < 3; j++) {
                proposal[j] = pf->particle[k][j] + factor[j][0] * z[0] + factor[j][1] * z[1] + factor[j][2] * z[2];
            }
            now = ImuMagPfRbEvaluate(pf, pf->rb.moments, proposal, soft);
            before = g < 1.0 ? ImuMagPfRbEvaluate(pf, pf->rb.previousMoments, proposal, softBefore) : now; /* pi_1 = pi_new */
            u = ImuRngUniform(&pf->rng);
            if (!(before > -HUGE_VAL && now > -HUGE_VAL)) {
                continue;
            }
            accept = (before + g * (now - before)) -
                     (pf->rb.previousLog[k] + g * (pf->work.logLikelihood[k] - pf->rb.previousLog[k]));
            if (accept >= 0.0 || u < exp(accept)) {
                memcpy(pf->particle[k], proposal, sizeof(proposal));
                memcpy(pf->particle[k] + 3, soft, sizeof(soft));
                pf->rb.previousLog[k] = before;
                pf->work.logLikelihood[k] = now;
            }
        }
    }
}

/** @brief Bridge the weighted cloud from the previous target to the current one. */
static void ImuMagPfRbBridge(ImuMagPf *pf)
{
    const double threshold = (2.0 / 3.0) * pf->settings.particleCount;
    double g = 0.0, factor[3][3];
    int step, i, moved = 0;
    for (step = 1; g < 1.0; step++) {
        const double next = ImuMagPfRbNextExponent(pf, g, step);
        for (i = 0; i < pf->settings.particleCount; i++) {
            pf->work.logWeight[i] = ImuMagPfRbLogWeight(pf, i, next - g);
        }
        ImuMagPfNormaliseLog(pf);
        g = next;
        pf->effectiveSampleSize = ImuMagPfEss(pf);
        if (pf->effectiveSampleSize < threshold) {
            ImuMagPfRbProposal(pf, factor);
            ImuMagPfRbResample(pf);
            if (pf->settings.enableMove) {
                ImuMagPfRbMove(pf, g, factor, IMU_MAG_PF_MOVE_SWEEPS);
                moved = 1;
            }
        }
    }
    if (pf->settings.enableMove && !moved) { /* a cloud whose weights stayed even still explores pi_new */
        ImuMagPfRbProposal(pf, factor);
        ImuMagPfRbMove(pf, 1.0, factor, IMU_MAG_PF_IDLE_SWEEPS);
    }
}

/** @brief 1 if the power sums hold new samples since the last move of the particles and either
 *         they grew by updateGrowth x the samples they held then (moments[0] counts the samples) or
 *         the estimate no longer explains the data (innovation average above updateInnovation).
 *         Without a new sample the target is the one the cloud already represents, so skipping is
 *         exact; the growth rule spaces the moves geometrically, as the information in the sums
 *         grows; the innovation rule keeps the estimate, which the change test, the glitch gate and
 *         the ambient-norm mean use, from lagging behind data that contradict it. */
static int ImuMagPfRbInformative(const ImuMagPf *pf)
{
    const ImuMagPfSettings *s = &pf->settings;
    const double added = pf->rb.moments[0] - pf->rb.previousMoments[0];
    return added > 0.0 && (added >= s->updateGrowth * pf->rb.previousMoments[0] ||
                           pf->innovationAverage > s->updateInnovation);
}

int ImuMagPfRbUpdate(ImuMagPf *pf, const double mag[3])
{
    const ImuMagPfSettings *s = &pf->settings;
    const double u[3] = {mag[0] - s->priorHardIron[0], mag[1] - s->priorHardIron[1], mag[2] - s->priorHardIron[2]};
    int i;
    if (!pf->frozen && ImuMagPfRotated(pf, mag) && !ImuMagPfOutlier(pf, mag)) { /* sums: turned by minRotation, no glitch */
        memcpy(pf->lastUsed, mag, sizeof(pf->lastUsed));
        ImuMagMomentsAdd(pf->rb.moments, u);
    }
    if (++pf->sampleCounter < s->decimation) { /* the change test sees every valid sample's updates */
        return 0;
    }
    pf->sampleCounter = 0;
    ImuMagPfAdapt(pf, mag);
    if (ImuMagPfChangeDeclared(pf, mag)) {
        double centre[IMU_MAG_PF_STATE_SIZE];
        ImuMagPfChangeCentre(pf, centre);
        pf->frozen = 0;
        ImuMagPfRbRestart(pf, mag, centre);
    } else if (pf->frozen) {
        return 0;
    } else if (ImuMagPfPriorExplains(pf, mag)) {
        ImuMagPfRbTakeBackPrior(pf);
        return 0;
    }
    if (!ImuMagPfRbInformative(pf)) { /* the change test above ran; the cloud waits for information */
        return 0;
    }
    if (!ImuMagPfRbWeighNew(pf)) { /* no admissible particle left: a change the test did not see */
        ImuMagPfDeclareChange(pf);
        ImuMagPfRbRestart(pf, mag, pf->estimate);
        if (!ImuMagPfRbWeighNew(pf)) { /* the estimate itself is hopeless: around the prior calibration */
            double prior[IMU_MAG_PF_STATE_SIZE];
            ImuMagPfPriorState(pf, prior);
            ImuMagPfRbRestart(pf, mag, prior);
            if (!ImuMagPfRbWeighNew(pf)) {
                return 0;
            }
        }
    }
    ImuMagPfRbBridge(pf);
    memcpy(pf->rb.previousMoments, pf->rb.moments, sizeof(pf->rb.moments));
    for (i = 0; i < s->particleCount; i++) {
        pf->rb.previousLog[i] = pf->work.logLikelihood[i];
    }
    ImuMagPfRbEstimate(pf);
    return 1;
}
