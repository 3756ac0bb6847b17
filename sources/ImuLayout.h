/**
 * @file ImuLayout.h
 * @brief Sizes and orders of the flat arrays shared with Python (contract/layout.py).
 *
 * The array enums are generated from the variable table (contract/variables.py, `python -m
 * contract.generate`); tests/test_runtime.py pins the block sizes to the Python side through
 * ImuBatchLayout().
 */
#ifndef IMU_LAYOUT_H
#define IMU_LAYOUT_H

#include "ImuTerms.h"
#include "ImuElm.h"
#include "ImuPsoBp.h"

#define IMU_LAYOUT_VERSION 4

/** Runtime inputs per sample (rad/s, m/s^2, uT, degC; auxiliary inputs in their own units). */
/* generated:begin inputs (python -m contract.generate, from contract/variables.py; do not edit) */
typedef enum {
    ImuInGyrX, /* rad/s */
    ImuInGyrY, /* rad/s */
    ImuInGyrZ, /* rad/s */
    ImuInAccX, /* m/s2 */
    ImuInAccY, /* m/s2 */
    ImuInAccZ, /* m/s2 */
    ImuInMagX, /* uT */
    ImuInMagY, /* uT */
    ImuInMagZ, /* uT */
    ImuInTemp, /* degC */
    ImuInAux1, /* 1 */
    ImuInAux2, /* 1 */
    ImuInAux3, /* 1 */
    ImuInAux4, /* 1 */
    IMU_INPUT_COUNT
} ImuInput;
/* generated:end inputs */

/* The auxiliary inputs are the last IMU_TERMS_AUX_COUNT inputs. */
typedef char ImuLayoutCheckAux[(IMU_INPUT_COUNT - ImuInAux1 == IMU_TERMS_AUX_COUNT) ? 1 : -1];

/** Runtime outputs per sample. */
/* generated:begin outputs (python -m contract.generate, from contract/variables.py; do not edit) */
typedef enum {
    ImuOutRateX,            /* rad/s */
    ImuOutRateY,            /* rad/s */
    ImuOutRateZ,            /* rad/s */
    ImuOutAccelX,           /* m/s2 */
    ImuOutAccelY,           /* m/s2 */
    ImuOutAccelZ,           /* m/s2 */
    ImuOutFieldX,           /* uT */
    ImuOutFieldY,           /* uT */
    ImuOutFieldZ,           /* uT */
    ImuOutRoll,             /* rad */
    ImuOutPitch,            /* rad */
    ImuOutYaw,              /* rad */
    ImuOutHeading,          /* rad */
    ImuOutQW,               /* 1 */
    ImuOutQX,               /* 1 */
    ImuOutQY,               /* 1 */
    ImuOutQZ,               /* 1 */
    ImuOutGainRoll,         /* 1 */
    ImuOutGainPitch,        /* 1 */
    ImuOutGainYaw,          /* 1 */
    ImuOutHardIronX,        /* uT */
    ImuOutHardIronY,        /* uT */
    ImuOutHardIronZ,        /* uT */
    ImuOutSoftIronXx,       /* 1 */
    ImuOutSoftIronYy,       /* 1 */
    ImuOutSoftIronZz,       /* 1 */
    ImuOutPfNeff,           /* 1 */
    ImuOutCalibrationValid, /* 1 */
    IMU_OUTPUT_COUNT
} ImuOutput;
/* generated:end outputs */

/** Settings (FMU parameters) in the flat settings array. */
/* generated:begin settings (python -m contract.generate, from contract/variables.py; do not edit) */
typedef enum {
    ImuSetDeclination,        /* rad */
    ImuSetFieldNorm,          /* uT */
    ImuSetGyroNoise,          /* rad/s/sqrt(Hz) */
    ImuSetGyroBiasResidual,   /* rad/s */
    ImuSetMseTimeConstant,    /* s */
    ImuSetAngleNoise,         /* rad */
    ImuSetEnableThermal,      /* 0 or 1 */
    ImuSetAttitudeMode,       /* whole number */
    ImuSetFieldDip,           /* rad */
    ImuSetTauAcc,             /* s */
    ImuSetTauMag,             /* s */
    ImuSetRestGyroThreshold,  /* rad/s */
    ImuSetRestAccThreshold,   /* m/s2 */
    ImuSetMagRejectTime,      /* s */
    ImuSetEnableElm,          /* 0 or 1 */
    ImuSetEnablePf,           /* 0 or 1 */
    ImuSetPfParticles,        /* whole number */
    ImuSetPfMeasurementNoise, /* uT */
    ImuSetPfProcessNoiseHard, /* uT */
    ImuSetPfProcessNoiseSoft, /* 1 */
    ImuSetPfPriorSpreadHard,  /* uT */
    ImuSetPfPriorSpreadSoft,  /* 1 */
    ImuSetPfDecimation,       /* whole number */
    ImuSetPfSeed,             /* whole number */
    ImuSetPfThresholdHigh,    /* 1 */
    ImuSetPfThresholdLow,     /* 1 */
    ImuSetPfSphereBins,       /* whole number */
    ImuSetEnablePsobp,        /* 0 or 1 */
    ImuSetPfRaoBlackwell,     /* 0 or 1 */
    ImuSetPfMinRotation,      /* rad */
    ImuSetPfChangeSpreadHard, /* uT */
    ImuSetPfHoldPrior,        /* 0 or 1 */
    ImuSetPfSettleSpread,     /* uT */
    ImuSetLagGyr,             /* s */
    ImuSetLagAcc,             /* s */
    ImuSetLagMag,             /* s */
    ImuSetMountX,             /* whole number */
    ImuSetMountY,             /* whole number */
    ImuSetMountZ,             /* whole number */
    IMU_SETTING_COUNT
} ImuSetting;
/* generated:end settings */

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
