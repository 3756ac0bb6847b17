"""Closed turns: motions between two rests that turn the sensor a whole number of times about an axis
near the vertical and put it back where it was — the gyro's known angle.

The rotation between two rests shows a gyro gain error only through the directions it moves (Tedaldi,
Pretto, Menegatti, ICRA 2014): gravity cannot see a turn about the vertical, so a gain error about a
vertical axis is invisible to the rest-to-rest invariant. The Ferraris protocol (Ferraris et al.,
Sensors and Materials 7(5), 1995; imucal) turns the sensor a full turn about each axis, held vertical,
and uses the known angle 360°: the integrated angle must be exactly n·360°.

A segment is a closed turn when the gravity direction at its end rest is that at its start rest
(within CLOSED_TILT_DEG), the rotation axis (the direction of the integrated rate) is within
CLOSURE_MAX_TILT_DEG of the vertical, and the angle turned about it is within TURN_TOLERANCE_DEG of a
non-zero whole number n of turns. Its residual is the winding angle: the angle that a body vector h0
perpendicular to the axis a sweeps about a (in the frame of the start rest), unwrapped sample by sample,
minus 2πn. The winding is a function of the attitude alone, so for a path that truly returns to its
start attitude it is exactly 2πn, whatever the axis did on the way (no fixed-axis assumption, unlike
integrating the rate).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from training.selfcal.rotations import attitudes, winding

#: Largest angle [deg] between the gravity directions at the two rests of a closed turn: the sensor is
#: put back on the same face (a face re-placed on a table repeats to ~0.1-0.5°); two distinct poses of a
#: multi-pose protocol are at least 12° apart (training.selfcal.poses.POSE_SEPARATION_DEG).
CLOSED_TILT_DEG = 3.0
#: Largest angle [deg] of a closed turn's axis from the vertical: within it, gravity sees less than
#: sin(30°) = half of a gain error about the axis, so the known angle is what determines it. Turns about
#: tilted axes (the project's protocol turns from a corner) are left to the rest-to-rest invariant,
#: which sees them without assuming that the sensor came back to the same heading.
CLOSURE_MAX_TILT_DEG = 30.0
#: Largest departure [deg] of the raw angle turned from a whole number of turns for the turn to count
#: as closed: a gyro gain up to ~7 % off nominal (MEMS datasheets: ±1-3 %) and a put-back heading
#: within a few degrees. A larger departure is not a whole turn (or a unit error): not used.
TURN_TOLERANCE_DEG = 25.0
#: Noise of the heading to which a hand puts the sensor back after a turn [rad] (a box against an edge
#: of the table: ~0.5°); the starting value of the turn group's noise, which the fit re-estimates
#: when there are more closed turns than gain parameters they inform ...
TURN_SIGMA_RAD = float(np.radians(0.2))
#: ... never below this [rad]: the integration of a MEMS gyro's noise and residual bias over a turn.
TURN_FLOOR_RAD = float(np.radians(0.02))


@dataclass(frozen=True)
class ClosedTurn:
    """One closed turn: its segment (index into Segments), whole turns n (signed), the turn axis a (3,)
    and the perpendicular body vector h0 (3,) in the sensor frame (unit), the raw angle turned [deg]
    (gyro bias removed, gains 1), and the axis's angle from the vertical [deg]."""

    segment: int
    turns: int
    axis: np.ndarray
    h0: np.ndarray
    raw_deg: float
    axis_tilt_deg: float


def _perpendicular(a: np.ndarray) -> np.ndarray:
    """A unit vector perpendicular to unit a: a × (the sensor axis least aligned with a), normalised."""
    e = np.eye(3)[int(np.argmin(np.abs(a)))]
    v = np.cross(a, e)
    return v / np.linalg.norm(v)


#: Least rotation [deg] about a fixed axis between two rests of the same pose for a move to count as a
#: full turn (about any axis): what the ImuFusion protocol asks for, 360° from a corner.
FULL_TURN_DEG = 300.0


def count_full_turns(increments: list, start: np.ndarray, end: np.ndarray, present: np.ndarray) -> int:
    """Moves between two rests of the same pose (gravity within CLOSED_TILT_DEG) that turn at least
    FULL_TURN_DEG about one axis (the norm of the integrated rate), whatever the axis's tilt."""
    count = 0
    for k, inc in enumerate(increments):
        if present[k] and len(inc):
            tilt = np.degrees(np.arccos(np.clip(start[k] @ end[k], -1, 1)))
            count += int(tilt <= CLOSED_TILT_DEG and np.degrees(np.linalg.norm(inc.sum(axis=0))) >= FULL_TURN_DEG)
    return count


def find_closed_turns(increments: list, start: np.ndarray, end: np.ndarray, present: np.ndarray) -> list[ClosedTurn]:
    """The closed turns among segments with bias-corrected increments [(L_s, 3) rad], unit gravity
    directions at their start and end rests (S, 3) and whether gravity is known at both (S,) bool."""
    out = []
    for k, inc in enumerate(increments):
        if not present[k] or len(inc) == 0:
            continue
        up = start[k] / np.linalg.norm(start[k])
        if np.degrees(np.arccos(np.clip(up @ end[k] / np.linalg.norm(end[k]), -1, 1))) > CLOSED_TILT_DEG:
            continue
        total = inc.sum(axis=0)
        if np.linalg.norm(total) == 0:
            continue
        axis = total / np.linalg.norm(total)
        tilt = float(np.degrees(np.arccos(min(abs(axis @ up), 1.0))))
        if tilt > CLOSURE_MAX_TILT_DEG:
            continue
        h0 = _perpendicular(axis)
        raw = float(winding(attitudes(inc[None]), axis[None], h0[None])[0])
        n = int(round(raw / (2 * np.pi)))
        if n != 0 and abs(np.degrees(raw - 2 * np.pi * n)) <= TURN_TOLERANCE_DEG:
            out.append(ClosedTurn(k, n, axis, h0, float(np.degrees(raw)), tilt))
    return out
