"""PCG32 (O'Neill 2014, XSH-RR 64/32): the bit-exact twin of sources/ImuRng.c.

Same seed and stream, same numbers in C and in Python: `next_u32` is integer-exact; `uniform`
is exact (53 bits from two outputs); `normal` uses the Marsaglia polar method with
`math.log/sqrt`, i.e. the C library's functions, so it agrees with C to the last bit on
the same platform (at worst 1 ulp where the libm differs).
"""
from __future__ import annotations

import math

import numpy as np

MASK64 = (1 << 64) - 1
MASK32 = (1 << 32) - 1
MULTIPLIER = 6364136223846793005


class Pcg32:
    """PCG32 generator with the draws the runtime uses (see ImuRng.h)."""

    def __init__(self, seed: int, stream: int) -> None:
        """Seed like pcg32_srandom_r: initial state `seed`, stream selector `stream` (uint64)."""
        self.state = 0
        self.increment = ((stream << 1) | 1) & MASK64
        self.next_u32()
        self.state = (self.state + seed) & MASK64
        self.next_u32()
        self.spare: float | None = None

    def next_u32(self) -> int:
        """Next 32-bit output."""
        old = self.state
        xorshifted = (((old >> 18) ^ old) >> 27) & MASK32
        rotation = old >> 59
        self.state = (old * MULTIPLIER + self.increment) & MASK64
        return ((xorshifted >> rotation) | (xorshifted << ((32 - rotation) & 31))) & MASK32

    def uniform(self) -> float:
        """Uniform double in [0, 1): (a>>5 * 2^26 + b>>6) / 2^53."""
        a = self.next_u32() >> 5
        b = self.next_u32() >> 6
        return (a * 67108864.0 + b) / 9007199254740992.0

    def normal(self) -> float:
        """Standard normal deviate (Marsaglia polar method; the second deviate is cached)."""
        if self.spare is not None:
            value, self.spare = self.spare, None
            return value
        while True:
            u = 2.0 * self.uniform() - 1.0
            v = 2.0 * self.uniform() - 1.0
            s = u * u + v * v
            if 0.0 < s < 1.0:
                break
        factor = math.sqrt(-2.0 * math.log(s) / s)
        self.spare = v * factor
        return u * factor

    def normals(self, n: int) -> np.ndarray:
        """(n,) array of consecutive `normal()` draws."""
        return np.array([self.normal() for _ in range(n)], dtype=np.float64)

    def uniforms(self, n: int) -> np.ndarray:
        """(n,) array of consecutive `uniform()` draws."""
        return np.array([self.uniform() for _ in range(n)], dtype=np.float64)
