/**
 * @file ImuRng.h
 * @brief PCG32 pseudo-random generator (O'Neill 2014, XSH-RR 64/32) with uniform and normal draws.
 *
 * The state lives in the caller's struct and is seeded from a parameter: same seed, same stream,
 * in C and in Python (training/models/rng.py is the bit-exact twin). Reference: seed 42, stream 54 gives
 * 0xa15c02b7 0x7b47f409 0xba1d3330 0x83d2f293 0xbfa4784b 0xcbed606e (pcg32-demo).
 */
#ifndef IMU_RNG_H
#define IMU_RNG_H

#include <stdint.h>
#include "ImuCommon.h"

/** Generator state: 64-bit LCG state, odd increment (stream), cached second normal deviate. */
typedef struct {
    uint64_t state;
    uint64_t increment;
    int hasSpare; /* 1 when spare holds the unused sine deviate of the last Box-Muller pair */
    double spare;
} ImuRng;

/** @brief Seed like pcg32_srandom_r: initial state seed, stream selector stream (any values). */
IMU_HIDDEN void ImuRngSeed(ImuRng *rng, uint64_t seed, uint64_t stream);
/** @brief Next 32-bit output. */
IMU_HIDDEN uint32_t ImuRngNext(ImuRng *rng);
/** @brief Uniform double in [0, 1) with 53 random bits from two outputs: (a>>5 * 2^26 + b>>6) / 2^53. */
IMU_HIDDEN double ImuRngUniform(ImuRng *rng);
/**
 * @brief Standard normal deviate by the Marsaglia polar method: u, v = 2U - 1 until
 *        0 < s = u^2 + v^2 < 1; returns u sqrt(-2 ln s / s) and caches v sqrt(-2 ln s / s) for the next call.
 */
IMU_HIDDEN double ImuRngNormal(ImuRng *rng);

#endif
