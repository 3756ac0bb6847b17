/**
 * @file config.h
 * @brief Model identity and the value references of the ImuFusion FMU.
 *
 * The value references, their types and their array slots are generated from the variable table
 * (contract/variables.py) by `python -m contract.generate`; tests/test_generated.py fails when
 * they are stale. New variables take the next free value reference, so existing ones never change.
 */
#ifndef IMU_CONFIG_H
#define IMU_CONFIG_H

#define MODEL_NAME "ImuFusion"

/* generated:begin value-references (python -m contract.generate, from contract/variables.py; do not edit) */
/** Value references of every model variable. */
typedef enum {
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
    vr_aux_1 = 70,
    vr_aux_2 = 71,
    vr_aux_3 = 72,
    vr_aux_4 = 73,
    vr_lag_gyr = 74,
    vr_lag_acc = 75,
    vr_lag_mag = 76,
    vr_calibration_valid = 77,
    vr_mount_x = 78,
    vr_mount_y = 79,
    vr_mount_z = 80,
    vr_gyro_hold = 81,
    vr_mag_disturbed = 82,
    vr_mag_heading = 83,
    vr_motion_bias = 84,
    vr_acc_norm_tolerance = 85,
    vr_euler_additions = 86,
    vr_pf_additions = 87,
    vr_psobp_clamp = 88,
    vr_thermal_continuation = 89,
    vr_bias_learning = 90,
    vr_bias_learning_rate = 91,
    vr_bias_learning_limit = 92,
    vr_bias_learning_shift = 93,
    vr_q_sensor_w = 94,
    vr_q_sensor_x = 95,
    vr_q_sensor_y = 96,
    vr_q_sensor_z = 97
} ValueReference;

#define VR_COUNT 98

/** Parameters of type Boolean (FMI 3: Boolean). */
#define VR_IS_BOOLEAN(vr) ((vr) == vr_enable_thermal || (vr) == vr_enable_elm || (vr) == vr_enable_pf || (vr) == vr_enable_psobp || (vr) == vr_pf_rao_blackwell || (vr) == vr_pf_hold_prior || (vr) == vr_gyro_hold || (vr) == vr_mag_heading || (vr) == vr_motion_bias || (vr) == vr_pf_additions || (vr) == vr_psobp_clamp || (vr) == vr_thermal_continuation || (vr) == vr_bias_learning)
/** Parameters of type Integer (FMI 3: Int32), stored as whole numbers in the settings array. */
#define VR_IS_INTEGER(vr) ((vr) == vr_attitude_mode || (vr) == vr_pf_particles || (vr) == vr_pf_decimation || (vr) == vr_pf_seed || (vr) == vr_pf_sphere_bins || (vr) == vr_mount_x || (vr) == vr_mount_y || (vr) == vr_mount_z || (vr) == vr_euler_additions)

/** Where each value reference lives: {'i' inputs / 'o' outputs / 's' settings, array index}. */
#define IMU_VR_SLOTS { \
    {'i', ImuInGyrX}, \
    {'i', ImuInGyrY}, \
    {'i', ImuInGyrZ}, \
    {'i', ImuInAccX}, \
    {'i', ImuInAccY}, \
    {'i', ImuInAccZ}, \
    {'i', ImuInMagX}, \
    {'i', ImuInMagY}, \
    {'i', ImuInMagZ}, \
    {'i', ImuInTemp}, \
    {'o', ImuOutRateX}, \
    {'o', ImuOutRateY}, \
    {'o', ImuOutRateZ}, \
    {'o', ImuOutAccelX}, \
    {'o', ImuOutAccelY}, \
    {'o', ImuOutAccelZ}, \
    {'o', ImuOutFieldX}, \
    {'o', ImuOutFieldY}, \
    {'o', ImuOutFieldZ}, \
    {'o', ImuOutRoll}, \
    {'o', ImuOutPitch}, \
    {'o', ImuOutYaw}, \
    {'o', ImuOutHeading}, \
    {'o', ImuOutQW}, \
    {'o', ImuOutQX}, \
    {'o', ImuOutQY}, \
    {'o', ImuOutQZ}, \
    {'o', ImuOutGainRoll}, \
    {'o', ImuOutGainPitch}, \
    {'o', ImuOutGainYaw}, \
    {'o', ImuOutHardIronX}, \
    {'o', ImuOutHardIronY}, \
    {'o', ImuOutHardIronZ}, \
    {'o', ImuOutSoftIronXx}, \
    {'o', ImuOutSoftIronYy}, \
    {'o', ImuOutSoftIronZz}, \
    {'o', ImuOutPfNeff}, \
    {'s', ImuSetDeclination}, \
    {'s', ImuSetFieldNorm}, \
    {'s', ImuSetGyroNoise}, \
    {'s', ImuSetGyroBiasResidual}, \
    {'s', ImuSetMseTimeConstant}, \
    {'s', ImuSetAngleNoise}, \
    {'s', ImuSetEnableThermal}, \
    {'s', ImuSetAttitudeMode}, \
    {'s', ImuSetFieldDip}, \
    {'s', ImuSetTauAcc}, \
    {'s', ImuSetTauMag}, \
    {'s', ImuSetRestGyroThreshold}, \
    {'s', ImuSetRestAccThreshold}, \
    {'s', ImuSetMagRejectTime}, \
    {'s', ImuSetEnableElm}, \
    {'s', ImuSetEnablePf}, \
    {'s', ImuSetPfParticles}, \
    {'s', ImuSetPfMeasurementNoise}, \
    {'s', ImuSetPfProcessNoiseHard}, \
    {'s', ImuSetPfProcessNoiseSoft}, \
    {'s', ImuSetPfPriorSpreadHard}, \
    {'s', ImuSetPfPriorSpreadSoft}, \
    {'s', ImuSetPfDecimation}, \
    {'s', ImuSetPfSeed}, \
    {'s', ImuSetPfThresholdHigh}, \
    {'s', ImuSetPfThresholdLow}, \
    {'s', ImuSetPfSphereBins}, \
    {'s', ImuSetEnablePsobp}, \
    {'s', ImuSetPfRaoBlackwell}, \
    {'s', ImuSetPfMinRotation}, \
    {'s', ImuSetPfChangeSpreadHard}, \
    {'s', ImuSetPfHoldPrior}, \
    {'s', ImuSetPfSettleSpread}, \
    {'i', ImuInAux1}, \
    {'i', ImuInAux2}, \
    {'i', ImuInAux3}, \
    {'i', ImuInAux4}, \
    {'s', ImuSetLagGyr}, \
    {'s', ImuSetLagAcc}, \
    {'s', ImuSetLagMag}, \
    {'o', ImuOutCalibrationValid}, \
    {'s', ImuSetMountX}, \
    {'s', ImuSetMountY}, \
    {'s', ImuSetMountZ}, \
    {'s', ImuSetGyroHold}, \
    {'o', ImuOutMagDisturbed}, \
    {'s', ImuSetMagHeading}, \
    {'s', ImuSetMotionBias}, \
    {'s', ImuSetAccNormTolerance}, \
    {'s', ImuSetEulerAdditions}, \
    {'s', ImuSetPfAdditions}, \
    {'s', ImuSetPsobpClamp}, \
    {'s', ImuSetThermalContinuation}, \
    {'s', ImuSetBiasLearning}, \
    {'s', ImuSetBiasLearningRate}, \
    {'s', ImuSetBiasLearningLimit}, \
    {'o', ImuOutBiasLearningShift}, \
    {'o', ImuOutQSensorW}, \
    {'o', ImuOutQSensorX}, \
    {'o', ImuOutQSensorY}, \
    {'o', ImuOutQSensorZ} \
}
/** The value references of the inputs, in ImuInput order. */
#define IMU_INPUT_VRS {vr_gyr_x, vr_gyr_y, vr_gyr_z, vr_acc_x, vr_acc_y, vr_acc_z, vr_mag_x, vr_mag_y, vr_mag_z, vr_temp, vr_aux_1, vr_aux_2, vr_aux_3, vr_aux_4}
/** The value references of the outputs, in ImuOutput order. */
#define IMU_OUTPUT_VRS {vr_rate_x, vr_rate_y, vr_rate_z, vr_accel_x, vr_accel_y, vr_accel_z, vr_field_x, vr_field_y, vr_field_z, vr_roll, vr_pitch, vr_yaw, vr_heading, vr_q_w, vr_q_x, vr_q_y, vr_q_z, vr_gain_roll, vr_gain_pitch, vr_gain_yaw, vr_hard_iron_x, vr_hard_iron_y, vr_hard_iron_z, vr_soft_iron_xx, vr_soft_iron_yy, vr_soft_iron_zz, vr_pf_neff, vr_calibration_valid, vr_mag_disturbed, vr_bias_learning_shift, vr_q_sensor_w, vr_q_sensor_x, vr_q_sensor_y, vr_q_sensor_z}
/* generated:end value-references */

/* generated:begin coefficient-parameters (python -m contract.generate, from contract/coefficient_parameters.py; do not edit) */
/** FMI 2: value reference of the scalar parameter of coefficient 0; coefficient i has VR_COEFFICIENTS + i. */
#define VR_COEFFICIENTS 100000u
/** FMI 3: value reference of the array parameter of block 0; block b has VR_COEFFICIENT_BLOCKS + b. */
#define VR_COEFFICIENT_BLOCKS 200000u
/* generated:end coefficient-parameters */

/** FMI 3 only: the independent variable "time" [s], outside the variable table's range. */
#define VR_TIME 1000000u

#endif
