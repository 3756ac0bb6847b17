/**
 * @file config.h
 * @brief Model identity and the value references of the ImuFusion FMU.
 *
 * The value references mirror the variable table in fmu/variables.py (tests/test_fmu.py pins
 * the two together). Each group is contiguous and in the order of ImuLayout.h, so model.c maps
 * a value reference to an array index by subtracting the group's first value reference.
 */
#ifndef IMU_CONFIG_H
#define IMU_CONFIG_H

#define MODEL_NAME "ImuFusion"

/** Value references of every model variable. */
typedef enum {
    /* inputs: raw sample (ImuInput order) */
    vr_gyr_x = 0,
    vr_gyr_y = 1,
    vr_gyr_z = 2,
    vr_acc_x = 3,
    vr_acc_y = 4,
    vr_acc_z = 5,
    vr_mag_x = 6,
    vr_mag_y = 7,
    vr_mag_z = 8,
    vr_temp = 9,
    /* outputs: estimate for the last consumed sample (ImuOutput order) */
    vr_rate_x = 10,
    vr_rate_y = 11,
    vr_rate_z = 12,
    vr_accel_x = 13,
    vr_accel_y = 14,
    vr_accel_z = 15,
    vr_field_x = 16,
    vr_field_y = 17,
    vr_field_z = 18,
    vr_roll = 19,
    vr_pitch = 20,
    vr_yaw = 21,
    vr_heading = 22,
    vr_q_w = 23,
    vr_q_x = 24,
    vr_q_y = 25,
    vr_q_z = 26,
    vr_gain_roll = 27,
    vr_gain_pitch = 28,
    vr_gain_yaw = 29,
    /* parameters: settings (ImuSetting order) */
    vr_declination = 30,
    vr_field_norm = 31,
    vr_gyro_noise = 32,
    vr_gyro_bias_residual = 33,
    vr_mse_time_constant = 34,
    vr_angle_noise = 35,
    vr_enable_thermal = 36,
    vr_attitude_mode = 37,
    vr_field_dip = 38,
    vr_tau_acc = 39,
    vr_tau_mag = 40,
    vr_rest_gyro_threshold = 41,
    vr_rest_acc_threshold = 42,
    vr_mag_reject_time = 43,
    vr_enable_elm = 44
} ValueReference;

/** Parameters of type Boolean; every other variable is Real (FMI 3: Float64) unless VR_IS_INTEGER. */
#define VR_IS_BOOLEAN(vr) ((vr) == vr_enable_thermal || (vr) == vr_enable_elm)
/** Parameters of type Integer (FMI 3: Int32), stored as whole numbers in the settings array. */
#define VR_IS_INTEGER(vr) ((void)(vr), 0)

/** FMI 3 only: the independent variable "time" [s], outside the variable table's range. */
#define VR_TIME 1000000u

#define VR_FIRST_INPUT vr_gyr_x
#define VR_FIRST_OUTPUT vr_rate_x
#define VR_FIRST_SETTING vr_declination
#define VR_COUNT (vr_enable_elm + 1)

#endif
