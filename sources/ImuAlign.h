/**
 * @file ImuAlign.h
 * @brief Time alignment of the compensated triads: undo a known lag of each triad's input.
 *
 * lag [s] is how long a triad's input lags true time (settings lag_gyr, lag_acc, lag_mag):
 *  - lag < 0 (the triad leads): the output is the triad at t - |lag|, linearly interpolated
 *    between the two buffered samples around it; the oldest buffered sample when the buffer does
 *    not reach back that far (start-up, or |lag| longer than the buffered span).
 *  - lag > 0, magnetometer: the field, fixed in the world, is advanced by the body rotation over
 *    [t - lag, t]. In body axes a world-fixed vector obeys dx/dt = -w x x, so the output is
 *    exp(-[theta x]) x with theta the integral of the buffered compensated gyro over the window
 *    (trapezoid on the buffered samples, the partial first interval interpolated, intervals with
 *    a non-finite gyro end skipped, over the buffered span only). First order: x + lag (x x w).
 *    Exact for a world-fixed field, and it adds no noise.
 *  - lag > 0, gyro or accelerometer: linear extrapolation 2 x(t) - x(t - lag), x(t - lag)
 *    interpolated as above (the oldest buffered sample when not reachable). The specific force
 *    is not world-fixed: a rotation predicts its gravity part only (a 3-sample accelerometer lag
 *    in handheld motion: 35 % of the error removed by the rotation, 74 % by extrapolation, whose
 *    cost is sqrt(5) x the white noise).
 *  - lag = 0: the triad passes unchanged, bit for bit.
 * The buffer holds the last IMU_ALIGN_CAPACITY samples: time and the 9 compensated components as
 * given (NaN included). A sample whose time is not finite or does not increase is not buffered
 * and passes unchanged. Plain fixed-size arrays only, so the state is copied with the FMU state.
 */
#ifndef IMU_ALIGN_H
#define IMU_ALIGN_H

#include "ImuCommon.h"

/** Buffered samples: the reach of a lag is IMU_ALIGN_CAPACITY - 1 sample intervals. */
#define IMU_ALIGN_CAPACITY 64

/** User settings: lag [s] of the gyro, accelerometer and magnetometer input behind true time. */
typedef struct {
    double lag[3];
} ImuAlignSettings;

/** Ring buffer of the last samples. */
typedef struct {
    double time[IMU_ALIGN_CAPACITY];      /* s */
    double x[IMU_ALIGN_CAPACITY][9];      /* compensated gyr [rad/s], acc [m/s^2], mag [uT] */
    int count;                            /* buffered samples, 0..IMU_ALIGN_CAPACITY */
    int head;                             /* index of the newest sample */
} ImuAlignState;

/** @brief 1 if the buffer's count (0..IMU_ALIGN_CAPACITY) and head (0..IMU_ALIGN_CAPACITY - 1) can
 *         index it and its buffered times are finite and increasing from the oldest to the newest,
 *         the newest equal to clock [s] (the pipeline's time of the last sample, which every sample
 *         pushes; a restored FMU state), else 0. */
IMU_HIDDEN int ImuAlignStateValid(const ImuAlignState *s, double clock);
/** @brief Empty the buffer. */
IMU_HIDDEN void ImuAlignReset(ImuAlignState *s);
/**
 * @brief Buffer the sample at time t [s] and align the compensated components x[9] (gyr rad/s,
 *        acc m/s^2, mag uT) in place by the lags of the settings.
 * @return 1 if a lag reaches beyond the full buffer (|lag| longer than its span: the alignment is
 *         clamped to the oldest buffered sample), else 0 (also while the buffer fills at start-up).
 */
IMU_HIDDEN int ImuAlignUpdate(ImuAlignState *s, const ImuAlignSettings *settings, double t, double x[9]);

#endif
