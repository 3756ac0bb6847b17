/**
 * @file ImuQuaternion.c
 * @brief Unit quaternions [w, x, y, z], Hamilton, rotating body -> nav.
 */
#include <math.h>
#include "ImuQuaternion.h"

/** @brief out = a (x) b (Hamilton product; out may alias neither). */
void ImuQuaternionMultiply(const double a[4], const double b[4], double out[4])
{
    out[0] = a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3];
    out[1] = a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2];
    out[2] = a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1];
    out[3] = a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0];
}

/** @brief out = q v q* for a 3-vector v (any unit). */
void ImuQuaternionRotate(const double q[4], const double v[3], double out[3])
{
    /* v + 2 w (u x v) + 2 u x (u x v), u = vector part of q */
    const double tx = 2.0 * (q[2] * v[2] - q[3] * v[1]);
    const double ty = 2.0 * (q[3] * v[0] - q[1] * v[2]);
    const double tz = 2.0 * (q[1] * v[1] - q[2] * v[0]);
    out[0] = v[0] + q[0] * tx + q[2] * tz - q[3] * ty;
    out[1] = v[1] + q[0] * ty + q[3] * tx - q[1] * tz;
    out[2] = v[2] + q[0] * tz + q[1] * ty - q[2] * tx;
}

/** @brief Scale q to unit norm (identity if its norm is zero or not finite). */
void ImuQuaternionNormalise(double q[4])
{
    const double n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    int i;
    if (!(n > 0.0) || !isfinite(n)) {
        q[0] = 1.0;
        q[1] = q[2] = q[3] = 0.0;
        return;
    }
    for (i = 0; i < 4; i++) {
        q[i] /= n;
    }
}

/** @brief q <- q (x) exp(w dt / 2), normalised; w [rad/s] held over dt [s]. */
void ImuQuaternionIntegrate(double q[4], const double w[3], double dt)
{
    const double angle = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]) * dt;
    /* Both computed: the compiler fuses them into one sincos call (the same values, half the cost). */
    const double sine = sin(0.5 * angle), cosine = cos(0.5 * angle);
    /* sin(angle/2)/angle by its Taylor series where the division loses precision */
    const double s = angle < 1e-4 ? 0.5 - angle * angle / 48.0 : sine / angle;
    const double step[4] = {cosine, s * w[0] * dt, s * w[1] * dt, s * w[2] * dt};
    double product[4];
    int i;
    ImuQuaternionMultiply(q, step, product);
    for (i = 0; i < 4; i++) {
        q[i] = product[i];
    }
    ImuQuaternionNormalise(q);
}

/** @brief Rotation matrix (row-major, body -> nav) of a unit quaternion q. */
void ImuQuaternionToMatrix(const double q[4], double r[9])
{
    const double w = q[0], x = q[1], y = q[2], z = q[3];
    r[0] = 1.0 - 2.0 * (y * y + z * z);
    r[1] = 2.0 * (x * y - w * z);
    r[2] = 2.0 * (x * z + w * y);
    r[3] = 2.0 * (x * y + w * z);
    r[4] = 1.0 - 2.0 * (x * x + z * z);
    r[5] = 2.0 * (y * z - w * x);
    r[6] = 2.0 * (x * z - w * y);
    r[7] = 2.0 * (y * z + w * x);
    r[8] = 1.0 - 2.0 * (x * x + y * y);
}

/** @brief q <- Rz(angle) (x) q: turn the nav frame about its z axis by angle [rad]. */
void ImuQuaternionTurnNav(double q[4], double angle)
{
    const double turn[4] = {cos(0.5 * angle), 0.0, 0.0, sin(0.5 * angle)};
    double product[4];
    int i;
    ImuQuaternionMultiply(turn, q, product);
    for (i = 0; i < 4; i++) {
        q[i] = product[i];
    }
}
