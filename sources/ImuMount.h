/**
 * @file ImuMount.h
 * @brief Mounting: the sensor's axes turned into the body axes by a signed axis permutation.
 *
 * Settings mount_x, mount_y, mount_z name the sensor axis that each body axis is, with its sign:
 * 1 = +x, 2 = +y, 3 = +z, -1 = -x, -2 = -y, -3 = -z. The body axes are FRD (x forward, y right,
 * z down), so a sensor at rest and level in the body reads a specific force of -g on body z. A
 * board whose z axis points up (at rest it reads +g on z) with x forward is mounted as
 * (1, -2, -3): a 180 deg turn about x. The three codes must name three different axes and keep
 * the axes right-handed (a proper rotation): a mirror would turn every attitude inside out.
 * The calibration (thermal, terms, particle filter, ELM) acts in the sensor's axes; the
 * mounting turns its result into the body axes, in which the attitude is estimated and every
 * vector output is given (body axes = sensor axes turned by mount_x..z); the outputs q_sensor_* give
 * the attitude of the sensor axes, q_body * ImuMountQuaternion. Identity (1, 2, 3) passes every value
 * unchanged, bit for bit.
 */
#ifndef IMU_MOUNT_H
#define IMU_MOUNT_H

#include "ImuCommon.h"

/** Body axis i is sign[i] times sensor axis axis[i] (0 = x, 1 = y, 2 = z). */
typedef struct {
    int axis[3];
    double sign[3];
} ImuMount;

/** @brief Mounting from the codes of mount_x, mount_y, mount_z; -1 (nothing set) when a code is not
 *         a whole number in {-3, -2, -1, 1, 2, 3} or the three do not form a proper rotation, else 0. */
IMU_HIDDEN int ImuMountFromCodes(ImuMount *m, const double codes[3]);
/** @brief The identity mounting (body axes = sensor axes). */
IMU_HIDDEN void ImuMountIdentity(ImuMount *m);
/** @brief 1 if every axis index of m is 0..2, the three differ and every sign is +-1, else 0. */
IMU_HIDDEN int ImuMountValid(const ImuMount *m);
/** @brief Turn the sensor-axes vector v[3] (any unit) into body axes, in place. */
IMU_HIDDEN void ImuMountVector(const ImuMount *m, double v[3]);
/** @brief Turn the body-axes vector v[3] (any unit) back into sensor axes, in place (the inverse of ImuMountVector). */
IMU_HIDDEN void ImuMountVectorInverse(const ImuMount *m, double v[3]);
/** @brief The unit quaternion [w, x, y, z] of the turn from sensor to body axes: its rotation matrix is M
 *         (v_body = M v_sensor), so q_sensor = q_body * q turns a body -> nav attitude into sensor -> nav. */
IMU_HIDDEN void ImuMountQuaternion(const ImuMount *m, double q[4]);
/** @brief Permute the diagonal d[3] of a sensor-axes matrix into body axes, in place (no signs:
 *         the diagonal of M D M^T for a signed permutation M). */
IMU_HIDDEN void ImuMountDiagonal(const ImuMount *m, double d[3]);

#endif
