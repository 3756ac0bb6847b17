/**
 * @file ImuRng.c
 * @brief PCG32 pseudo-random generator with uniform and normal draws.
 */
#include <math.h>
#include "ImuRng.h"

#define IMU_RNG_MULTIPLIER 6364136223846793005ULL

/** @brief Seed like pcg32_srandom_r: initial state seed, stream selector stream (any values). */
void ImuRngSeed(ImuRng *rng, uint64_t seed, uint64_t stream)
{
    rng->state = 0U;
    rng->increment = (stream << 1U) | 1U;
    (void)ImuRngNext(rng);
    rng->state += seed;
    (void)ImuRngNext(rng);
    rng->hasSpare = 0;
    rng->spare = 0.0;
}

/** @brief Next 32-bit output (XSH-RR permutation of the previous LCG state). */
uint32_t ImuRngNext(ImuRng *rng)
{
    const uint64_t old = rng->state;
    const uint32_t xorShifted = (uint32_t)(((old >> 18U) ^ old) >> 27U);
    const uint32_t rotation = (uint32_t)(old >> 59U);
    rng->state = old * IMU_RNG_MULTIPLIER + rng->increment;
    return (xorShifted >> rotation) | (xorShifted << ((32U - rotation) & 31U));
}

/** @brief Uniform double in [0, 1) with 53 random bits from two outputs. */
double ImuRngUniform(ImuRng *rng)
{
    const uint32_t a = ImuRngNext(rng) >> 5U;
    const uint32_t b = ImuRngNext(rng) >> 6U;
    return ((double)a * 67108864.0 + (double)b) / 9007199254740992.0;
}

/** @brief Standard normal deviate (Marsaglia polar method, the second deviate cached for the next call). */
double ImuRngNormal(ImuRng *rng)
{
    double u, v, s, factor;
    if (rng->hasSpare) {
        rng->hasSpare = 0;
        return rng->spare;
    }
    do {
        u = 2.0 * ImuRngUniform(rng) - 1.0;
        v = 2.0 * ImuRngUniform(rng) - 1.0;
        s = u * u + v * v;
    } while (s >= 1.0 || s == 0.0);
    factor = sqrt(-2.0 * log(s) / s);
    rng->spare = v * factor;
    rng->hasSpare = 1;
    return u * factor;
}
