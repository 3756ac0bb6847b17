/**
 * @file motion.h
 * @brief The synthetic motion the C test harnesses feed the FMU: a sensor rocking in roll and pitch
 *        while it turns in yaw, in the input units (rad/s, m/s^2, uT, degC); auxiliary inputs 0.
 */
#ifndef IMU_TEST_MOTION_H
#define IMU_TEST_MOTION_H

#include <math.h>

#include "ImuLayout.h"

/** @brief The inputs at time t [s] of the rocking, turning sensor. */
static void motionSample(double t, double x[IMU_INPUT_COUNT]) {
    const double roll = 0.3 * sin(1.3 * t), pitch = 0.2 * sin(0.9 * t), yaw = 0.5 * t;
    int i;
    for (i = 0; i < IMU_INPUT_COUNT; i++) {
        x[i] = 0.0;
    }
    x[0] = 0.39 * cos(1.3 * t);
    x[1] = 0.18 * cos(0.9 * t);
    x[2] = 0.5;
    x[3] = 9.80665 * sin(pitch);
    x[4] = -9.80665 * sin(roll) * cos(pitch);
    x[5] = -9.80665 * cos(roll) * cos(pitch);
    x[6] = 20.0 * cos(yaw);
    x[7] = -20.0 * sin(yaw);
    x[8] = 40.0;
    x[9] = 20.0 + 0.5 * t;
}

#endif
