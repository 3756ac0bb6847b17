"""Mounting in the data: what the mounting settings (contract.mounting) should be for a recording,
and a recording's references expressed in the body axes of a mounting. The body axes are FRD, so
at rest and level the specific force reads −g on body z. The runtime calibrates in the sensor's
axes, then turns the result into the body axes, where it estimates the attitude and gives every
vector output.

One rule decides the body axes (issue 35), whatever references the calibration recordings carry:

1. a declaration, when there is one: `train --mounting 1,-2,-3`, else the sidecar key
   `"mounting": [1, -2, -3]` (codes as mount_x, mount_y, mount_z; the recordings that declare one
   must agree);
2. else the data: a board that at rest reads the specific force along +z (its z axis points up) is
   mounted as (1, −2, −3), a 180° turn about x that keeps x forward; along −z, the sensor axes are
   the body axes. Any other direction of gravity at rest is reported, not guessed: which way is
   forward is not in the data.

An attitude reference (ref_q) does not decide: it is in the sensor axes, as every data set publishes
it, and is expressed in the body axes (body_references) wherever it is compared with the outputs.
So the same sensor trained on the same motions with and without its reference gets the same frame.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from contract.errors import ModelError
from contract.mounting import IDENTITY, MOUNT_SETTINGS, Z_UP, frame_text, mount_matrix, mounting_problem
from training.data.dataset import ImuData
from training.data.earth import STANDARD_GRAVITY, local_gravity
from training.frames import quat_from_matrix, quat_multiply

#: A sample counts as quasi-static for the direction of gravity when its specific force is within
#: this of the recording's local g [m/s²] (0.05 g: walking, handling and vibration exceed it)...
STATIC_ACC_TOLERANCE = 0.05 * STANDARD_GRAVITY
#: ...and its raw rate below this [rad/s] (0.2 rad/s = 11 °/s: far above any MEMS gyro bias, far
#: below a deliberate turn; centripetal and tangential accelerations then stay small).
STATIC_RATE = 0.2
#: Fewest quasi-static samples before the data tell the mounting (1 s at 100 Hz).
MIN_STATIC_SAMPLES = 100
#: The median quasi-static gravity direction must be within this angle of a sensor axis [deg]
#: for train to act on it: 30° is a board visibly tilted, not mounted another way.
AXIS_TOLERANCE_DEG = 30.0
#: ...and at least this share of the quasi-static samples within that angle of the axis: the board rests
#: mostly one way up. A multi-position calibration (six faces, 11 % each) has no such axis; its median
#: direction is an accident of which poses lasted longest (the two-soak scenario's landed 10° from +z).
MIN_AXIS_SHARE = 0.5


def body_references(data: ImuData, codes) -> ImuData:
    """A copy of `data` whose references are in the body axes of the mounting `codes`: the vector
    references turned by M, the attitude q_ref ⊗ q(Mᵀ) (body -> NED = sensor -> NED · body -> sensor).
    The identity returns `data` itself."""
    if tuple(int(c) for c in codes) == IDENTITY:
        return data
    m = mount_matrix(codes)

    def turned(ref):
        return None if ref is None else ref @ m.T
    ref_q = None if data.ref_q is None else body_attitude(data.ref_q, codes)
    return replace(data, ref_gyr=turned(data.ref_gyr), ref_acc=turned(data.ref_acc),
                   ref_mag=turned(data.ref_mag), ref_q=ref_q)


def body_attitude(q_sensor: np.ndarray, codes) -> np.ndarray:
    """(N, 4) sensor -> nav quaternions as body -> nav of the mounting `codes`:
    q ⊗ q(Mᵀ) (body -> nav = sensor -> nav · body -> sensor)."""
    q_body_to_sensor = quat_from_matrix(mount_matrix(codes).T)
    return quat_multiply(q_sensor, np.tile(q_body_to_sensor, (len(q_sensor), 1)))


def sensor_attitude(q_body: np.ndarray, codes) -> np.ndarray:
    """(N, 4) body -> nav quaternions of the mounting `codes` as sensor -> nav: q ⊗ q(M) (sensor -> nav =
    body -> nav · sensor -> body); the inverse of body_attitude, what the FMU's q_sensor_* outputs give."""
    q_sensor_to_body = quat_from_matrix(mount_matrix(codes))
    return quat_multiply(np.asarray(q_body, float), np.tile(q_sensor_to_body, (len(q_body), 1)))


def _static_directions(data: ImuData) -> np.ndarray:
    """(K, 3) unit vectors of the specific force at the quasi-static samples of a recording."""
    acc, gyr = np.asarray(data.acc, float), np.asarray(data.gyr, float)
    norm = np.linalg.norm(acc, axis=1)
    rate = np.linalg.norm(gyr, axis=1) if data.has("gyr") else np.zeros(len(data))
    try:
        g = local_gravity(data.meta)[0]
    except ValueError:
        g = STANDARD_GRAVITY
    static = np.isfinite(norm) & (np.abs(norm - g) < STATIC_ACC_TOLERANCE) & (np.nan_to_num(rate) < STATIC_RATE)
    return acc[static] / norm[static, None]


def gravity_axis(data: ImuData) -> tuple[str, float, float] | None:
    """(signed sensor axis such as '+z', angle [deg] to it, share of the quasi-static samples within
    AXIS_TOLERANCE_DEG of it) of the median direction of the specific force at rest, or None when fewer than
    MIN_STATIC_SAMPLES samples are quasi-static. At rest the specific force points up, away from gravity:
    '+z' means the z axis points up."""
    if not data.has("acc"):
        return None
    directions = _static_directions(data)
    if len(directions) < MIN_STATIC_SAMPLES:
        return None
    median = np.median(directions, axis=0)
    if not np.linalg.norm(median) > 0.0:
        return None  # rests every way up in equal shares: no direction to speak of
    median /= np.linalg.norm(median)
    axis = int(np.argmax(np.abs(median)))
    angle = float(np.rad2deg(np.arccos(min(1.0, abs(median[axis])))))
    sign = 1.0 if median[axis] > 0 else -1.0
    share = float(np.mean(sign * directions[:, axis] >= np.cos(np.deg2rad(AXIS_TOLERANCE_DEG))))
    return ("+" if sign > 0 else "-") + "xyz"[axis], angle, share


def declared_mounting(datasets: list[ImuData], declared=None) -> tuple[tuple[int, int, int], str] | None:
    """(codes, where they were declared) of the mounting declared by `train --mounting` (`declared`, codes)
    or, without it, by the sidecars' "mounting" key; None when nothing declares one. ModelError when the
    codes are no mounting or two sidecars declare different ones."""
    if declared is not None:
        codes, source = tuple(declared), "train --mounting"
    else:
        found = {d.name: tuple(d.meta["mounting"]) for d in datasets if d.meta.get("mounting") is not None}
        if not found:
            return None
        if len(set(found.values())) > 1:
            raise ModelError("train: the sidecars declare different mountings ("
                             + "; ".join(f"{name}: {list(c)}" for name, c in found.items())
                             + "): one sensor, one mounting; pass train --mounting to say which")
        codes, source = next(iter(found.values())), "the sidecar 'mounting' of " + ", ".join(found)
    problem = mounting_problem(codes)
    if problem is not None:
        raise ModelError(f"train: the mounting declared by {source}: {problem}")
    return tuple(int(c) for c in codes), source


def recommended_mounting(datasets: list[ImuData], notes: list[str], declared=None) -> dict[str, float]:
    """mount_x, mount_y, mount_z from a declaration (`declared`: train --mounting's codes; the sidecars'
    "mounting") or else from the direction of gravity at rest in the calibration recordings, by the same
    rule whether or not they carry a reference (see the module docstring); a note for every mounting set
    and every direction of gravity train does not act on."""
    found = declared_mounting(datasets, declared)
    if found is not None:
        codes, source = found
        notes.append(f"mounting: declared by {source}: {frame_text(codes)}")
        return dict(zip(MOUNT_SETTINGS, map(float, codes)))
    told = {d.name: axis for d in datasets if (axis := gravity_axis(d)) is not None}
    text = ", ".join(f"sensor {axis} ({angle:.0f}° off it; {100 * share:.0f} % of the rest samples within "
                     f"{AXIS_TOLERANCE_DEG:.0f}°) in {name}" for name, (axis, angle, share) in told.items())
    rests_one_way = {name: angle <= AXIS_TOLERANCE_DEG and share >= MIN_AXIS_SHARE
                     for name, (_, angle, share) in told.items()}
    clear = all(rests_one_way.values())
    axes = {axis for axis, _, _ in told.values()}
    if clear and axes == {"+z"}:
        notes.append(f"mounting: at rest the specific force points along the sensor's +z axis ({text}): the board's z axis "
                     "points up; mount_x, mount_y, mount_z = 1, -2, -3 (body = x, -y, -z, a 180° turn about x) so "
                     "that the attitude is in FRD/NED; declare it (sidecar \"mounting\", train --mounting) if x is "
                     "not forward")
        return dict(zip(MOUNT_SETTINGS, map(float, Z_UP)))
    if any(one_way and told[name][0] != "-z" for name, one_way in rests_one_way.items()):
        notes.append(f"mounting: at rest the specific force points along {text}, not along sensor -z (z down) "
                     "throughout; body axes = sensor axes kept: declare the mounting (sidecar \"mounting\", "
                     "train --mounting; docs/fmu.md, Frames) if the board is mounted another way")
    return {}


def frame_lines(settings: dict[str, float], notes: list[str]) -> list[str]:
    """The first lines of the calibration summary (issue 35): the body frame of the trained model's outputs
    (its settings' mount_x..z) and what decided it (its 'mounting:' note: a declaration or the data)."""
    from contract.mounting import settings_codes
    codes = settings_codes(settings)
    told = next((n[len("mounting: "):] for n in notes if n.startswith("mounting: ")), None)
    if told is not None and told.startswith("declared by "):
        source = told.split(": ", 1)[0]
    elif told is not None and codes == Z_UP:
        source = ("decided from the data: at rest gravity reads along sensor +z (z up), the same rule with or "
                  "without a reference")
    elif told is not None:
        source = "the data do not tell (gravity at rest not along sensor -z throughout): sensor axes kept"
    else:
        source = ("decided from the data: at rest gravity reads along sensor -z (z down) or no rest was seen, "
                  "the same rule with or without a reference")
    return [f"frame: {frame_text(codes)} ({source}; declare it with train --mounting or the sidecar's \"mounting\")",
            "  the FMU's rate_*, accel_*, field_*, roll, pitch, yaw, heading and q_* are in these body axes "
            "(NED); q_sensor_* is the attitude of the sensor axes"]
