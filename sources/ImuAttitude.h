/**
 * @file ImuAttitude.h
 * @brief Attitude by adaptive-gain fusion of two ZYX Euler sets: one from the gyro (rotation-
 *        matrix update), one from accelerometer (roll, pitch) and magnetometer (yaw).
 *
 * Angles are body -> magnetic NED; the gains come from the mean-square errors of the two sets
 * (gyro: propagated variance P; acc/mag: moving mean-square innovation R), K = P / (P + R).
 */
#ifndef IMU_ATTITUDE_H
#define IMU_ATTITUDE_H

#include "ImuCommon.h"

/** Standard gravity [m/s^2]: the specific-force norm at rest. */
#define IMU_ATTITUDE_GRAVITY 9.80665

/** Settings in user units. */
typedef struct {
    double gyroNoise;        /* rad/s/sqrt(Hz), white-noise density of the corrected gyro */
    double gyroBiasResidual; /* rad/s, residual gyro bias */
    double mseTimeConstant;  /* s, averaging time of the innovation mean-square errors (> 0) */
    double angleNoise;       /* rad, floor of the acc/mag angle error standard deviation (> 0) */
    double fieldNorm;        /* uT, local earth-field magnitude (> 0) */
} ImuAttitudeSettings;

/** Settings and evolving state (plain struct: copy = save state). */
typedef struct {
    ImuAttitudeSettings settings;
    double rotation[9];     /* 1, body -> magnetic NED, row-major, rebuilt from euler */
    double euler[3];        /* rad, fused roll, pitch, yaw in (-pi, pi] */
    double variance[3];     /* rad^2, P_i: mean-square error of the gyro-propagated angles */
    double mse[3];          /* rad^2, R_i: moving mean-square acc/mag innovation */
    double gain[3];         /* 1, K_i of the last update (0 where no correction was made) */
    double previousRate[3]; /* rad/s, corrected rate of the previous sample (may be NaN) */
    int tiltInitialised;    /* roll/pitch were set from the accelerometer */
    int yawInitialised;     /* yaw was set from the magnetometer */
} ImuAttitude;

/** @brief Set the settings and reset the state (level, yaw 0, nothing initialised). */
IMU_HIDDEN void ImuAttitudeInitialise(ImuAttitude *a, const ImuAttitudeSettings *s);
/** @brief Reset the state, keeping the settings. */
IMU_HIDDEN void ImuAttitudeReset(ImuAttitude *a);
/**
 * @brief Process one sample: gyr [rad/s], acc specific force [m/s^2], mag [uT] (corrected,
 *        body axes); dt [s] since the previous sample (0 on the first; no propagation if <= 0).
 */
IMU_HIDDEN void ImuAttitudeUpdate(ImuAttitude *a, const double gyr[3], const double acc[3],
                                  const double mag[3], double dt);
/** @brief Fused roll, pitch, yaw [rad], each in (-pi, pi]. */
IMU_HIDDEN void ImuAttitudeGetEuler(const ImuAttitude *a, double euler[3]);
/** @brief Attitude quaternion [w, x, y, z] body -> magnetic NED, w >= 0. */
IMU_HIDDEN void ImuAttitudeGetQuaternion(const ImuAttitude *a, double q[4]);
/** @brief Fusion gains [1] of roll, pitch, yaw from the last update. */
IMU_HIDDEN void ImuAttitudeGetGains(const ImuAttitude *a, double gains[3]);

#endif
