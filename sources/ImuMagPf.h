/**
 * @file ImuMagPf.h
 * @brief Online hard- and soft-iron estimation by particle filter (docs/magpf.md).
 *
 * State x = [h_p (3) uT, b11 b12 b13 b22 b23 b33 (1)], a random walk per filter update.
 * Observation y = |h_m|^2 - |h_0|^2 = h(x) + noise with h(x) = 2 h_p.h_m - |h_p|^2
 * - d^T (B + B^T + B^T B) d, d = h_m - h_p; noise mean 3 sigma^2, variance 4 |h_0|^2 sigma^2 + 6 sigma^4.
 * Each update: store the sample in a buffer of past samples binned over the sphere of directions,
 * predict, weigh (log domain) against the whole buffer, N_eff; below 2N/3 double-threshold
 * splitting with roughened copies whose weights come from a small back-propagation network
 * (diversity check by the Hill number), then systematic resampling if N_eff is still below 2N/3.
 * A change test on the innovation of the estimate re-widens the cloud and flushes the buffer; the
 * prior calibration is re-tested after every change and taken back when it explains the data.
 * Compensation h_c = (I + B)(h_m - h_p) with the weighted-mean estimate. All memory is inside
 * ImuMagPf. This header is the interface of the facade ImuMagPf.c (its comment lists the mode
 * files and their dependency order); what the mode files share is in ImuMagPfPrivate.h.
 */
#ifndef IMU_MAG_PF_H
#define IMU_MAG_PF_H

#include <stddef.h>
#include <stdint.h>
#include "ImuCommon.h"
#include "ImuRng.h"
#include "ImuMagMoments.h"

#define IMU_MAG_PF_MAX_PARTICLES 512 /* compile-time maximum particle count */
#define IMU_MAG_PF_STATE_SIZE 9      /* hard iron (3) + soft iron (6) */
#define IMU_MAG_PF_MAX_HIDDEN 8      /* maximum hidden units of the restoration network */
#define IMU_MAG_PF_MAX_TRAINING 64   /* high-weight particles used to train the network */
#define IMU_MAG_PF_MAX_BIN_SIDE 4    /* largest sphereBins (cells per cube-face side) */
#define IMU_MAG_PF_MAX_BINS (6 * IMU_MAG_PF_MAX_BIN_SIDE * IMU_MAG_PF_MAX_BIN_SIDE) /* 96 */
#define IMU_MAG_PF_INTERNAL_COUNT 26 /* settings that are not FMU parameters (ImuMagPf.c ImuMagPfInternal) */

/** User settings (units in the comments): the FMU parameters pf_* and field_norm, and the internal
 *  settings of ImuMagPf.c ImuMagPfInternal. */
typedef struct {
    int particleCount;             /* 1, N in 2..IMU_MAG_PF_MAX_PARTICLES */
    double highThreshold;          /* 1, omega1 relative to 1/N, in (1, 100] */
    double lowThreshold;           /* 1, omega2 relative to 1/N, in (0, 1) */
    double measurementNoise;       /* uT, sigma of the field noise per axis, > 0 */
    double processNoiseHard;       /* uT per filter update, random-walk sigma of h_p, >= 0 */
    double processNoiseSoft;       /* 1 per filter update, random-walk sigma of b_ij, >= 0 */
    double priorSpreadHard;        /* uT, prior sigma of h_p around priorHardIron, >= 0 */
    double priorSpreadSoft;        /* 1, prior sigma of b_ij around priorSoftIron, >= 0 */
    double priorHardIron[3];       /* uT, prior mean of h_p */
    double priorSoftIron[6];       /* 1, prior mean of b11 b12 b13 b22 b23 b33 */
    double roughening;             /* 1, K: jitter sigma = K N^(-1/9) x cloud sigma, in [0, 10] */
    double innovationTimeConstant; /* filter updates of the innovation average; 0: no adaptation */
    double maxInflation;           /* 1, largest process-noise inflation factor, >= 1 */
    int decimation;                /* filter every k-th valid sample, 1..1000 */
    double minRotation;            /* rad, skip samples within this angle of the last used one, [0, pi/2] */
    int hiddenUnits;               /* tansig units of the network, 1..IMU_MAG_PF_MAX_HIDDEN */
    int trainingEpochs;            /* gradient-descent epochs per training, 1..200 */
    double learningRate;           /* 1, gradient-descent step on normalised data, (0, 10] */
    int maxTries;                  /* diversity-restoration tries, 1..20 */
    int enableSplitting;           /* 1: steps 5-6; 0: plain SIR (baseline) */
    int enableMove;                /* 1: Metropolis acceptance of the roughening after resampling (resample-move) */
    int enableTempering;           /* mode 0: 1: tempering exponent alpha = min(1, sqrt(ln 2 / var_w(l))); 0: alpha = 1 (the method) */
    int resampleRoughening;        /* mode 0: 1: roughen the resampled cloud (the proposal of enableMove); 0: plain copies (the method) */
    int glitchClipping;            /* 1: innovations enter the change test clipped at 2 x changeThreshold and readings beyond
                                      4 x stay out of the buffer / sums; 0: neither */
    int sphereBins;                /* cells per cube-face side of the sample buffer (6 k^2 bins), 0..4; 0: current sample only */
    double changeThreshold;        /* 1, averaged normalised innovation declaring a change; 0: off, else [2, 1e6] */
    double changeSpreadHard;       /* uT, sigma of h_p drawn around the estimate after a change, >= 0 */
    double changeSpreadSoft;       /* 1, sigma of b_ij drawn around the estimate after a change, >= 0 */
    double normTimeConstant;       /* updates, mean of the residual removed from the change test; 0: off */
    double updateGrowth;           /* 1, mode 1 moves the particles once the samples in the power sums grew by this
                                      fraction since its last move (and by at least one); 0: whenever one was added */
    double updateInnovation;       /* 1, mode 1 also moves them (given a new sample) while the innovation average exceeds this, >= 1 */
    double settleSpread;           /* uT, the estimate counts as settled while the hard-iron cloud sigma is below it; 0: always */
    int holdPrior;                 /* 1: mode 1 holds the prior calibration until the first declared change; 0: adapts from the start */
    int raoBlackwell;              /* 1: hard iron sampled, soft iron integrated out (ImuMagPfRb.c); 0: the method's 9-state filter */
    uint64_t seed;                 /* PCG32 initial state */
    double fieldNorm;              /* uT, |h_0| of the undisturbed field, > 0 */
} ImuMagPfSettings;

/** Values derived once from the settings. */
typedef struct {
    double observationMean;        /* uT^2, 3 sigma^2 */
    double halfInverseVariance;    /* 1/uT^4, 1 / (2 (4 |h_0|^2 sigma^2 + 6 sigma^4)) */
    double fieldNormSquared;       /* uT^2 */
    double highWeight;             /* 1, omega1 / N */
    double lowWeight;              /* 1, omega2 / N */
    double rougheningScale;        /* 1, K N^(-1/9) */
    double processNoise[IMU_MAG_PF_STATE_SIZE]; /* state units per update */
    double innovationRate;         /* 1, 1 / innovationTimeConstant (0: off) */
    double minRotationCosine;      /* 1, cos(minRotation) */
} ImuMagPfCoefficients;

/** Restoration network: 9 inputs, hiddenUnits tansig units, one linear output (normalised data). */
typedef struct {
    double w1[IMU_MAG_PF_MAX_HIDDEN][IMU_MAG_PF_STATE_SIZE];
    double b1[IMU_MAG_PF_MAX_HIDDEN];
    double w2[IMU_MAG_PF_MAX_HIDDEN];
    double b2;
    double inputMean[IMU_MAG_PF_STATE_SIZE];
    double inputScale[IMU_MAG_PF_STATE_SIZE];
    double outputMean;
    double outputScale;
} ImuMagPfNetwork;

/** Scratch arrays of one update (part of the state so that nothing is allocated). */
typedef struct {
    double logLikelihood[IMU_MAG_PF_MAX_PARTICLES];      /* 1, log p(buffer | x_i) */
    double logWeight[IMU_MAG_PF_MAX_PARTICLES];          /* 1 */
    double logSpare[IMU_MAG_PF_MAX_PARTICLES];           /* 1, resampling copy of previousLog */
    double copy[IMU_MAG_PF_MAX_PARTICLES][IMU_MAG_PF_STATE_SIZE];
    int high[IMU_MAG_PF_MAX_PARTICLES];
    int low[IMU_MAG_PF_MAX_PARTICLES];
    int parent[IMU_MAG_PF_MAX_PARTICLES];
    double hidden[IMU_MAG_PF_MAX_TRAINING][IMU_MAG_PF_MAX_HIDDEN];
    double error[IMU_MAG_PF_MAX_TRAINING];
    ImuMagPfNetwork network;
} ImuMagPfWork;

/** State of the Rao-Blackwellised mode only (ImuMagPfRb.c; particle[i] = [h_p (3) uT, m (6) posterior
 *  mean of M given h_p]). */
typedef struct {
    double moments[IMU_MAG_MOMENT_COUNT];         /* power sums of mag - priorHardIron since the reset or change */
    double previousMoments[IMU_MAG_MOMENT_COUNT]; /* the sums at the previous filter update */
    double previousLog[IMU_MAG_PF_MAX_PARTICLES]; /* 1, log target of each particle under previousMoments */
    ImuMagMarginalPrior prior;                    /* priors since the reset or the last change */
} ImuMagPfRbState;

/** The filter: settings, coefficients and state in one plain struct (a copy is a saved state). */
typedef struct {
    ImuMagPfSettings settings;
    ImuMagPfCoefficients coefficients;
    ImuRng rng;
    double particle[IMU_MAG_PF_MAX_PARTICLES][IMU_MAG_PF_STATE_SIZE];
    double weight[IMU_MAG_PF_MAX_PARTICLES];
    double estimate[IMU_MAG_PF_STATE_SIZE];
    double effectiveSampleSize;    /* 1, 1 / sum w^2 after the last update */
    double innovationAverage;      /* 1, averaged normalised innovation squared of the estimate */
    double inflation;              /* 1, current process-noise factor */
    int sampleCounter;             /* valid samples since the last filter update */
    double lastUsed[3];            /* uT, raw sample of the last filter update (0: none yet) */
    double bin[IMU_MAG_PF_MAX_BINS][3];  /* uT, newest raw sample per direction bin */
    int binUsed[IMU_MAG_PF_MAX_BINS];    /* 1 if the bin holds a sample */
    int binList[IMU_MAG_PF_MAX_BINS];    /* indices of the filled bins in order of first filling */
    int binCount;                  /* number of filled bins */
    int updatesSinceChange;        /* filter updates since the reset or the last declared change */
    int changeArmed;               /* 1 once the innovation average fell below changeThreshold */
    int changeCount;               /* changes of environment declared since the reset */
    double residualMean;           /* uT^2, averaged residual of the estimate (normTimeConstant) */
    double hardSpread;             /* uT, largest weighted sigma of the hard-iron components of the cloud */
    int frozen;                    /* 1 while the prior calibration is held (holdPrior, no change declared yet or taken back) */
    int evidenceDirections;        /* distinct field directions (armed, innovation average above changeThreshold)
                                      of the samples whose own innovation exceeded it */
    double evidenceDirection[3];   /* uT, raw sample of the last direction counted as evidence */
    double priorAverage;           /* 1, averaged clipped normalised innovation of the prior calibration (re-tests) */
    int retestUpdates;             /* updates since the prior's average last exceeded changeThreshold */
    int retestDirections;          /* distinct field directions (minRotation apart) among them */
    double retestDirection[3];     /* uT, raw sample of the last direction counted in the re-test */
    double retestPriorSum;         /* 1, sum of the prior's clipped normalised innovations over them */
    double retestEstimateSum;      /* 1, sum of the estimate's clipped normalised innovations over them */
    int retesting;                 /* 1 from a declared change until the prior calibration is taken back */
    ImuMagPfRbState rb;            /* Rao-Blackwellised mode only */
    ImuMagPfWork work;
} ImuMagPf;

/** @brief Zero every setting, then give the internal ones (not FMU parameters) their defaults (additions
 *         1) or their values in the method as its source describes it (additions 0: FMU parameter
 *         pf_additions); the FMU parameters come from the settings array (ImuPipeline.c
 *         ImuPipelinePfSettings), whose defaults are the variable table's (contract/variables.py). */
IMU_HIDDEN void ImuMagPfSettingsDefault(ImuMagPfSettings *settings, int additions);
/** @brief Name (snake_case), unit, default and source-method value of internal setting index <
 *         IMU_MAG_PF_INTERNAL_COUNT; 0, or -1 past the end. */
IMU_HIDDEN int ImuMagPfInternalInfo(size_t index, const char **name, const char **unit, double *value,
                                    double *source);
/** @brief Set internal setting index < IMU_MAG_PF_INTERNAL_COUNT to value [its unit]; an integer
 *         setting that is not a whole number in [0, 2^31) becomes -1, which the check rejects. */
IMU_HIDDEN void ImuMagPfSetInternal(ImuMagPfSettings *settings, size_t index, double value);
/** @brief 0 if the settings are valid, else -1 with *message naming the setting and its range. */
IMU_HIDDEN int ImuMagPfSettingsCheck(const ImuMagPfSettings *settings, const char **message);
/** @brief Check settings and derive the coefficients, keeping the evolving state (a restored FMU
 *         state); 0, or -1 (filter untouched) if invalid. */
IMU_HIDDEN int ImuMagPfConfigure(ImuMagPf *pf, const ImuMagPfSettings *settings);
/** @brief Check settings, derive coefficients and reset; 0, or -1 (filter untouched) if invalid. */
IMU_HIDDEN int ImuMagPfInitialise(ImuMagPf *pf, const ImuMagPfSettings *settings);
/** @brief 1 if the evolving counters and indices of pf (a restored FMU state) fit its settings:
 *         binCount and binList index the 6 sphereBins^2 bins (1 with sphereBins 0), every listed bin
 *         is marked in binUsed and as many bins are marked as listed (so binCount cannot outgrow
 *         the bins), and 0 <= sampleCounter < decimation; else 0. */
IMU_HIDDEN int ImuMagPfStateValid(const ImuMagPf *pf);
/** @brief Reseed the generator and draw the prior particles (weights 1/N). */
IMU_HIDDEN void ImuMagPfReset(ImuMagPf *pf);
/** @brief Feed one raw field sample [uT]; 1 if the filter updated, 0 if skipped or decimated. */
IMU_HIDDEN int ImuMagPfUpdate(ImuMagPf *pf, const double mag[3]);
/** @brief h_c = (I + B)(mag - h_p) [uT] with the current estimate. */
IMU_HIDDEN void ImuMagPfCompensate(const ImuMagPf *pf, const double mag[3], double out[3]);
/** @brief Hard-iron estimate h_p [uT]. */
IMU_HIDDEN void ImuMagPfGetHardIron(const ImuMagPf *pf, double hardIron[3]);
/** @brief Soft-iron estimate [1] as b11 b12 b13 b22 b23 b33. */
IMU_HIDDEN void ImuMagPfGetSoftIron(const ImuMagPf *pf, double softIron[6]);
/** @brief Effective sample size 1 / sum w^2 after the last update [particles]. */
IMU_HIDDEN double ImuMagPfGetEffectiveSampleSize(const ImuMagPf *pf);
/** @brief 1 while the prior calibration is held or the hard-iron cloud sigma is below settleSpread (or that is 0). */
IMU_HIDDEN int ImuMagPfSettled(const ImuMagPf *pf);
/** @brief Number of changes of environment declared since the reset. */
IMU_HIDDEN int ImuMagPfGetChangeCount(const ImuMagPf *pf);

#endif
