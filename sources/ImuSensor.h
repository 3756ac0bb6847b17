/**
 * @file ImuSensor.h
 * @brief The virtual sensor: what a calibrated unit outputs for a true motion, its trained corrections
 *        run backwards plus its characterised noise (docs/virtual_sensor.md).
 *
 * The ImuFusion chain (ImuPipeline.h) maps a raw sample to the corrected one: gain/bias(T), PSO-BP
 * bias, time alignment, correction terms, magnetometer particle filter and ELM, mounting. The virtual
 * sensor runs the same trained stages backwards on the same coefficients and settings, each by the
 * stage's own code:
 *  - mounting by the inverse permutation;
 *  - the ELM by a fixed-point iteration of its forward map (a contraction: its correction is small
 *    against the field);
 *  - the correction terms by Newton's method on their forward map (not a fixed point: a lag term's
 *    time derivative can outweigh the triad it corrects);
 *  - the time alignment by ImuAlign with the lags negated (a triad that lags true time is delayed; one
 *    that leads is extrapolated as ImuAlign extrapolates);
 *  - the PSO-BP bias added back;
 *  - the gain/bias(T) model, affine in the triad at a given temperature, inverted exactly from three
 *    probes of ImuThermalApply.
 * The particle filter is an online estimator of what the calibration left: the virtual sensor applies
 * no further hard/soft iron (the trained one is the magnetometer's B(T), A). The online bias learning
 * is not inverted: a freshly calibrated unit has learnt nothing.
 *
 * Noise (in sensor axes, units of the triad, per axis): white noise of density N [u/sqrt(Hz)] (sigma
 * N / sqrt(h) per sample of interval h), a bias random walk K [u/sqrt(s)] (increments K sqrt(h) N(0, 1),
 * from 0 at power-on) and a flicker-like bias of instability B [u]: IMU_SENSOR_FLICKER_POLES
 * first-order Gauss-Markov processes with correlation times 10^(k/2) s, k = 0..8, each of stationary
 * sigma IMU_SENSOR_FLICKER_GAIN * B, from 0 (their Allan floor is sqrt(2 ln 2 / pi) B within +-4 % from
 * 10 s to 1000 s; the simulator's TriadErrors.bias_instability is the same construction, tests pin the
 * two). Then saturation at +-fullScale and rounding to the LSB (each when > 0). One seeded generator
 * (ImuRng), so the same seed gives the same recording.
 */
#ifndef IMU_SENSOR_H
#define IMU_SENSOR_H

#include "ImuCommon.h"
#include "ImuPipeline.h"
#include "ImuRng.h"

/** Gauss-Markov processes that make the flicker-like bias. */
#define IMU_SENSOR_FLICKER_POLES 9
/** Stationary sigma of each process per unit bias instability [1]. */
#define IMU_SENSOR_FLICKER_GAIN 0.6125

/** Noise of the three triads (gyr, acc, mag), per axis in the triad's unit u. */
typedef struct {
    double density[3][3];     /* white noise density N [u/sqrt(Hz)] */
    double instability[3][3]; /* bias instability B [u] */
    double walk[3][3];        /* bias random walk K [u/sqrt(s)] */
    double lsb[3];            /* quantisation step [u], 0 = none */
    double fullScale[3];      /* saturation [u], 0 = none */
    int enabled;              /* 0: the exact inverse of the corrections, no noise, saturation or quantisation */
    int seed;                 /* of the generator */
} ImuSensorNoise;

/** Evolving noise: the generator, the random-walk and flicker biases [u]. */
typedef struct {
    ImuRng rng;
    double walk[3][3];
    double flicker[3][3][IMU_SENSOR_FLICKER_POLES];
} ImuSensorNoiseState;

/** The virtual sensor: the trained chain's settings and coefficients, its noise, and the state of the
 *  stages that evolve (time alignment, correction-term signals, PSO-BP temperature rate, noise). */
typedef struct {
    ImuPipelineSettings settings;
    ImuCoefficients coefficients;
    ImuSensorNoise noise;
    ImuAlignSettings delay;   /* the lags negated */
    ImuAlignState align;
    ImuTermsState terms;
    ImuPsoBpState psobp;
    ImuSensorNoiseState noiseState;
    int hasSample;            /* 1 once a sample was produced */
    double clock;             /* s, time of the last sample */
} ImuSensor;

/** @brief Set the trained chain (settings checked by the caller with ImuPipelineSettingsCheck), the noise,
 *         and reset the state. */
IMU_HIDDEN void ImuSensorInitialise(ImuSensor *s, const ImuPipelineSettings *settings, const ImuCoefficients *c,
                                    const ImuSensorNoise *noise);
/** @brief Back to the state right after ImuSensorInitialise (the generator re-seeded). */
IMU_HIDDEN void ImuSensorReset(ImuSensor *s);
/** @brief NULL if the evolving state is one the sensor can reach by clock [s] (a restored FMU state),
 *         else what is wrong. */
IMU_HIDDEN const char *ImuSensorStateProblem(const ImuSensor *s, double clock);
/** @brief NULL if the noise figures are finite and >= 0, else the one that is not. */
IMU_HIDDEN const char *ImuSensorNoiseProblem(const ImuSensorNoise *noise);
/**
 * @brief The raw sample of the unit at time t [s] (non-decreasing), h [s] after the previous one
 *        (the first: the sampling interval; > 0).
 * @param truth true body rate [rad/s], specific force [m/s^2] and field [uT] in body axes (9 values).
 * @param temperature the sensor's temperature [degC] (NaN: unknown, the models take their reference).
 * @param aux the auxiliary inputs the correction terms use (IMU_TERMS_AUX_COUNT, their units).
 * @param raw out: gyro [rad/s], accelerometer [m/s^2], magnetometer [uT] in sensor axes (9 values).
 */
IMU_HIDDEN void ImuSensorUpdate(ImuSensor *s, double t, double h, const double truth[9], double temperature,
                                const double aux[IMU_TERMS_AUX_COUNT], double raw[9]);

#endif
