/**
 * @file ImuQuaternion.h
 * @brief Unit quaternions [w, x, y, z], Hamilton, rotating body -> nav (v_nav = q v_body q*).
 */
#ifndef IMU_QUATERNION_H
#define IMU_QUATERNION_H

#include "ImuCommon.h"

/** @brief out = a (x) b (out may alias neither). */
IMU_HIDDEN void ImuQuaternionMultiply(const double a[4], const double b[4], double out[4]);
/** @brief out = q v q* for a 3-vector v (any unit; out must not alias v). */
IMU_HIDDEN void ImuQuaternionRotate(const double q[4], const double v[3], double out[3]);
/** @brief Scale q to unit norm (identity if its norm is zero or not finite). */
IMU_HIDDEN void ImuQuaternionNormalise(double q[4]);
/** @brief Body-rate update q <- q (x) exp(w dt / 2), normalised; w [rad/s], dt [s]. */
IMU_HIDDEN void ImuQuaternionIntegrate(double q[4], const double w[3], double dt);
/** @brief Rotation matrix (row-major, body -> nav) of a unit quaternion. */
IMU_HIDDEN void ImuQuaternionToMatrix(const double q[4], double r[9]);
/** @brief q <- Rz(angle) (x) q: turn the nav frame about its z axis by angle [rad]. */
IMU_HIDDEN void ImuQuaternionTurnNav(double q[4], double angle);

#endif
