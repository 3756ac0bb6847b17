/**
 * @file ImuMath.c
 * @brief Vectors, 3x3 rotation matrices, quaternions and ZYX Euler angles.
 */
#include <math.h>
#include "ImuMath.h"

/** @brief Wrap an angle [rad] into (-pi, pi]; non-finite values pass through. */
double ImuWrapAngle(double angle)
{
    double b;
    if (angle > -IMU_PI && angle <= IMU_PI) {
        return angle;
    }
    b = fmod(IMU_PI - angle, 2.0 * IMU_PI); /* in (-2 pi, 2 pi) */
    if (b < 0.0) {
        b += 2.0 * IMU_PI;
    }
    return IMU_PI - b;
}

/** @brief 1 if all n values are finite, else 0. */
int ImuAllFinite(const double *v, int n)
{
    int i;
    for (i = 0; i < n; i++) {
        if (!isfinite(v[i])) {
            return 0;
        }
    }
    return 1;
}

/** @brief Euclidean norm of a 3-vector (any unit). */
double ImuVectorNorm(const double v[3])
{
    return sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
}

/** @brief out = a b for row-major 3x3 matrices (out must not alias a or b). */
void ImuMatrixMultiply(const double a[9], const double b[9], double out[9])
{
    int i, j;
    for (i = 0; i < 3; i++) {
        for (j = 0; j < 3; j++) {
            out[3 * i + j] = a[3 * i] * b[j] + a[3 * i + 1] * b[3 + j] + a[3 * i + 2] * b[6 + j];
        }
    }
}

/** @brief out = a v for a row-major 3x3 matrix (out must not alias v). */
void ImuMatrixVector(const double a[9], const double v[3], double out[3])
{
    int i;
    for (i = 0; i < 3; i++) {
        out[i] = a[3 * i] * v[0] + a[3 * i + 1] * v[1] + a[3 * i + 2] * v[2];
    }
}

/** @brief Rodrigues: out = exp([w x] dt) for a rate w [rad/s] held over dt [s]. */
void ImuMatrixExp(const double w[3], double dt, double out[9])
{
    const double x = w[0] * dt, y = w[1] * dt, z = w[2] * dt;
    const double angle2 = x * x + y * y + z * z;
    double s, c; /* sin(a)/a and (1 - cos(a))/a^2, Taylor series for small angles */
    if (angle2 < 1e-8) {
        s = 1.0 - angle2 / 6.0;
        c = 0.5 - angle2 / 24.0;
    } else {
        const double angle = sqrt(angle2);
        s = sin(angle) / angle;
        c = (1.0 - cos(angle)) / angle2;
    }
    out[0] = 1.0 - c * (y * y + z * z);
    out[1] = c * x * y - s * z;
    out[2] = c * x * z + s * y;
    out[3] = c * x * y + s * z;
    out[4] = 1.0 - c * (x * x + z * z);
    out[5] = c * y * z - s * x;
    out[6] = c * x * z - s * y;
    out[7] = c * y * z + s * x;
    out[8] = 1.0 - c * (x * x + y * y);
}

/** @brief Restore orthonormality of a nearly orthonormal rotation matrix (rows). */
void ImuMatrixOrthonormalise(double r[9])
{
    /* Share the non-orthogonality of rows 0 and 1 equally, row 2 = row 0 x row 1, normalise. */
    const double e = 0.5 * (r[0] * r[3] + r[1] * r[4] + r[2] * r[5]);
    double x[3], y[3], n;
    int i;
    for (i = 0; i < 3; i++) {
        x[i] = r[i] - e * r[3 + i];
        y[i] = r[3 + i] - e * r[i];
    }
    r[6] = x[1] * y[2] - x[2] * y[1];
    r[7] = x[2] * y[0] - x[0] * y[2];
    r[8] = x[0] * y[1] - x[1] * y[0];
    for (i = 0; i < 3; i++) {
        r[i] = x[i];
        r[3 + i] = y[i];
    }
    for (i = 0; i < 3; i++) {
        n = ImuVectorNorm(&r[3 * i]);
        r[3 * i] /= n;
        r[3 * i + 1] /= n;
        r[3 * i + 2] /= n;
    }
}

/** @brief Body-rate update R <- R exp([w x] dt), re-orthonormalised; w [rad/s], dt [s]. */
void ImuMatrixPropagate(double r[9], const double w[3], double dt)
{
    double step[9], product[9];
    int i;
    ImuMatrixExp(w, dt, step);
    ImuMatrixMultiply(r, step, product);
    for (i = 0; i < 9; i++) {
        r[i] = product[i];
    }
    ImuMatrixOrthonormalise(r);
}

/** @brief Rotation matrix body -> nav from ZYX Euler angles roll, pitch, yaw [rad]. */
void ImuMatrixFromEuler(double roll, double pitch, double yaw, double r[9])
{
    const double cr = cos(roll), sr = sin(roll);
    const double cp = cos(pitch), sp = sin(pitch);
    const double cy = cos(yaw), sy = sin(yaw);
    r[0] = cp * cy;
    r[1] = sr * sp * cy - cr * sy;
    r[2] = cr * sp * cy + sr * sy;
    r[3] = cp * sy;
    r[4] = sr * sp * sy + cr * cy;
    r[5] = cr * sp * sy - sr * cy;
    r[6] = -sp;
    r[7] = sr * cp;
    r[8] = cr * cp;
}

/** @brief ZYX Euler angles [roll, pitch, yaw] [rad] of a rotation matrix body -> nav. */
void ImuMatrixToEuler(const double r[9], double euler[3])
{
    euler[0] = atan2(r[7], r[8]);
    euler[1] = atan2(-r[6], sqrt(r[7] * r[7] + r[8] * r[8]));
    euler[2] = atan2(r[3], r[0]);
}

/** @brief Unit quaternion [w, x, y, z] (w >= 0) of a rotation matrix body -> nav (Shepperd). */
void ImuQuaternionFromMatrix(const double r[9], double q[4])
{
    const double trace = r[0] + r[4] + r[8];
    double s, n;
    int i;
    if (trace > 0.0) {
        s = 2.0 * sqrt(1.0 + trace);
        q[0] = 0.25 * s; q[1] = (r[7] - r[5]) / s; q[2] = (r[2] - r[6]) / s; q[3] = (r[3] - r[1]) / s;
    } else if (r[0] > r[4] && r[0] > r[8]) {
        s = 2.0 * sqrt(1.0 + r[0] - r[4] - r[8]);
        q[0] = (r[7] - r[5]) / s; q[1] = 0.25 * s; q[2] = (r[1] + r[3]) / s; q[3] = (r[2] + r[6]) / s;
    } else if (r[4] > r[8]) {
        s = 2.0 * sqrt(1.0 + r[4] - r[0] - r[8]);
        q[0] = (r[2] - r[6]) / s; q[1] = (r[1] + r[3]) / s; q[2] = 0.25 * s; q[3] = (r[5] + r[7]) / s;
    } else {
        s = 2.0 * sqrt(1.0 + r[8] - r[0] - r[4]);
        q[0] = (r[3] - r[1]) / s; q[1] = (r[2] + r[6]) / s; q[2] = (r[5] + r[7]) / s; q[3] = 0.25 * s;
    }
    n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    if (q[0] < 0.0) {
        n = -n;
    }
    for (i = 0; i < 4; i++) {
        q[i] /= n;
    }
}
