"""The faces of a box: six poses whose gravity directions are the ± axes of one orthogonal frame.

The Ferraris protocol (Ferraris et al., "Procedure for effortless in-field calibration of three-axial
rate gyro and accelerometers", Sensors and Materials 7(5), 1995; imucal's FerrarisCalibration) lays the
sensor, in its box, on each of the box's six faces. The box's faces are orthogonal and opposite faces
parallel, so the six calibrated specific forces are ±g along three orthogonal axes: 18 equations (6 × 3)
instead of the 6 of the gravity-norm invariant, enough for the accelerometer's bias, gains and
non-orthogonality (and the rotation of the sensor in its box, which is a nuisance here). The norm alone
cannot see the non-orthogonality at such poses: a cross-axis term changes the norm only to second order
when gravity lies along an axis.

A face set is recognised from the rests' raw specific force, since the calibration is what is
sought: pairs of opposite poses (within PAIR_TOLERANCE_DEG of antiparallel: a bias of up to 0.1 g tilts
each by up to 6°), and three such pairs whose geometry, once their common bias is removed, is that of a
box: opposite faces antiparallel and axes orthogonal within FACE_TOLERANCE_DEG. For opposite faces
f₊ = g e + b and f₋ = −g e + b, so the pair's midpoint is the bias b and its half difference g e,
whatever the bias; what is left of the departure are gain and cross-axis errors (≲ 3 %, 1°) and the
placement on the table.
"""
from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations

import numpy as np

from training.selfcal.rest import RestWindow

#: Largest angle [deg] of two raw pose directions from antiparallel for them to be candidate opposite
#: faces: a bias of 0.1 g (1 m/s², twice the largest MEMS datasheet value) tilts each by 5.7°.
PAIR_TOLERANCE_DEG = 15.0
#: Largest departure [deg] of the bias-free face geometry from a box's (opposite faces antiparallel,
#: axes orthogonal): a 3 % gain difference between axes bends it by 1.7°, 1° of cross-axis by 1°; the
#: next-closest poses of a multi-pose protocol (corners, body diagonals) are 35° away.
FACE_TOLERANCE_DEG = 5.0


@dataclass(frozen=True)
class FaceSet:
    """axis (K,) int 0..2 and sign (K,) ±1 of each window's face (axis -1 for a window at no face),
    R0 (3, 3) the rotation taking raw unit specific forces to the face frame (Kabsch), the six poses
    ({(axis, sign): pose index}), and the largest departure [deg] of the bias-free raw faces from a box."""

    axis: np.ndarray
    sign: np.ndarray
    R0: np.ndarray
    poses: dict
    departure_deg: float

    def targets(self) -> np.ndarray:
        """(K, 3) unit target direction sign·e_axis of each window (NaN for windows at no face)."""
        out = np.full((len(self.axis), 3), np.nan)
        at = self.axis >= 0
        out[at] = 0.0
        out[np.flatnonzero(at), self.axis[at]] = self.sign[at]
        return out


def _pose_means(windows: list[RestWindow]) -> dict[int, np.ndarray]:
    """{pose: mean raw specific force (3,) m/s²} over the windows of each pose."""
    return {pose: np.mean([w.acc for w in windows if w.pose == pose], axis=0)
            for pose in sorted({w.pose for w in windows if w.pose >= 0})}


def _angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    """Angle [deg] between vectors a and b."""
    return float(np.degrees(np.arccos(np.clip(a @ b / (np.linalg.norm(a) * np.linalg.norm(b)), -1.0, 1.0))))


def _opposite_pairs(means: dict[int, np.ndarray]) -> list[tuple[int, int]]:
    """(pose a, pose b) of every pair of raw directions within PAIR_TOLERANCE_DEG of antiparallel."""
    return [(a, b) for a, b in combinations(means, 2)
            if 180.0 - _angle_deg(means[a], means[b]) <= PAIR_TOLERANCE_DEG]


def _departure_deg(means: dict[int, np.ndarray], triple) -> float:
    """Largest departure [deg] of three opposite pairs from a box once their common bias (the mean of
    the pairs' midpoints) is removed: opposite faces from antiparallel, axes from orthogonal."""
    bias = np.mean([0.5 * (means[a] + means[b]) for a, b in triple], axis=0)
    axes = [means[a] - means[b] for a, b in triple]
    opposite = [180.0 - _angle_deg(means[a] - bias, means[b] - bias) for a, b in triple]
    orthogonal = [abs(90.0 - _angle_deg(axes[i], axes[j])) for i, j in combinations(range(3), 2)]
    return max(opposite + orthogonal)


def _best_triple(means: dict[int, np.ndarray], pairs) -> tuple[tuple, float] | None:
    """The three disjoint pairs of least departure from a box, when within FACE_TOLERANCE_DEG."""
    best = None
    for triple in combinations(pairs, 3):
        if len({p for pair in triple for p in pair}) < 6:
            continue
        departure = _departure_deg(means, triple)
        if departure <= FACE_TOLERANCE_DEG and (best is None or departure < best[1]):
            best = (triple, departure)
    return best


def _kabsch(measured: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Rotation R (3, 3) minimising Σ ‖R m_k − t_k‖² over unit rows m (K, 3), t (K, 3)."""
    u, _, vt = np.linalg.svd(target.T @ measured)
    d = np.sign(np.linalg.det(u @ vt))
    return u @ np.diag([1.0, 1.0, d]) @ vt


def find_faces(windows: list[RestWindow]) -> FaceSet | None:
    """The face set of `windows` (poses grouped), or None when no six poses form one. The face
    frame's axis i is the pair nearest sensor axis i, with the sensor's sign; it is right-handed when
    the sensor's axes are (R0 is a proper rotation whatever the assignment)."""
    means = _pose_means([w for w in windows if np.all(np.isfinite(w.acc))])
    best = _best_triple(means, _opposite_pairs(means))
    if best is None:
        return None
    triple, departure = best
    axes = np.array([means[a] - means[b] for a, b in triple])
    faces, poses = {}, {}
    for slot, k in enumerate(_sensor_order(axes)):
        a, b = triple[k]
        sign = 1 if axes[k][slot] >= 0 else -1
        faces[a], faces[b] = (slot, sign), (slot, -sign)
        poses[(slot, sign)], poses[(slot, -sign)] = a, b
    axis = np.array([faces.get(w.pose, (-1, 0))[0] for w in windows], dtype=int)
    sign = np.array([faces.get(w.pose, (-1, 0))[1] for w in windows], dtype=float)
    face_set = FaceSet(axis, sign, np.eye(3), poses, departure)
    at = axis >= 0
    measured = np.array([w.acc / np.linalg.norm(w.acc) for w in windows])[at]
    return FaceSet(axis, sign, _kabsch(measured, face_set.targets()[at]), poses, departure)


def _sensor_order(axes: np.ndarray) -> list[int]:
    """Which pair (index into axes (3, 3)) is face axis 0, 1, 2: the permutation that puts the largest
    components on the diagonal (the sensor's own axes, however it sits in its box)."""
    from itertools import permutations
    return list(max(permutations(range(3)), key=lambda p: sum(abs(axes[p[i]][i]) for i in range(3))))
