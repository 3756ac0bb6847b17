/**
 * @file ImuCommon.h
 * @brief Definitions every runtime module shares.
 *
 * IMU_HIDDEN keeps the algorithm functions out of the shared library's export table, so the
 * FMU binary exports exactly the fmi2* / fmi3* functions; IMU_EXPORT marks the batch library's
 * entry points. On Windows a DLL exports only what is declared __declspec(dllexport) (the FMI
 * headers do so for the fmi2* / fmi3* functions), so every other function is already hidden and
 * GCC's visibility attribute, which mingw-w64 does not support, is not used.
 */
#ifndef IMU_COMMON_H
#define IMU_COMMON_H

#if defined(_WIN32) || defined(__CYGWIN__)
#define IMU_HIDDEN
#define IMU_EXPORT __declspec(dllexport)
#elif defined(__GNUC__) || defined(__clang__)
#define IMU_HIDDEN __attribute__((visibility("hidden")))
#define IMU_EXPORT __attribute__((visibility("default")))
#else
#define IMU_HIDDEN
#define IMU_EXPORT
#endif

#endif
