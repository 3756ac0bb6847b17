"""Plausibility limits of the raw sensor inputs, mirrored from the C runtime's guard
(sources/ImuGuard.h; tests/test_io.py pins every value to its #define).

The runtime treats a sample beyond them as bad input (the triad is skipped, the temperature held);
the loader (training.data.io) refuses a recording that contains one, naming the row, so training never
fits what the runtime would refuse.
"""
from __future__ import annotations

GYR_LIMIT_RAD_S = 100.0    # IMU_GUARD_GYR_LIMIT: beyond any MEMS gyro's full scale (about 70 rad/s)
ACC_LIMIT_M_S2 = 2000.0    # IMU_GUARD_ACC_LIMIT: about 200 g
MAG_SATURATION = 20.0      # IMU_GUARD_MAG_SATURATION: × the field norm, an axis at or beyond it is saturated
TEMP_MIN_C = -60.0         # IMU_GUARD_TEMP_MIN: lower end of the valid temperature range
TEMP_MAX_C = 125.0         # IMU_GUARD_TEMP_MAX: upper end of the valid temperature range
GAP_STEPS = 100.0          # IMU_GUARD_GAP_STEPS: a step longer than this many nominal steps is a gap

#: The C name of each limit (for the pinning test and the messages).
C_NAMES = {"GYR_LIMIT_RAD_S": "IMU_GUARD_GYR_LIMIT", "ACC_LIMIT_M_S2": "IMU_GUARD_ACC_LIMIT",
           "MAG_SATURATION": "IMU_GUARD_MAG_SATURATION", "TEMP_MIN_C": "IMU_GUARD_TEMP_MIN",
           "TEMP_MAX_C": "IMU_GUARD_TEMP_MAX",
           "GAP_STEPS": "IMU_GUARD_GAP_STEPS"}
