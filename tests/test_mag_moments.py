"""The power-sum tables of sources/ImuMagMoments.c agree with each other: the shift's chain table is what
ImuMagIndex gives, chain by chain (a wrong entry would shift the moments of every particle)."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

SOURCE = (Path(__file__).resolve().parents[1] / "sources" / "ImuMagMoments.c").read_text()
DEGREE = 4


def _numbers(name: str) -> list[int]:
    """The integers of the initialiser of the C array `name`."""
    body = re.search(rf"{name}\[[^=]*=\s*(\{{.*?\}});", SOURCE, re.S).group(1)
    return [int(v) for v in re.findall(r"-?\d+", body)]


def test_the_shift_chains_are_the_power_sum_positions_axis_by_axis():
    index = np.array(_numbers("ImuMagIndex")).reshape(5, 5, 5)
    expected, lengths = [], []
    for axis in range(3):
        first, second = (1, 2) if axis == 0 else (0, 2) if axis == 1 else (0, 1)
        chains = []
        for i in range(DEGREE + 1):
            for j in range(DEGREE + 1 - i):
                length = DEGREE + 1 - i - j
                lengths += [length] if axis == 0 else []
                for a in range(length):
                    e = [0, 0, 0]
                    e[first], e[second], e[axis] = i, j, a
                    chains.append(int(index[tuple(e)]))
        expected.append(chains)
    assert _numbers("ImuMagShiftChain") == [v for chains in expected for v in chains]
    assert _numbers("ImuMagShiftChainLength") == lengths
    assert all(sorted(chains) == list(range(35)) for chains in expected)  # every power sum once per axis
