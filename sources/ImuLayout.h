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
    ImuOutRateX,             /* rad/s */
    ImuOutRateY,             /* rad/s */
    ImuOutRateZ,             /* rad/s */
    ImuOutAccelX,            /* m/s2 */
    ImuOutAccelY,            /* m/s2 */
    ImuOutAccelZ,            /* m/s2 */
    ImuOutFieldX,            /* uT */
    ImuOutFieldY,            /* uT */
    ImuOutFieldZ,            /* uT */
    ImuOutRoll,              /* rad */
    ImuOutPitch,             /* rad */
    ImuOutYaw,               /* rad */
    ImuOutHeading,           /* rad */
    ImuOutQW,                /* 1 */
    ImuOutQX,                /* 1 */
    ImuOutQY,                /* 1 */
    ImuOutQZ,                /* 1 */
    ImuOutGainRoll,          /* 1 */
    ImuOutGainPitch,         /* 1 */
    ImuOutGainYaw,           /* 1 */
    ImuOutHardIronX,         /* uT */
    ImuOutHardIronY,         /* uT */
    ImuOutHardIronZ,         /* uT */
    ImuOutSoftIronXx,        /* 1 */
    ImuOutSoftIronYy,        /* 1 */
    ImuOutSoftIronZz,        /* 1 */
    ImuOutPfNeff,            /* 1 */
    ImuOutCalibrationValid,  /* 1 */
    ImuOutMagDisturbed,      /* 1 */
    ImuOutBiasLearningShift, /* rad/s */
    ImuOutQSensorW,          /* 1 */
    ImuOutQSensorX,          /* 1 */
    ImuOutQSensorY,          /* 1 */
    ImuOutQSensorZ,          /* 1 */
    IMU_OUTPUT_COUNT
} ImuOutput;
/* generated:end outputs */

/** Settings (FMU parameters) in the flat settings array. */
/* generated:begin settings (python -m contract.generate, from contract/variables.py; do not edit) */
typedef enum {
    ImuSetDeclination,         /* rad */
    ImuSetFieldNorm,           /* uT */
    ImuSetGyroNoise,           /* rad/s/sqrt(Hz) */
    ImuSetGyroBiasResidual,    /* rad/s */
    ImuSetMseTimeConstant,     /* s */
    ImuSetAngleNoise,          /* rad */
    ImuSetEnableThermal,       /* 0 or 1 */
    ImuSetAttitudeMode,        /* whole number */
    ImuSetFieldDip,            /* rad */
    ImuSetTauAcc,              /* s */
    ImuSetTauMag,              /* s */
    ImuSetRestGyroThreshold,   /* rad/s */
    ImuSetRestAccThreshold,    /* m/s2 */
    ImuSetMagRejectTime,       /* s */
    ImuSetEnableElm,           /* 0 or 1 */
    ImuSetEnablePf,            /* 0 or 1 */
    ImuSetPfParticles,         /* whole number */
    ImuSetPfMeasurementNoise,  /* uT */
    ImuSetPfProcessNoiseHard,  /* uT */
    ImuSetPfProcessNoiseSoft,  /* 1 */
    ImuSetPfPriorSpreadHard,   /* uT */
    ImuSetPfPriorSpreadSoft,   /* 1 */
    ImuSetPfDecimation,        /* whole number */
    ImuSetPfSeed,              /* whole number */
    ImuSetPfThresholdHigh,     /* 1 */
    ImuSetPfThresholdLow,      /* 1 */
    ImuSetPfSphereBins,        /* whole number */
    ImuSetEnablePsobp,         /* 0 or 1 */
    ImuSetPfRaoBlackwell,      /* 0 or 1 */
    ImuSetPfMinRotation,       /* rad */
    ImuSetPfChangeSpreadHard,  /* uT */
    ImuSetPfHoldPrior,         /* 0 or 1 */
    ImuSetPfSettleSpread,      /* uT */
    ImuSetLagGyr,              /* s */
    ImuSetLagAcc,              /* s */
    ImuSetLagMag,              /* s */
    ImuSetMountX,              /* whole number */
    ImuSetMountY,              /* whole number */
    ImuSetMountZ,              /* whole number */
    ImuSetGyroHold,            /* 0 or 1 */
    ImuSetMagHeading,          /* 0 or 1 */
    ImuSetMotionBias,          /* 0 or 1 */
    ImuSetAccNormTolerance,    /* 1 */
    ImuSetEulerAdditions,      /* whole number */
    ImuSetPfAdditions,         /* 0 or 1 */
    ImuSetPsobpClamp,          /* 0 or 1 */
    ImuSetThermalContinuation, /* 0 or 1 */
    ImuSetBiasLearning,        /* 0 or 1 */
    ImuSetBiasLearningRate,    /* 1/s */
    ImuSetBiasLearningLimit,   /* rad/s */
    IMU_SETTING_COUNT
} ImuSetting;
/* generated:end settings */

/** Flags of a declared setting range. */
enum {
    IMU_RANGE_MIN_OPEN = 1, /* the minimum itself is refused */
    IMU_RANGE_MAX_OPEN = 2, /* the maximum itself is refused */
    IMU_RANGE_WHOLE = 4,    /* a whole number (Integer and Boolean settings) */
    IMU_RANGE_NONZERO = 8   /* 0 is refused */
};

/** Declared range of a setting [its unit] and the message naming it when a value is outside. */
typedef struct {
    double min;
    double max;
    int flags;           /* IMU_RANGE_* bits */
    const char *problem; /* "<name> must be ..." */
} ImuSettingRange;

/* generated:begin setting-ranges (python -m contract.generate, from contract/variables.py; do not edit) */
/** Declared range of every setting, in ImuSetting order (ImuSettingRange). */
#define IMU_SETTING_RANGES { \
    {-3.141592653589793, 3.141592653589793, 0, "declination must be finite and within [-3.141593, 3.141593] rad"}, \
    {5.0, 1000.0, 0, "field_norm must be finite and within [5, 1000] uT"}, \
    {0.0, 0.1, 0, "gyro_noise must be finite and within [0, 0.1] rad/s/sqrt(Hz)"}, \
    {0.0, 1.0, 0, "gyro_bias_residual must be finite and within [0, 1] rad/s"}, \
    {0.0, 86400.0, 1, "mse_time_constant must be finite and within (0, 86400] s"}, \
    {0.0, 3.141592653589793, 1, "angle_noise must be finite and within (0, 3.141593] rad"}, \
    {0.0, 1.0, 4, "enable_thermal must be 0 or 1"}, \
    {0.0, 1.0, 4, "attitude_mode must be a whole number in 0..1"}, \
    {-1.5707963267948966, 1.5707963267948966, 0, "field_dip must be finite and within [-1.570796, 1.570796] rad"}, \
    {0.0, 86400.0, 1, "tau_acc must be finite and within (0, 86400] s"}, \
    {0.0, 86400.0, 1, "tau_mag must be finite and within (0, 86400] s"}, \
    {0.0, 1.0, 0, "rest_gyro_threshold must be finite and within [0, 1] rad/s"}, \
    {0.0, 9.80665, 1, "rest_acc_threshold must be finite and within (0, 9.80665] m/s2"}, \
    {0.0, 86400.0, 0, "mag_reject_time must be finite and within [0, 86400] s"}, \
    {0.0, 1.0, 4, "enable_elm must be 0 or 1"}, \
    {0.0, 1.0, 4, "enable_pf must be 0 or 1"}, \
    {2.0, 512.0, 4, "pf_particles must be a whole number in 2..512"}, \
    {0.0, 100.0, 1, "pf_measurement_noise must be finite and within (0, 100] uT"}, \
    {0.0, 100.0, 0, "pf_process_noise_hard must be finite and within [0, 100] uT"}, \
    {0.0, 1.0, 0, "pf_process_noise_soft must be finite and within [0, 1]"}, \
    {0.0, 10000.0, 0, "pf_prior_spread_hard must be finite and within [0, 10000] uT"}, \
    {0.0, 1.0, 0, "pf_prior_spread_soft must be finite and within [0, 1]"}, \
    {1.0, 1000.0, 4, "pf_decimation must be a whole number in 1..1000"}, \
    {0.0, 2147483647.0, 4, "pf_seed must be a whole number in 0..2147483647"}, \
    {1.0, 100.0, 1, "pf_threshold_high must be finite and within (1, 100]"}, \
    {0.0, 1.0, 3, "pf_threshold_low must be finite and within (0, 1)"}, \
    {0.0, 4.0, 4, "pf_sphere_bins must be a whole number in 0..4"}, \
    {0.0, 1.0, 4, "enable_psobp must be 0 or 1"}, \
    {0.0, 1.0, 4, "pf_rao_blackwell must be 0 or 1"}, \
    {0.0, 1.5707963267948966, 0, "pf_min_rotation must be finite and within [0, 1.570796] rad"}, \
    {0.0, 10000.0, 0, "pf_change_spread_hard must be finite and within [0, 10000] uT"}, \
    {0.0, 1.0, 4, "pf_hold_prior must be 0 or 1"}, \
    {0.0, 10000.0, 0, "pf_settle_spread must be finite and within [0, 10000] uT"}, \
    {-1.0, 1.0, 0, "lag_gyr must be finite and within [-1, 1] s"}, \
    {-1.0, 1.0, 0, "lag_acc must be finite and within [-1, 1] s"}, \
    {-1.0, 1.0, 0, "lag_mag must be finite and within [-1, 1] s"}, \
    {-3.0, 3.0, 12, "mount_x must be a whole number in -3..3 other than 0"}, \
    {-3.0, 3.0, 12, "mount_y must be a whole number in -3..3 other than 0"}, \
    {-3.0, 3.0, 12, "mount_z must be a whole number in -3..3 other than 0"}, \
    {0.0, 1.0, 4, "gyro_hold must be 0 or 1"}, \
    {0.0, 1.0, 4, "mag_heading must be 0 or 1"}, \
    {0.0, 1.0, 4, "motion_bias must be 0 or 1"}, \
    {0.0, 1.0, 0, "acc_norm_tolerance must be finite and within [0, 1]"}, \
    {0.0, 63.0, 4, "euler_additions must be a whole number in 0..63"}, \
    {0.0, 1.0, 4, "pf_additions must be 0 or 1"}, \
    {0.0, 1.0, 4, "psobp_clamp must be 0 or 1"}, \
    {0.0, 1.0, 4, "thermal_continuation must be 0 or 1"}, \
    {0.0, 1.0, 4, "bias_learning must be 0 or 1"}, \
    {0.0, 1.0, 1, "bias_learning_rate must be finite and within (0, 1] 1/s"}, \
    {0.0, 1.0, 0, "bias_learning_limit must be finite and within [0, 1] rad/s"} \
}
/* generated:end setting-ranges */

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

/** One block of the coefficient array, as the FMU exposes it (contract/coefficient_parameters.py). */
typedef struct {
    int offset;          /* first index in the coefficient array */
    int size;            /* number of coefficients */
    const char *name;    /* the FMU parameter that carries it */
    const char *problem; /* the runtime's message when it does not fit the layout */
} ImuCoefficientBlock;

/* generated:begin coefficient-blocks (python -m contract.generate, from contract/coefficient_parameters.py; do not edit) */
#define IMU_COEFFICIENT_BLOCK_COUNT 7
/** {first index, length, parameter name, the runtime's message when the block is invalid} of every
 *  coefficient block, in array order (ImuCoefficientBlock). */
#define IMU_COEFFICIENT_BLOCKS { \
    {0, 1, "calibration.layout_version", "calibration.layout_version is not this FMU's coefficient layout version"}, \
    {1, 37, "calibration.thermal_gyr", "calibration.thermal_gyr does not fit the coefficient layout (a flag, degree, count, index or range outside what the block allows, or a value it uses not finite)"}, \
    {38, 37, "calibration.thermal_acc", "calibration.thermal_acc does not fit the coefficient layout (a flag, degree, count, index or range outside what the block allows, or a value it uses not finite)"}, \
    {75, 37, "calibration.thermal_mag", "calibration.thermal_mag does not fit the coefficient layout (a flag, degree, count, index or range outside what the block allows, or a value it uses not finite)"}, \
    {112, 385, "calibration.terms", "calibration.terms does not fit the coefficient layout (a flag, degree, count, index or range outside what the block allows, or a value it uses not finite)"}, \
    {497, 463, "calibration.elm", "calibration.elm does not fit the coefficient layout (a flag, degree, count, index or range outside what the block allows, or a value it uses not finite)"}, \
    {960, 202, "calibration.psobp", "calibration.psobp does not fit the coefficient layout (a flag, degree, count, index or range outside what the block allows, or a value it uses not finite)"} \
}
/* generated:end coefficient-blocks */

#endif
