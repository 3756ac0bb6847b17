/**
 * @file ImuRestDetector.h
 * @brief Rest detection on gyro and accelerometer, and the gyro bias it measures.
 *
 * Both signals are low-passed (time constant IMU_REST_FILTER_TIME). The sensor is at rest when,
 * for at least IMU_REST_MIN_TIME, every sample stays within the gyro threshold of the low-passed
 * rate, the low-passed rate itself is within the threshold on every axis (so a bias up to the
 * threshold is allowed, a slow turn is not) and every specific-force sample stays within the
 * accelerometer threshold of its low-passed value. At rest the low-passed rate is the bias.
 */
#ifndef IMU_REST_DETECTOR_H
#define IMU_REST_DETECTOR_H

#include "ImuCommon.h"

/** Time constant [s] of the low-pass filters of rate and specific force. */
#define IMU_REST_FILTER_TIME 0.5
/** Time [s] the thresholds must hold before the sensor counts as at rest. */
#define IMU_REST_MIN_TIME 1.5

/** Evolving state (plain struct). */
typedef struct {
    double gyrLp[3];  /* rad/s, low-passed rate */
    double accLp[3];  /* m/s^2, low-passed specific force */
    double restTime;  /* s, time the thresholds have held */
    int initialised;  /* the filters hold a first sample */
} ImuRestDetector;

/** @brief Forget everything (not at rest). */
IMU_HIDDEN void ImuRestDetectorReset(ImuRestDetector *r);
/**
 * @brief Feed one finite sample gyr [rad/s], acc [m/s^2] after dt [s] with thresholds gyroThreshold
 *        [rad/s] and accThreshold [m/s^2]. @return 1 at rest, else 0.
 */
IMU_HIDDEN int ImuRestDetectorUpdate(ImuRestDetector *r, const double gyr[3], const double acc[3], double dt,
                                     double gyroThreshold, double accThreshold);
/**
 * @brief As ImuRestDetectorUpdate, the low-passed rate checked against biasThreshold [rad/s] instead of
 *        gyroThreshold (the bias a rest may carry; the samples' spread is still held to gyroThreshold).
 */
IMU_HIDDEN int ImuRestDetectorUpdateBias(ImuRestDetector *r, const double gyr[3], const double acc[3], double dt,
                                         double gyroThreshold, double biasThreshold, double accThreshold);
/** @brief Low-passed rate [rad/s]: the gyro bias while at rest. */
IMU_HIDDEN void ImuRestDetectorGetRate(const ImuRestDetector *r, double rate[3]);

#endif
