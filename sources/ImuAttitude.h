/**
 * @file ImuAttitude.h
 * @brief Attitude body -> magnetic NED from corrected gyro, accelerometer and magnetometer, in
 *        one of two modes:
 *
 * - IMU_ATTITUDE_EULER: adaptive-gain fusion of two ZYX Euler sets, one from the gyro (rotation-
 *   matrix update), one from accelerometer (roll, pitch) and magnetometer (yaw); the gains come
 *   from the mean-square errors of the two sets (gyro: propagated variance P; acc/mag: moving
 *   mean-square innovation R), K = P / (P + R).
 * - IMU_ATTITUDE_QUATERNION: singularity-free quaternion filter: gyro strapdown, inclination
 *   correction from the specific force low-passed in the almost-inertial strapdown frame (a
 *   linear acceleration averages out there), heading offset corrected by the magnetometer with
 *   rejection of fields whose norm or dip disagree with the earth field (with recovery after
 *   mag_reject_time). Ideas of VQF (Laidig & Seel, Information Fusion 91, 2023).
 *
 * Both modes subtract a gyro bias estimated while a rest detector (gyro + accelerometer) holds
 * (the quaternion mode, with motionBias, also in motion from its inclination correction), and both run as without a magnetometer when magHeading is 0 (6D: a field too non-uniform to trust).
 */
#ifndef IMU_ATTITUDE_H
#define IMU_ATTITUDE_H

#include "ImuCommon.h"
#include "ImuLowPass.h"
#include "ImuMotionBias.h"
#include "ImuRestDetector.h"

/** Standard gravity [m/s^2]: the specific-force norm at rest. */
#define IMU_ATTITUDE_GRAVITY 9.80665

/** Attitude modes (setting attitude_mode). */
typedef enum {
    IMU_ATTITUDE_EULER = 0,      /* adaptive-gain Euler fusion (the method) */
    IMU_ATTITUDE_QUATERNION = 1  /* quaternion filter with disturbance rejection */
} ImuAttitudeMode;

/**
 * The project's additions to the adaptive-gain Euler fusion (ImuAttitudeSettings.eulerAdditions, a
 * sum of these bits: FMU parameter euler_additions, default all, 0 being the method as its source
 * describes it, docs/euler.md). Why each came: ImuAttitudeEuler.c.
 */
typedef enum {
    IMU_EULER_TRAPEZOID = 1,        /* propagate with the mean of the previous and current rate
                                     * (off: the current rate alone) */
    IMU_EULER_MSE_FLOOR = 2,        /* R_i floored by angle_noise^2 */
    IMU_EULER_DEPARTURE = 4,        /* R_i grows with the departure of |f| from g, |m| from field_norm */
    IMU_EULER_STEP_ERROR = 8,       /* P_i grows by the step's integration-error bound */
    IMU_EULER_YAW_TILT_VARIANCE = 16, /* yaw's R carries the variance of the tilt it is de-tilted with */
    IMU_EULER_RESTART = 32          /* restart from the acc/mag set when the summed bounds grow */
} ImuEulerAddition;
/** Every Euler addition (the FMU's filter). */
#define IMU_EULER_ALL_ADDITIONS (IMU_EULER_TRAPEZOID | IMU_EULER_MSE_FLOOR | IMU_EULER_DEPARTURE | \
                                 IMU_EULER_STEP_ERROR | IMU_EULER_YAW_TILT_VARIANCE | IMU_EULER_RESTART)

/** Settings in user units. */
typedef struct {
    double gyroNoise;        /* rad/s/sqrt(Hz), white-noise density of the corrected gyro */
    double gyroBiasResidual; /* rad/s, residual gyro bias */
    double mseTimeConstant;  /* s, averaging time of the innovation mean-square errors (> 0) */
    double angleNoise;       /* rad, floor of the acc/mag angle error standard deviation (> 0) */
    double fieldNorm;        /* uT, local earth-field magnitude (> 0) */
    int mode;                /* ImuAttitudeMode */
    double fieldDip;         /* rad, local earth-field dip (inclination, positive down) */
    double tauAcc;           /* s, time constant of the inclination correction (> 0) */
    double tauMag;           /* s, time constant of the heading correction (> 0) */
    double restGyroThreshold; /* rad/s, rest-detection rate threshold (0: no bias estimation) */
    double restAccThreshold; /* m/s^2, rest-detection specific-force threshold (> 0) */
    double magRejectTime;    /* s, longest rejection of a disturbed field (0: no rejection) */
    int gyroHold;            /* 1: a rate sample holds over the interval before it (a sensor that
                              * averages over its sample interval); 0: trapezoid of two samples */
    int magHeading;          /* 1: the field corrects the heading; 0: 6D (the field is not used) */
    int motionBias;          /* 1: quaternion mode also estimates the gyro bias in motion (ImuMotionBias.h) */
    double accNormTolerance; /* 1, |f| / g - 1 the still, corrected accelerometer may show (its own scale
                              * error, not linear acceleration; >= 0) */
    int eulerAdditions;      /* sum of ImuEulerAddition bits in use by the Euler mode (FMU parameter
                              * euler_additions) */
} ImuAttitudeSettings;

/** Settings and evolving state (plain struct: copy = save state). */
typedef struct {
    ImuAttitudeSettings settings;
    double rotation[9];     /* 1, body -> magnetic NED, row-major, rebuilt from euler */
    double euler[3];        /* rad, fused roll, pitch, yaw in (-pi, pi] */
    double variance[3];     /* rad^2, P_i: mean-square error of the gyro-propagated angles */
    double mse[3];          /* rad^2, R_i: moving mean-square acc/mag innovation */
    double gain[3];         /* 1, K_i of the last update (0 where no correction was made) */
    double previousRate[3]; /* rad/s, corrected rate of the previous sample (may be NaN) */
    double nominalStep;     /* s, the guard's nominal step at the last sample (ImuGuardNominalStep; 0 before one is known) */
    int tiltInitialised;    /* roll/pitch were set from the accelerometer */
    int yawInitialised;     /* yaw was set from the magnetometer */
    double bias[3];         /* rad/s, gyro bias estimated at rest */
    ImuRestDetector rest;   /* rest detection feeding the bias */
    int atRest;             /* the rest detector held at the last sample */
    ImuMotionBias motionBias; /* quaternion mode: the bias estimate in motion */
    double qGyr[4];         /* 1, quaternion mode: strapdown body -> almost-inertial frame */
    double qAcc[4];         /* 1, quaternion mode: inclination correction, inertial -> level frame */
    ImuLowPass accLowPass;  /* m/s^2, quaternion mode: low-pass of f in the inertial frame */
    double headingOffset;   /* rad, quaternion mode: level frame -> magnetic NED about down */
    double magRejected;     /* s, quaternion mode: time the field has been rejected */
    double magClean;        /* s, quaternion mode: time the field has stayed within the tolerances */
    double magSamples;      /* 1, quaternion mode: accepted field samples (start-up averaging) */
    double magDisturbed;    /* 1, quaternion mode: 1 when the last field sample was rejected as disturbed */
    double stepError;       /* rad^2, summed integration-error bounds of the recent steps, decaying
                             * with mse_time_constant (Euler) or tau_acc (quaternion); beyond
                             * IMU_ATTITUDE_RESTART_VARIANCE the corrections restart */
} ImuAttitude;

/** @brief Set the settings and reset the state (level, yaw 0, nothing initialised). */
IMU_HIDDEN void ImuAttitudeInitialise(ImuAttitude *a, const ImuAttitudeSettings *s);
/** @brief Reset the state, keeping the settings. */
IMU_HIDDEN void ImuAttitudeReset(ImuAttitude *a);
/** @brief 1 if a's evolving state is one the filter can reach (a restored FMU state): its flags 0 or
 *         1, its nominal step finite and >= 0, its low-passes and motion estimate valid; else 0. */
IMU_HIDDEN int ImuAttitudeStateValid(const ImuAttitude *a);
/**
 * @brief After a gap of `gap` [s] without samples: the corrections restart as at power-on
 *        (roll/pitch from the next specific force, yaw from the next field, rest detection anew)
 *        and the angles' variance grows by the motion nobody measured, (1 rad/s x gap)^2, so the
 *        following acc/mag samples average the restart down; the gyro bias and the angles are
 *        kept (without a magnetometer yaw keeps its value from before the gap). Call before the
 *        first sample after the gap, which must then come with dt = 0.
 */
IMU_HIDDEN void ImuAttitudeRestart(ImuAttitude *a, double gap);
/**
 * @brief Process one sample: gyr [rad/s], acc specific force [m/s^2], mag [uT] (corrected,
 *        body axes); dt [s] since the previous sample (0 on the first; no propagation if <= 0);
 *        nominalStep [s] the sampling step before this one (ImuGuardNominalStep: robust to one
 *        short or long step; 0 when unknown): a step longer than IMU_ATTITUDE_MISSING_STEPS of
 *        it has lost samples.
 */
IMU_HIDDEN void ImuAttitudeUpdate(ImuAttitude *a, const double gyr[3], const double acc[3],
                                  const double mag[3], double dt, double nominalStep);
/** @brief Fused roll, pitch, yaw [rad], each in (-pi, pi]. */
IMU_HIDDEN void ImuAttitudeGetEuler(const ImuAttitude *a, double euler[3]);
/** @brief Attitude quaternion [w, x, y, z] body -> magnetic NED, w >= 0. */
IMU_HIDDEN void ImuAttitudeGetQuaternion(const ImuAttitude *a, double q[4]);
/** @brief 1 while the filter rejects the field as disturbed (quaternion mode), else 0. */
IMU_HIDDEN int ImuAttitudeMagDisturbed(const ImuAttitude *a);
/** @brief Fusion gains [1] of roll, pitch, yaw from the last update. */
IMU_HIDDEN void ImuAttitudeGetGains(const ImuAttitude *a, double gains[3]);

#endif
