/**
 * @file ImuLayout.h
 * @brief Sizes and orders of the flat arrays shared with Python (contract/layout.py).
 *
 * tests/test_layout.py pins these numbers to the Python side through ImuBatchLayout().
 */
#ifndef IMU_LAYOUT_H
#define IMU_LAYOUT_H

#include "ImuTerms.h"
#include "ImuElm.h"
#include "ImuPsoBp.h"

#define IMU_LAYOUT_VERSION 4

/** Runtime inputs per sample (rad/s, m/s^2, uT, degC; auxiliary inputs in their own units). */
typedef enum {
    ImuInGyrX, ImuInGyrY, ImuInGyrZ,
    ImuInAccX, ImuInAccY, ImuInAccZ,
    ImuInMagX, ImuInMagY, ImuInMagZ,
    ImuInTemp,
    ImuInAux1, ImuInAux2, ImuInAux3, ImuInAux4, /* signals from outside the IMU for the correction terms */
    IMU_INPUT_COUNT
} ImuInput;

/* The auxiliary inputs are the last IMU_TERMS_AUX_COUNT inputs. */
typedef char ImuLayoutCheckAux[(IMU_INPUT_COUNT - ImuInAux1 == IMU_TERMS_AUX_COUNT) ? 1 : -1];

/** Runtime outputs per sample. */
typedef enum {
    ImuOutRateX, ImuOutRateY, ImuOutRateZ,        /* rad/s */
    ImuOutAccelX, ImuOutAccelY, ImuOutAccelZ,     /* m/s^2 */
    ImuOutFieldX, ImuOutFieldY, ImuOutFieldZ,     /* uT */
    ImuOutRoll, ImuOutPitch, ImuOutYaw,           /* rad, body -> magnetic NED, ZYX */
    ImuOutHeading,                                /* rad, yaw + declination */
    ImuOutQw, ImuOutQx, ImuOutQy, ImuOutQz,       /* body -> magnetic NED */
    ImuOutGainRoll, ImuOutGainPitch, ImuOutGainYaw, /* 1 */
    ImuOutHardIronX, ImuOutHardIronY, ImuOutHardIronZ, /* uT, particle-filter hard iron */
    ImuOutSoftIronXx, ImuOutSoftIronYy, ImuOutSoftIronZz, /* 1, particle-filter soft-iron diagonal */
    ImuOutPfNeff,                                 /* 1, effective sample size (0 when off) */
    ImuOutCalibrationValid,                       /* 1 while every model input is inside its calibrated range, else 0 (layout 4) */
    IMU_OUTPUT_COUNT
} ImuOutput;

/** Settings (FMU parameters) in the flat settings array. */
typedef enum {
    ImuSetDeclination,       /* rad */
    ImuSetFieldNorm,         /* uT */
    ImuSetGyroNoise,         /* rad/s/sqrt(Hz) */
    ImuSetGyroBiasResidual,  /* rad/s */
    ImuSetMseTimeConstant,   /* s */
    ImuSetAngleNoise,        /* rad */
    ImuSetEnableThermal,     /* 0 or 1 */
    ImuSetAttitudeMode,      /* 0 Euler, 1 quaternion */
    ImuSetFieldDip,          /* rad */
    ImuSetTauAcc,            /* s */
    ImuSetTauMag,            /* s */
    ImuSetRestGyroThreshold, /* rad/s */
    ImuSetRestAccThreshold,  /* m/s^2 */
    ImuSetMagRejectTime,     /* s */
    ImuSetEnableElm,         /* 0 or 1 */
    ImuSetEnablePf,          /* 0 or 1 */
    ImuSetPfParticles,       /* 1 */
    ImuSetPfMeasurementNoise, /* uT */
    ImuSetPfProcessNoiseHard, /* uT per update */
    ImuSetPfProcessNoiseSoft, /* 1 per update */
    ImuSetPfPriorSpreadHard, /* uT */
    ImuSetPfPriorSpreadSoft, /* 1 */
    ImuSetPfDecimation,      /* samples */
    ImuSetPfSeed,            /* 1 */
    ImuSetPfThresholdHigh,   /* 1/N */
    ImuSetPfThresholdLow,    /* 1/N */
    ImuSetPfSphereBins,      /* cells per cube-face side */
    ImuSetEnablePsoBp,       /* 0 or 1 */
    ImuSetPfRaoBlackwell,    /* 0 or 1 */
    ImuSetPfMinRotation,     /* rad */
    ImuSetPfChangeSpreadHard, /* uT */
    ImuSetPfHoldPrior,       /* 0 or 1 */
    ImuSetPfSettleSpread,    /* uT */
    ImuSetLagGyr,            /* s, how long the gyro input lags true time (ImuAlign.h) */
    ImuSetLagAcc,            /* s */
    ImuSetLagMag,            /* s */
    ImuSetMountX,            /* signed sensor axis that is body x: 1..3 = +x..+z, -1..-3 = -x..-z (ImuMount.h) */
    ImuSetMountY,            /* signed sensor axis that is body y */
    ImuSetMountZ,            /* signed sensor axis that is body z */
    IMU_SETTING_COUNT
} ImuSetting;

#define IMU_THERMAL_MAX_DEGREE 3
/** One triad block: enabled, t0, ts, degree, A[9], g[3][MAX], b[3][MAX+1], then (layout 4) the
 *  calibrated temperature range: hasRange (0/1), tMin [degC], tMax [degC]. */
#define IMU_THERMAL_BLOCK (4 + 9 + 3 * IMU_THERMAL_MAX_DEGREE + 3 * (IMU_THERMAL_MAX_DEGREE + 1) + 3)
/** Offsets of the blocks in the coefficient array: [version, gyr, acc, mag thermal blocks, terms, elm, psobp]. */
#define IMU_OFFSET_THERMAL 1
#define IMU_OFFSET_TERMS (IMU_OFFSET_THERMAL + 3 * IMU_THERMAL_BLOCK)
#define IMU_OFFSET_ELM (IMU_OFFSET_TERMS + IMU_TERMS_BLOCK)
#define IMU_OFFSET_PSOBP (IMU_OFFSET_ELM + IMU_ELM_BLOCK)
#define IMU_COEFFICIENT_COUNT (IMU_OFFSET_PSOBP + IMU_PSOBP_BLOCK)

#endif
