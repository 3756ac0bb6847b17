"""Poses: rests grouped by the direction of gravity (the specific force) in the sensor frame.

A pose is one orientation of the sensor against gravity, whatever its heading: the rests of a
calibration protocol are grouped into poses so that each distinct pose counts once in the gravity-norm
fit (training.selfcal.accel.group_weights), and the number of poses says what a recording can determine.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from training.selfcal.rest import RestWindow

#: Rests whose gravity directions are closer than this [deg] are one pose: hand-placed poses of
#: a calibration protocol differ by 35° or more, while one pose re-placed by hand or seen through
#: a ~1-2 % uncalibrated accelerometer scatters by a few degrees.
POSE_SEPARATION_DEG = 12.0


def direction_groups(vectors: np.ndarray) -> np.ndarray:
    """Group index (K,) of each vector (K, 3) by direction: greedy in order, a new group when a
    direction is more than POSE_SEPARATION_DEG from every group's first member; -1 for a
    non-finite or zero vector."""
    cos_limit = np.cos(np.deg2rad(POSE_SEPARATION_DEG))
    heads: list[np.ndarray] = []
    labels = np.full(len(vectors), -1, dtype=int)
    for k, v in enumerate(np.asarray(vectors, dtype=np.float64)):
        norm = np.linalg.norm(v)
        if not np.isfinite(norm) or norm == 0:
            continue
        u = v / norm
        match = next((i for i, head in enumerate(heads) if float(u @ head) >= cos_limit), None)
        if match is None:
            heads.append(u)
            match = len(heads) - 1
        labels[k] = match
    return labels


def group_poses(windows: list[RestWindow]) -> list[RestWindow]:
    """The windows with `pose` set by `direction_groups` of their mean specific force, in
    window order (pose -1 where the accelerometer is not recorded)."""
    labels = direction_groups(np.array([w.acc for w in windows]).reshape(-1, 3))
    return [replace(w, pose=int(label)) for w, label in zip(windows, labels)]


def count_poses(windows: list[RestWindow]) -> int:
    """Number of distinct poses among windows (pose >= 0)."""
    return len({w.pose for w in windows if w.pose >= 0})
