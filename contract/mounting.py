"""What the mounting settings mean (sources/ImuMount.h): mount_x, mount_y, mount_z name the sensor
axis that each FRD body axis is, with its sign (1 = +x, 2 = +y, 3 = +z, negative: the opposite
direction); the three must name different axes and stay right-handed. training.mounting finds the
mounting in the data."""
from __future__ import annotations

import numpy as np

from contract.layout import SETTINGS

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


def settings_codes(settings: dict[str, float]) -> tuple[int, int, int]:
    """The mounting codes of a settings dict (identity where a code is missing)."""
    return tuple(int(settings.get(name, default)) for name, default in zip(MOUNT_SETTINGS, IDENTITY))


def array_codes(settings) -> tuple[int, int, int]:
    """The mounting codes of a flat settings array (contract.layout.SETTINGS order)."""
    names = [name for name, _ in SETTINGS]
    return tuple(int(settings[names.index(name)]) for name in MOUNT_SETTINGS)
