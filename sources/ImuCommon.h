/**
 * @file ImuCommon.h
 * @brief Definitions every runtime module shares.
 *
 * IMU_HIDDEN keeps the algorithm functions out of the shared library's export table, so the
 * FMU binary exports exactly the fmi2* / fmi3* functions.
 */
#ifndef IMU_COMMON_H
#define IMU_COMMON_H

#if defined(__GNUC__) || defined(__clang__)
#define IMU_HIDDEN __attribute__((visibility("hidden")))
#define IMU_EXPORT __attribute__((visibility("default")))
#else
#define IMU_HIDDEN
#define IMU_EXPORT
#endif

#endif
