/**
 * @file ImuMount.c
 * @brief Mounting: sensor axes -> body axes by a signed axis permutation (see ImuMount.h).
 */
#include <math.h>
#include <string.h>
#include "ImuMount.h"
#include "ImuMath.h"

/** @brief Sign [+-1] of the permutation axis[3] of {0, 1, 2}: +1 for an even permutation. */
static double ImuMountParity(const int axis[3])
{
    const int inversions = (axis[0] > axis[1]) + (axis[0] > axis[2]) + (axis[1] > axis[2]);
    return inversions % 2 == 0 ? 1.0 : -1.0;
}

void ImuMountIdentity(ImuMount *m)
{
    int i;
    for (i = 0; i < 3; i++) {
        m->axis[i] = i;
        m->sign[i] = 1.0;
    }
}

int ImuMountValid(const ImuMount *m)
{
    int i;
    for (i = 0; i < 3; i++) {
        if (m->axis[i] < 0 || m->axis[i] > 2 || (m->sign[i] != 1.0 && m->sign[i] != -1.0)) {
            return 0;
        }
    }
    return m->axis[0] != m->axis[1] && m->axis[0] != m->axis[2] && m->axis[1] != m->axis[2];
}

int ImuMountFromCodes(ImuMount *m, const double codes[3])
{
    ImuMount candidate;
    int i;
    memset(&candidate, 0, sizeof candidate); /* padding too: the settings are part of the checksummed FMU state */
    for (i = 0; i < 3; i++) {
        const double magnitude = fabs(codes[i]);
        if (!(magnitude == 1.0 || magnitude == 2.0 || magnitude == 3.0)) { /* also false for NaN */
            return -1;
        }
        candidate.axis[i] = (int)magnitude - 1;
        candidate.sign[i] = codes[i] > 0.0 ? 1.0 : -1.0;
    }
    /* det M = parity of the permutation x product of the signs: +1 for a rotation, -1 for a mirror */
    if (!ImuMountValid(&candidate)
        || ImuMountParity(candidate.axis) * candidate.sign[0] * candidate.sign[1] * candidate.sign[2] != 1.0) {
        return -1;
    }
    *m = candidate;
    return 0;
}

void ImuMountVector(const ImuMount *m, double v[3])
{
    const double sensor[3] = {v[0], v[1], v[2]};
    int i;
    for (i = 0; i < 3; i++) {
        v[i] = m->sign[i] * sensor[m->axis[i]];
    }
}

void ImuMountQuaternion(const ImuMount *m, double q[4])
{
    double r[9] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    int i;
    for (i = 0; i < 3; i++) {
        r[3 * i + m->axis[i]] = m->sign[i]; /* row i of M: body axis i = sign * sensor axis */
    }
    ImuQuaternionFromMatrix(r, q);
}

void ImuMountVectorInverse(const ImuMount *m, double v[3])
{
    const double body[3] = {v[0], v[1], v[2]};
    int i;
    for (i = 0; i < 3; i++) {
        v[m->axis[i]] = m->sign[i] * body[i];
    }
}

void ImuMountDiagonal(const ImuMount *m, double d[3])
{
    const double sensor[3] = {d[0], d[1], d[2]};
    int i;
    for (i = 0; i < 3; i++) {
        d[i] = sensor[m->axis[i]];
    }
}
