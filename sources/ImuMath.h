/**
 * @file ImuMath.h
 * @brief Vectors, 3x3 rotation matrices (row-major double[9]), quaternions and ZYX Euler angles.
 *
 * Conventions (ARCHITECTURE.md): rotation matrices and quaternions rotate body -> nav
 * (v_nav = R v_body); quaternions are [w, x, y, z] Hamilton; Euler angles are ZYX
 * (R = Rz(yaw) Ry(pitch) Rx(roll)) in rad.
 */
#ifndef IMU_MATH_H
#define IMU_MATH_H

#include "ImuCommon.h"

#define IMU_PI 3.14159265358979323846

/** @brief Wrap an angle [rad] into (-pi, pi]; non-finite values pass through. */
IMU_HIDDEN double ImuWrapAngle(double angle);
/** @brief 1 if all n values are finite, else 0. */
IMU_HIDDEN int ImuAllFinite(const double *v, int n);
/** @brief Euclidean norm of a 3-vector (any unit). */
IMU_HIDDEN double ImuVectorNorm(const double v[3]);
/** @brief out = a b for row-major 3x3 matrices (out must not alias a or b). */
IMU_HIDDEN void ImuMatrixMultiply(const double a[9], const double b[9], double out[9]);
/** @brief out = a v for a row-major 3x3 matrix (out must not alias v). */
IMU_HIDDEN void ImuMatrixVector(const double a[9], const double v[3], double out[3]);
/** @brief Rodrigues: out = exp([w x] dt) for a rate w [rad/s] held over dt [s]. */
IMU_HIDDEN void ImuMatrixExp(const double w[3], double dt, double out[9]);
/** @brief Restore orthonormality of a nearly orthonormal rotation matrix (rows). */
IMU_HIDDEN void ImuMatrixOrthonormalise(double r[9]);
/** @brief Body-rate update R <- R exp([w x] dt), re-orthonormalised; w [rad/s], dt [s]. */
IMU_HIDDEN void ImuMatrixPropagate(double r[9], const double w[3], double dt);
/** @brief Rotation matrix body -> nav from ZYX Euler angles roll, pitch, yaw [rad]. */
IMU_HIDDEN void ImuMatrixFromEuler(double roll, double pitch, double yaw, double r[9]);
/** @brief ZYX Euler angles [roll, pitch, yaw] [rad] of a rotation matrix body -> nav. */
IMU_HIDDEN void ImuMatrixToEuler(const double r[9], double euler[3]);
/** @brief Unit quaternion [w, x, y, z] (w >= 0) of a rotation matrix body -> nav. */
IMU_HIDDEN void ImuQuaternionFromMatrix(const double r[9], double q[4]);

#endif
