"""What the mounting settings mean (sources/ImuMount.h): mount_x, mount_y, mount_z name the sensor
axis that each FRD body axis is, with its sign (1 = +x, 2 = +y, 3 = +z, negative: the opposite
direction); the three must name different axes and stay right-handed. training.mounting finds the
mounting in the data."""
from __future__ import annotations

import numpy as np

from contract.layout import SETTINGS
from contract.variables import BODY_FRAME

#: The mounting settings, in body-axis order.
MOUNT_SETTINGS = ("mount_x", "mount_y", "mount_z")
#: Body axes = sensor axes.
IDENTITY = (1, 2, 3)
#: A board whose z axis points up, x forward: body = (x, −y, −z), 180° about x.
Z_UP = (1, -2, -3)


def mount_matrix(codes) -> np.ndarray:
    """(3, 3) matrix M with v_body = M · v_sensor for the codes (mount_x, mount_y, mount_z)."""
    m = np.zeros((3, 3))
    for row, code in enumerate(codes):
        m[row, abs(int(code)) - 1] = np.sign(code)
    return m


def mounting_problem(codes) -> str | None:
    """Why the codes (mount_x, mount_y, mount_z) are no mounting, or None (the check of
    ImuPipelineSettingsCheck: three different signed axes that stay right-handed)."""
    if any(not float(c).is_integer() or abs(c) not in (1, 2, 3) for c in codes):
        return "mount_x, mount_y, mount_z must each be ±1, ±2 or ±3 (a sensor axis with its sign)"
    if len({abs(int(c)) for c in codes}) != 3:
        return f"mount_x, mount_y, mount_z = {tuple(int(c) for c in codes)} name a sensor axis twice"
    if round(np.linalg.det(mount_matrix(codes))) != 1:
        return (f"mount_x, mount_y, mount_z = {tuple(int(c) for c in codes)} mirror the axes (left-handed); "
                "flip the sign of one of them")
    return None


def frame_text(codes) -> str:
    """The body frame of the mounting `codes` in one line: 'body axes = sensor axes turned by mount_x..z =
    1, -2, -3 (body x = +x, y = -y, z = -z of the sensor: 180° about x)'; identity: 'body axes = sensor axes
    (mount_x..z = 1, 2, 3)'."""
    codes = tuple(int(c) for c in codes)
    if codes == IDENTITY:
        return "body axes = sensor axes (mount_x..z = 1, 2, 3)"
    axes = ", ".join(f"{body} = {'+' if c > 0 else '-'}{'xyz'[abs(c) - 1]}" for body, c in zip("xyz", codes))
    angle, axis = _rotation(codes)
    return (f"{BODY_FRAME} = {', '.join(map(str, codes))} (body {axes} of the sensor: "
            f"{angle:.0f}° about sensor [{', '.join(f'{v:.3g}' for v in axis)}])")


def _rotation(codes) -> tuple[float, np.ndarray]:
    """(angle [deg], unit axis (3,) in sensor axes) of the turn that carries the sensor axes onto the body
    axes of `codes` (the rotation whose matrix is Mᵀ: body axis i = Mᵀ e_i in sensor coordinates)."""
    r = mount_matrix(codes).T
    angle = float(np.degrees(np.arccos(np.clip((np.trace(r) - 1.0) / 2.0, -1.0, 1.0))))
    if angle > 179.0:  # 180°: the axis is the column of (R + I) / 2 with the largest norm
        b = (r + np.eye(3)) / 2.0
        axis = b[:, int(np.argmax(np.linalg.norm(b, axis=0)))]
    else:
        axis = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    axis = axis / np.linalg.norm(axis)
    return angle, axis + 0.0  # no -0


def settings_codes(settings: dict[str, float]) -> tuple[int, int, int]:
    """The mounting codes of a settings dict (identity where a code is missing)."""
    return tuple(int(settings.get(name, default)) for name, default in zip(MOUNT_SETTINGS, IDENTITY))


def array_codes(settings) -> tuple[int, int, int]:
    """The mounting codes of a flat settings array (contract.layout.SETTINGS order)."""
    names = [name for name, _ in SETTINGS]
    return tuple(int(settings[names.index(name)]) for name in MOUNT_SETTINGS)
