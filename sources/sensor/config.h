/**
 * @file config.h
 * @brief Model identity, value references and array layout of the virtual-sensor FMU (ImuSensor).
 *
 * Generated from its variable table (contract/sensor_variables.py) by `python -m contract.generate`;
 * tests/test_generated.py fails when stale. Staged in place of the ImuFusion config.h by fmu/sensor_fmu.py.
 */
#ifndef IMU_SENSOR_CONFIG_H
#define IMU_SENSOR_CONFIG_H

#define MODEL_NAME "ImuSensor"

/* generated:begin arrays (python -m contract.generate, from contract/sensor_variables.py; do not edit) */
typedef enum {
    SensorInTrueRateX,  /* rad/s */
    SensorInTrueRateY,  /* rad/s */
    SensorInTrueRateZ,  /* rad/s */
    SensorInTrueAccelX, /* m/s2 */
    SensorInTrueAccelY, /* m/s2 */
    SensorInTrueAccelZ, /* m/s2 */
    SensorInTrueQW,     /* 1 */
    SensorInTrueQX,     /* 1 */
    SensorInTrueQY,     /* 1 */
    SensorInTrueQZ,     /* 1 */
    SensorInTrueFieldX, /* uT */
    SensorInTrueFieldY, /* uT */
    SensorInTrueFieldZ, /* uT */
    SensorInTrueTemp,   /* degC */
    SensorInAux1,       /* 1 */
    SensorInAux2,       /* 1 */
    SensorInAux3,       /* 1 */
    SensorInAux4,       /* 1 */
    SENSOR_INPUT_COUNT
} SensorInput;

typedef enum {
    SensorOutGyrX, /* rad/s */
    SensorOutGyrY, /* rad/s */
    SensorOutGyrZ, /* rad/s */
    SensorOutAccX, /* m/s2 */
    SensorOutAccY, /* m/s2 */
    SensorOutAccZ, /* m/s2 */
    SensorOutMagX, /* uT */
    SensorOutMagY, /* uT */
    SensorOutMagZ, /* uT */
    SensorOutTemp, /* degC */
    SENSOR_OUTPUT_COUNT
} SensorOutput;

typedef enum {
    SensorSetSeed,                /* whole number */
    SensorSetNoise,               /* 0 or 1 */
    SensorSetFieldFromAttitude,   /* 0 or 1 */
    SensorSetFieldNorm,           /* uT */
    SensorSetFieldDip,            /* rad */
    SensorSetDeclination,         /* rad */
    SensorSetGyrNoiseDensityX,    /* rad/s/sqrt(Hz) */
    SensorSetGyrNoiseDensityY,    /* rad/s/sqrt(Hz) */
    SensorSetGyrNoiseDensityZ,    /* rad/s/sqrt(Hz) */
    SensorSetGyrBiasInstabilityX, /* rad/s */
    SensorSetGyrBiasInstabilityY, /* rad/s */
    SensorSetGyrBiasInstabilityZ, /* rad/s */
    SensorSetGyrRandomWalkX,      /* rad/s/sqrt(s) */
    SensorSetGyrRandomWalkY,      /* rad/s/sqrt(s) */
    SensorSetGyrRandomWalkZ,      /* rad/s/sqrt(s) */
    SensorSetAccNoiseDensityX,    /* m/s2/sqrt(Hz) */
    SensorSetAccNoiseDensityY,    /* m/s2/sqrt(Hz) */
    SensorSetAccNoiseDensityZ,    /* m/s2/sqrt(Hz) */
    SensorSetAccBiasInstabilityX, /* m/s2 */
    SensorSetAccBiasInstabilityY, /* m/s2 */
    SensorSetAccBiasInstabilityZ, /* m/s2 */
    SensorSetAccRandomWalkX,      /* m/s2/sqrt(s) */
    SensorSetAccRandomWalkY,      /* m/s2/sqrt(s) */
    SensorSetAccRandomWalkZ,      /* m/s2/sqrt(s) */
    SensorSetMagNoiseDensityX,    /* uT/sqrt(Hz) */
    SensorSetMagNoiseDensityY,    /* uT/sqrt(Hz) */
    SensorSetMagNoiseDensityZ,    /* uT/sqrt(Hz) */
    SensorSetMagBiasInstabilityX, /* uT */
    SensorSetMagBiasInstabilityY, /* uT */
    SensorSetMagBiasInstabilityZ, /* uT */
    SensorSetMagRandomWalkX,      /* uT/sqrt(s) */
    SensorSetMagRandomWalkY,      /* uT/sqrt(s) */
    SensorSetMagRandomWalkZ,      /* uT/sqrt(s) */
    SensorSetGyrLsb,              /* rad/s */
    SensorSetGyrFullScale,        /* rad/s */
    SensorSetAccLsb,              /* m/s2 */
    SensorSetAccFullScale,        /* m/s2 */
    SensorSetMagLsb,              /* uT */
    SensorSetMagFullScale,        /* uT */
    SENSOR_SETTING_COUNT
} SensorSetting;
/* generated:end arrays */

/* generated:begin value-references (python -m contract.generate, from contract/sensor_variables.py; do not edit) */
/** Value references of every model variable. */
typedef enum {
    vr_true_rate_x = 0,
    vr_true_rate_y = 1,
    vr_true_rate_z = 2,
    vr_true_accel_x = 3,
    vr_true_accel_y = 4,
    vr_true_accel_z = 5,
    vr_true_q_w = 6,
    vr_true_q_x = 7,
    vr_true_q_y = 8,
    vr_true_q_z = 9,
    vr_true_field_x = 10,
    vr_true_field_y = 11,
    vr_true_field_z = 12,
    vr_true_temp = 13,
    vr_aux_1 = 14,
    vr_aux_2 = 15,
    vr_aux_3 = 16,
    vr_aux_4 = 17,
    vr_gyr_x = 18,
    vr_gyr_y = 19,
    vr_gyr_z = 20,
    vr_acc_x = 21,
    vr_acc_y = 22,
    vr_acc_z = 23,
    vr_mag_x = 24,
    vr_mag_y = 25,
    vr_mag_z = 26,
    vr_temp = 27,
    vr_seed = 28,
    vr_noise = 29,
    vr_field_from_attitude = 30,
    vr_field_norm = 31,
    vr_field_dip = 32,
    vr_declination = 33,
    vr_gyr_noise_density_x = 34,
    vr_gyr_noise_density_y = 35,
    vr_gyr_noise_density_z = 36,
    vr_gyr_bias_instability_x = 37,
    vr_gyr_bias_instability_y = 38,
    vr_gyr_bias_instability_z = 39,
    vr_gyr_random_walk_x = 40,
    vr_gyr_random_walk_y = 41,
    vr_gyr_random_walk_z = 42,
    vr_acc_noise_density_x = 43,
    vr_acc_noise_density_y = 44,
    vr_acc_noise_density_z = 45,
    vr_acc_bias_instability_x = 46,
    vr_acc_bias_instability_y = 47,
    vr_acc_bias_instability_z = 48,
    vr_acc_random_walk_x = 49,
    vr_acc_random_walk_y = 50,
    vr_acc_random_walk_z = 51,
    vr_mag_noise_density_x = 52,
    vr_mag_noise_density_y = 53,
    vr_mag_noise_density_z = 54,
    vr_mag_bias_instability_x = 55,
    vr_mag_bias_instability_y = 56,
    vr_mag_bias_instability_z = 57,
    vr_mag_random_walk_x = 58,
    vr_mag_random_walk_y = 59,
    vr_mag_random_walk_z = 60,
    vr_gyr_lsb = 61,
    vr_gyr_full_scale = 62,
    vr_acc_lsb = 63,
    vr_acc_full_scale = 64,
    vr_mag_lsb = 65,
    vr_mag_full_scale = 66
} ValueReference;

#define VR_COUNT 67

/** Parameters of type Boolean (FMI 3: Boolean). */
#define VR_IS_BOOLEAN(vr) ((vr) == vr_noise || (vr) == vr_field_from_attitude)
/** Parameters of type Integer (FMI 3: Int32), stored as whole numbers in the settings array. */
#define VR_IS_INTEGER(vr) ((vr) == vr_seed)

/** Where each value reference lives: {'i' inputs / 'o' outputs / 's' settings, array index}. */
#define SENSOR_VR_SLOTS { \
    {'i', SensorInTrueRateX}, \
    {'i', SensorInTrueRateY}, \
    {'i', SensorInTrueRateZ}, \
    {'i', SensorInTrueAccelX}, \
    {'i', SensorInTrueAccelY}, \
    {'i', SensorInTrueAccelZ}, \
    {'i', SensorInTrueQW}, \
    {'i', SensorInTrueQX}, \
    {'i', SensorInTrueQY}, \
    {'i', SensorInTrueQZ}, \
    {'i', SensorInTrueFieldX}, \
    {'i', SensorInTrueFieldY}, \
    {'i', SensorInTrueFieldZ}, \
    {'i', SensorInTrueTemp}, \
    {'i', SensorInAux1}, \
    {'i', SensorInAux2}, \
    {'i', SensorInAux3}, \
    {'i', SensorInAux4}, \
    {'o', SensorOutGyrX}, \
    {'o', SensorOutGyrY}, \
    {'o', SensorOutGyrZ}, \
    {'o', SensorOutAccX}, \
    {'o', SensorOutAccY}, \
    {'o', SensorOutAccZ}, \
    {'o', SensorOutMagX}, \
    {'o', SensorOutMagY}, \
    {'o', SensorOutMagZ}, \
    {'o', SensorOutTemp}, \
    {'s', SensorSetSeed}, \
    {'s', SensorSetNoise}, \
    {'s', SensorSetFieldFromAttitude}, \
    {'s', SensorSetFieldNorm}, \
    {'s', SensorSetFieldDip}, \
    {'s', SensorSetDeclination}, \
    {'s', SensorSetGyrNoiseDensityX}, \
    {'s', SensorSetGyrNoiseDensityY}, \
    {'s', SensorSetGyrNoiseDensityZ}, \
    {'s', SensorSetGyrBiasInstabilityX}, \
    {'s', SensorSetGyrBiasInstabilityY}, \
    {'s', SensorSetGyrBiasInstabilityZ}, \
    {'s', SensorSetGyrRandomWalkX}, \
    {'s', SensorSetGyrRandomWalkY}, \
    {'s', SensorSetGyrRandomWalkZ}, \
    {'s', SensorSetAccNoiseDensityX}, \
    {'s', SensorSetAccNoiseDensityY}, \
    {'s', SensorSetAccNoiseDensityZ}, \
    {'s', SensorSetAccBiasInstabilityX}, \
    {'s', SensorSetAccBiasInstabilityY}, \
    {'s', SensorSetAccBiasInstabilityZ}, \
    {'s', SensorSetAccRandomWalkX}, \
    {'s', SensorSetAccRandomWalkY}, \
    {'s', SensorSetAccRandomWalkZ}, \
    {'s', SensorSetMagNoiseDensityX}, \
    {'s', SensorSetMagNoiseDensityY}, \
    {'s', SensorSetMagNoiseDensityZ}, \
    {'s', SensorSetMagBiasInstabilityX}, \
    {'s', SensorSetMagBiasInstabilityY}, \
    {'s', SensorSetMagBiasInstabilityZ}, \
    {'s', SensorSetMagRandomWalkX}, \
    {'s', SensorSetMagRandomWalkY}, \
    {'s', SensorSetMagRandomWalkZ}, \
    {'s', SensorSetGyrLsb}, \
    {'s', SensorSetGyrFullScale}, \
    {'s', SensorSetAccLsb}, \
    {'s', SensorSetAccFullScale}, \
    {'s', SensorSetMagLsb}, \
    {'s', SensorSetMagFullScale} \
}
/** The value references of the inputs, in SensorInput order. */
#define SENSOR_INPUT_VRS {vr_true_rate_x, vr_true_rate_y, vr_true_rate_z, vr_true_accel_x, vr_true_accel_y, vr_true_accel_z, vr_true_q_w, vr_true_q_x, vr_true_q_y, vr_true_q_z, vr_true_field_x, vr_true_field_y, vr_true_field_z, vr_true_temp, vr_aux_1, vr_aux_2, vr_aux_3, vr_aux_4}
/** The value references of the outputs, in SensorOutput order. */
#define SENSOR_OUTPUT_VRS {vr_gyr_x, vr_gyr_y, vr_gyr_z, vr_acc_x, vr_acc_y, vr_acc_z, vr_mag_x, vr_mag_y, vr_mag_z, vr_temp}
/* generated:end value-references */

/** Declared range of one parameter: [min, max], whether it must be a whole number, the message when not. */
typedef struct {
    double min, max;
    int whole;
    const char *message;
} SensorSettingRange;

/* generated:begin setting-ranges (python -m contract.generate, from contract/sensor_variables.py; do not edit) */
/** Declared range of every parameter, in SensorSetting order (SensorSettingRange). */
#define SENSOR_SETTING_RANGES { \
    {0.0, 2147483647.0, 1, "seed must be within [0, 2147483647]"}, \
    {0.0, 1.0, 1, "noise must be within [0, 1]"}, \
    {0.0, 1.0, 1, "field_from_attitude must be within [0, 1]"}, \
    {5.0, 1000.0, 0, "field_norm must be finite and within [5, 1000] uT"}, \
    {-1.5707963267948966, 1.5707963267948966, 0, "field_dip must be finite and within [-1.570796327, 1.570796327] rad"}, \
    {-3.141592653589793, 3.141592653589793, 0, "declination must be finite and within [-3.141592654, 3.141592654] rad"}, \
    {0.0, 1.0, 0, "gyr_noise_density_x must be finite and within [0, 1] rad/s/sqrt(Hz)"}, \
    {0.0, 1.0, 0, "gyr_noise_density_y must be finite and within [0, 1] rad/s/sqrt(Hz)"}, \
    {0.0, 1.0, 0, "gyr_noise_density_z must be finite and within [0, 1] rad/s/sqrt(Hz)"}, \
    {0.0, 1.0, 0, "gyr_bias_instability_x must be finite and within [0, 1] rad/s"}, \
    {0.0, 1.0, 0, "gyr_bias_instability_y must be finite and within [0, 1] rad/s"}, \
    {0.0, 1.0, 0, "gyr_bias_instability_z must be finite and within [0, 1] rad/s"}, \
    {0.0, 1.0, 0, "gyr_random_walk_x must be finite and within [0, 1] rad/s/sqrt(s)"}, \
    {0.0, 1.0, 0, "gyr_random_walk_y must be finite and within [0, 1] rad/s/sqrt(s)"}, \
    {0.0, 1.0, 0, "gyr_random_walk_z must be finite and within [0, 1] rad/s/sqrt(s)"}, \
    {0.0, 10.0, 0, "acc_noise_density_x must be finite and within [0, 10] m/s2/sqrt(Hz)"}, \
    {0.0, 10.0, 0, "acc_noise_density_y must be finite and within [0, 10] m/s2/sqrt(Hz)"}, \
    {0.0, 10.0, 0, "acc_noise_density_z must be finite and within [0, 10] m/s2/sqrt(Hz)"}, \
    {0.0, 10.0, 0, "acc_bias_instability_x must be finite and within [0, 10] m/s2"}, \
    {0.0, 10.0, 0, "acc_bias_instability_y must be finite and within [0, 10] m/s2"}, \
    {0.0, 10.0, 0, "acc_bias_instability_z must be finite and within [0, 10] m/s2"}, \
    {0.0, 10.0, 0, "acc_random_walk_x must be finite and within [0, 10] m/s2/sqrt(s)"}, \
    {0.0, 10.0, 0, "acc_random_walk_y must be finite and within [0, 10] m/s2/sqrt(s)"}, \
    {0.0, 10.0, 0, "acc_random_walk_z must be finite and within [0, 10] m/s2/sqrt(s)"}, \
    {0.0, 100.0, 0, "mag_noise_density_x must be finite and within [0, 100] uT/sqrt(Hz)"}, \
    {0.0, 100.0, 0, "mag_noise_density_y must be finite and within [0, 100] uT/sqrt(Hz)"}, \
    {0.0, 100.0, 0, "mag_noise_density_z must be finite and within [0, 100] uT/sqrt(Hz)"}, \
    {0.0, 100.0, 0, "mag_bias_instability_x must be finite and within [0, 100] uT"}, \
    {0.0, 100.0, 0, "mag_bias_instability_y must be finite and within [0, 100] uT"}, \
    {0.0, 100.0, 0, "mag_bias_instability_z must be finite and within [0, 100] uT"}, \
    {0.0, 100.0, 0, "mag_random_walk_x must be finite and within [0, 100] uT/sqrt(s)"}, \
    {0.0, 100.0, 0, "mag_random_walk_y must be finite and within [0, 100] uT/sqrt(s)"}, \
    {0.0, 100.0, 0, "mag_random_walk_z must be finite and within [0, 100] uT/sqrt(s)"}, \
    {0.0, 1000.0, 0, "gyr_lsb must be finite and within [0, 1000] rad/s"}, \
    {0.0, 1000.0, 0, "gyr_full_scale must be finite and within [0, 1000] rad/s"}, \
    {0.0, 10000.0, 0, "acc_lsb must be finite and within [0, 10000] m/s2"}, \
    {0.0, 10000.0, 0, "acc_full_scale must be finite and within [0, 10000] m/s2"}, \
    {0.0, 100000.0, 0, "mag_lsb must be finite and within [0, 100000] uT"}, \
    {0.0, 100000.0, 0, "mag_full_scale must be finite and within [0, 100000] uT"} \
}
/* generated:end setting-ranges */

/** FMI 3 only: the independent variable "time" [s], outside the variable table's range. */
#define VR_TIME 1000000u

#endif
