"""Error-free readings of a body turning at a given rate (test helper): the true attitude by strapdown
integration (training.models.attitude_twin.quat_integrate), gravity and a fixed earth field seen in the
body. Tests add their own sensor errors."""
from __future__ import annotations

import numpy as np

from training.models import attitude_twin

#: Earth field [µT] in magnetic NED (norm 49.2 µT, dip 66°).
FIELD_NED = np.array([20.0, 0.0, 45.0])


def ideal_readings(rate: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(q body -> NED (N, 4), specific force [m/s²] (N, 3), field [µT] (N, 3)) for body rates
    rate [rad/s] (N, 3) sampled every dt [s], starting level and heading north."""
    n = len(rate)
    q = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    for k in range(1, n):
        q[k] = attitude_twin.quat_integrate(q[k - 1], rate[k], dt)
    conj = q * np.array([1.0, -1.0, -1.0, -1.0])
    acc = np.array([attitude_twin.quat_rotate(c, [0.0, 0.0, -9.80665]) for c in conj])
    mag = np.array([attitude_twin.quat_rotate(c, FIELD_NED) for c in conj])
    return q, acc, mag
