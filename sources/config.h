/**
 * @file config.h
 * @brief Model identity and the value references of the ImuFusion FMU.
 *
 * The value references mirror the variable table in contract/variables.py (tests/test_fmu.py pins
 * the two together). Each group is contiguous and in the order of ImuLayout.h, so model.c maps
 * a value reference to an array index by subtracting the group's first value reference and adding
 * the group's first array index. Variables added by later layout versions form new groups after
 * the last value reference, so existing value references never change.
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
    vr_hard_iron_x = 30,
    vr_hard_iron_y = 31,
    vr_hard_iron_z = 32,
    vr_soft_iron_xx = 33,
    vr_soft_iron_yy = 34,
    vr_soft_iron_zz = 35,
    vr_pf_neff = 36,
    /* parameters: settings (ImuSetting order) */
    vr_declination = 37,
    vr_field_norm = 38,
    vr_gyro_noise = 39,
    vr_gyro_bias_residual = 40,
    vr_mse_time_constant = 41,
    vr_angle_noise = 42,
    vr_enable_thermal = 43,
    vr_attitude_mode = 44,
    vr_field_dip = 45,
    vr_tau_acc = 46,
    vr_tau_mag = 47,
    vr_rest_gyro_threshold = 48,
    vr_rest_acc_threshold = 49,
    vr_mag_reject_time = 50,
    vr_enable_elm = 51,
    vr_enable_pf = 52,
    vr_pf_particles = 53,
    vr_pf_measurement_noise = 54,
    vr_pf_process_noise_hard = 55,
    vr_pf_process_noise_soft = 56,
    vr_pf_prior_spread_hard = 57,
    vr_pf_prior_spread_soft = 58,
    vr_pf_decimation = 59,
    vr_pf_seed = 60,
    vr_pf_threshold_high = 61,
    vr_pf_threshold_low = 62,
    vr_pf_sphere_bins = 63,
    vr_enable_psobp = 64,
    vr_pf_rao_blackwell = 65,
    vr_pf_min_rotation = 66,
    vr_pf_change_spread_hard = 67,
    vr_pf_hold_prior = 68,
    vr_pf_settle_spread = 69,
    /* inputs (layout version 3): auxiliary inputs (ImuInAux1..) */
    vr_aux_1 = 70,
    vr_aux_2 = 71,
    vr_aux_3 = 72,
    vr_aux_4 = 73,
    /* parameters (layout version 3): triad lags (ImuSetLagGyr..) */
    vr_lag_gyr = 74,
    vr_lag_acc = 75,
    vr_lag_mag = 76,
    /* outputs (layout version 4): calibrated-range flag (ImuOutCalibrationValid) */
    vr_calibration_valid = 77,
    /* parameters (layout version 4): mounting, sensor -> body axes (ImuSetMountX..) */
    vr_mount_x = 78,
    vr_mount_y = 79,
    vr_mount_z = 80
} ValueReference;

/** Parameters of type Boolean; every other variable is Real (FMI 3: Float64) unless VR_IS_INTEGER. */
#define VR_IS_BOOLEAN(vr) ((vr) == vr_enable_thermal || (vr) == vr_enable_elm || (vr) == vr_enable_pf || (vr) == vr_enable_psobp || (vr) == vr_pf_rao_blackwell || (vr) == vr_pf_hold_prior)
/** Parameters of type Integer (FMI 3: Int32), stored as whole numbers in the settings array. */
#define VR_IS_INTEGER(vr) ((vr) == vr_attitude_mode || (vr) == vr_pf_particles || (vr) == vr_pf_decimation || (vr) == vr_pf_seed || (vr) == vr_pf_sphere_bins || (vr) == vr_mount_x || (vr) == vr_mount_y || (vr) == vr_mount_z)

/** FMI 3 only: the independent variable "time" [s], outside the variable table's range. */
#define VR_TIME 1000000u

#define VR_FIRST_INPUT vr_gyr_x
#define VR_FIRST_OUTPUT vr_rate_x
#define VR_FIRST_SETTING vr_declination
#define VR_FIRST_AUX vr_aux_1
#define VR_FIRST_LAG vr_lag_gyr
#define VR_FIRST_VALIDITY vr_calibration_valid
#define VR_FIRST_MOUNT vr_mount_x
#define VR_COUNT (vr_mount_z + 1)

#endif
