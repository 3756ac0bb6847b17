/**
 * @file ImuPipeline.h
 * @brief The per-sample processing chain: thermal compensation -> time alignment -> correction
 *        terms -> magnetometer stages -> mounting (sensor -> body axes) -> attitude fusion.
 *
 * Knows nothing of FMI. The FMU (model.c) and the batch library (batch/ImuBatch.c) both drive it
 * through these verbs, so both give bit-identical outputs for the same inputs.
 */
#ifndef IMU_PIPELINE_H
#define IMU_PIPELINE_H

#include <stddef.h>
#include "ImuCommon.h"
#include "ImuLayout.h"
#include "ImuThermal.h"
#include "ImuAlign.h"
#include "ImuMount.h"
#include "ImuAttitude.h"
#include "ImuTerms.h"
#include "ImuElm.h"
#include "ImuMagPf.h"
#include "ImuPsoBp.h"
#include "ImuBiasLearning.h"

/** Trained coefficients of every stage (unpacked from the flat coefficient array). */
typedef struct {
    ImuThermalCoefficients thermal[3]; /* gyr, acc, mag */
    ImuTermsCoefficients terms;        /* additive terms found by `imufmu diagnose` */
    ImuElm elm;                        /* nonlinear field model (field form) */
    ImuPsoBpCoefficients psobp;        /* gyro bias network on temperature and its rate */
} ImuCoefficients;

/** User settings in user units (the FMU parameters). */
typedef struct {
    double values[IMU_SETTING_COUNT]; /* as given (ImuSetting order); checked against their declared ranges */
    double declination;      /* rad */
    double fieldNorm;        /* uT */
    double gyroNoise;        /* rad/s/sqrt(Hz) */
    double gyroBiasResidual; /* rad/s */
    double mseTimeConstant;  /* s */
    double angleNoise;       /* rad */
    int enableThermal;       /* 0 or 1 */
    int attitudeMode;        /* ImuAttitudeMode; -1 marks a value other than 0/1 for the check */
    double fieldDip;         /* rad */
    double tauAcc;           /* s */
    double tauMag;           /* s */
    double restGyroThreshold; /* rad/s, 0 = no bias estimation */
    double restAccThreshold; /* m/s^2 */
    double magRejectTime;    /* s, 0 = no rejection */
    int gyroHold;            /* a rate sample holds over the interval before it (else trapezoid) */
    int magHeading;          /* the field corrects the heading (else 6D) */
    int motionBias;          /* the quaternion filter estimates the gyro bias in motion too */
    double accNormTolerance; /* 1, |f| / g - 1 of the still, corrected accelerometer */
    int enableElm;           /* 0 or 1: apply the ELM nonlinear field model */
    int enablePf;            /* 0 or 1: online hard/soft-iron particle filter */
    int pfSeed;              /* particle-filter seed, -1 marks an invalid value for the check */
    int enablePsoBp;         /* 0 or 1: PSO-BP gyro bias network (mode of its block) */
    int psobpClamp;          /* 0 or 1: the network's inputs clamped to their training ranges */
    int thermalContinuation; /* 0 or 1: gain/bias models continue along their edge tangent */
    ImuBiasLearningSettings learning; /* online learning of the gyro bias at rests */
    int eulerAdditions;      /* ImuEulerAddition bits of the Euler fusion */
    ImuMagPfSettings pf;     /* particle-filter settings (defaults + the FMU parameters) */
    ImuAlignSettings align;  /* lags [s] of the gyr, acc, mag inputs behind true time */
    ImuMount mount;          /* sensor axes -> body axes (identity when the codes are invalid) */
    int mountValid;          /* 1 if mount_x, mount_y, mount_z form a proper signed axis permutation */
} ImuPipelineSettings;

/** Models whose input left the range it was calibrated on in the last sample (one bit each); the
 *  model was evaluated with that input clamped to the range (ImuThermal.h, ImuPsoBp.h, ImuTerms.h,
 *  ImuElm.h). Output calibration_valid is 1 while none is set. */
typedef enum {
    ImuRangeThermalGyr = 1 << 0, /* temperature outside the gyroscope gain/bias model's range */
    ImuRangeThermalAcc = 1 << 1, /* temperature outside the accelerometer gain/bias model's range */
    ImuRangeThermalMag = 1 << 2, /* temperature outside the magnetometer gain/bias model's range */
    ImuRangePsoBp = 1 << 3,      /* temperature or its rate outside the PSO-BP network's ranges */
    ImuRangeTerms = 1 << 4,      /* a correction term's regressor outside its [lo, hi] */
    ImuRangeElm = 1 << 5,        /* the field outside the ELM's calibrated box */
    ImuRangeLag = 1 << 6         /* a lag beyond the time-alignment buffer's span: clamped to it */
} ImuRangeIssue;

/** Whole pipeline: settings, coefficients and evolving state in one plain struct (copyable). */
typedef struct {
    ImuPipelineSettings settings;
    ImuCoefficients coefficients;
    ImuAttitude attitude;
    ImuAlignState align; /* buffer of the compensated triads for their time alignment */
    ImuTermsState terms;
    ImuMagPf pf;       /* used when settings.enablePf */
    ImuPsoBpState psobp; /* causal temperature-rate estimate of the PSO-BP model */
    ImuBiasLearning learning; /* the gyro bias learnt at rests */
    int rangeIssues;   /* ImuRangeIssue bits of the last sample */
} ImuPipeline;

/** @brief Unpack a flat coefficient array (layout: ImuLayout.h). @return 0, -1 on bad size/version, -(2 + b) when
 *  block b of IMU_COEFFICIENT_BLOCKS is invalid. */
IMU_HIDDEN int ImuCoefficientsFromArray(ImuCoefficients *c, const double *a, size_t n);
/** @brief Unpack a flat settings array (enable_thermal other than 0/1 is stored as -1 for the check). @return 0, or -1 on bad size. */
IMU_HIDDEN int ImuPipelineSettingsFromArray(ImuPipelineSettings *s, const double *a, size_t n);
/** @brief Check settings; on error return -1 and point *message at a static text naming the setting and range. */
IMU_HIDDEN int ImuPipelineSettingsCheck(const ImuPipelineSettings *s, const char **message);
/**
 * @brief Set settings and coefficients and everything the stages derive from them (attitude settings,
 *        particle-filter coefficients, PSO-BP time constant), keeping the evolving state: what a
 *        restored FMU state must not take from the restored bytes (the settings must pass
 *        ImuPipelineSettingsCheck).
 */
IMU_HIDDEN void ImuPipelineConfigure(ImuPipeline *p, const ImuPipelineSettings *s, const ImuCoefficients *c);
/** @brief Set settings and coefficients and reset the state. */
IMU_HIDDEN void ImuPipelineInitialise(ImuPipeline *p, const ImuPipelineSettings *s, const ImuCoefficients *c);
/** @brief Return to the state right after ImuPipelineInitialise. */
IMU_HIDDEN void ImuPipelineReset(ImuPipeline *p);
/**
 * @brief A gap of `gap` [s] in the samples (ImuGuard.h): re-initialise what cannot be integrated across it. The
 *        attitude corrections restart as at power-on (the gyro bias is kept; without a field yaw
 *        keeps its value from before the gap) and the time-alignment buffer empties.
 */
IMU_HIDDEN void ImuPipelineGap(ImuPipeline *p, double gap);
/**
 * @brief NULL if the evolving state of an initialised pipeline is one it can reach by clock [s]
 *        (ImuGuard's time of the last sample; a restored FMU state): buffer heads and counts that
 *        index, times finite and no later than clock, filter flags and counts in range; else what is
 *        wrong, in the state's terms.
 */
IMU_HIDDEN const char *ImuPipelineStateProblem(const ImuPipeline *p, double clock);
/**
 * @brief Process one sample.
 * @param t time of the sample [s] since the first one (the clock of the time-dependent signals:
 *        alignment, correction terms, PSO-BP temperature rate; it does not decrease).
 * @param dt integration step [s] from the previous sample (0: nothing is propagated).
 * @param nominalStep the sampling step [s] before this sample (ImuGuardNominalStep; 0 when unknown).
 * @param in IMU_INPUT_COUNT raw inputs (rad/s, m/s^2, uT, degC, then the auxiliary inputs).
 * @param out IMU_OUTPUT_COUNT outputs (see ImuLayout.h).
 */
IMU_HIDDEN void ImuPipelineUpdate(ImuPipeline *p, double t, double dt, double nominalStep, const double in[IMU_INPUT_COUNT],
                                  double out[IMU_OUTPUT_COUNT]);
/** @brief One line naming the models of the ImuRangeIssue bits `issues` with their calibrated
 *         ranges (degC, degC/s, uT) into text (at most size bytes, NUL-terminated). */
IMU_HIDDEN void ImuPipelineDescribeRanges(const ImuPipeline *p, int issues, char *text, size_t size);

#endif
