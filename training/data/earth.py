"""Earth gravity and magnetic field in the NED frame (true north)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Standard gravity [m/s²] (CGPM 1901); the simulator uses a flat, uniform gravity field.
STANDARD_GRAVITY = 9.80665
#: Gravity vector in NED [m/s²]: it points down, so a level sensor at rest measures
#: specific force f = −g = [0, 0, −9.80665].
GRAVITY_NED = np.array([0.0, 0.0, STANDARD_GRAVITY])


@dataclass(frozen=True)
class EarthField:
    """Local geomagnetic field: magnitude [µT], dip (inclination, positive down) [deg] and
    declination (magnetic north east of true north) [deg]."""

    norm_ut: float
    dip_deg: float
    declination_deg: float

    def field_ned(self) -> np.ndarray:
        """Field vector (3,) in true-north NED [µT]:
        m_n = |m| · [cos(dip) cos(decl), cos(dip) sin(decl), sin(dip)]."""
        dip, decl = np.deg2rad(self.dip_deg), np.deg2rad(self.declination_deg)
        return self.norm_ut * np.array([np.cos(dip) * np.cos(decl),
                                        np.cos(dip) * np.sin(decl),
                                        np.sin(dip)])

    def as_meta(self) -> dict:
        """The sidecar 'earth_field' entry of imu-csv/1."""
        return {"norm_ut": self.norm_ut, "dip_deg": self.dip_deg,
                "declination_deg": self.declination_deg}
