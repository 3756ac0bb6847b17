"""Earth gravity and magnetic field in the NED frame (true north), and the local gravity of a recording."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Standard gravity [m/s²] (CGPM 1901): the default when a recording says nothing about its site.
STANDARD_GRAVITY = 9.80665
#: Gravity vector in NED [m/s²] at standard gravity: it points down, so a level sensor at rest
#: measures specific force f = −g = [0, 0, −9.80665]. `gravity_ned` gives it for another g.
GRAVITY_NED = np.array([0.0, 0.0, STANDARD_GRAVITY])
#: Accepted sidecar gravity_mps2 [m/s²]. Gravity on the Earth's surface spans 9.764 (Nevado Huascarán)
#: to 9.834 (the Arctic Ocean); the margin covers heights up to SITE_ALTITUDE_M's 20 km (−0.06). A
#: value outside is another unit (cm/s² = Gal: 981; g: 1.0; ft/s²: 32.2) or a typing error.
GRAVITY_RANGE_MPS2 = (9.7, 9.9)
#: Accepted site altitude [m above the WGS-84 ellipsoid]: the shore of the Dead Sea (−430 m) to 20 km
#: (aircraft, balloons); beyond, the free-air gradient below is no longer the normal field's and the
#: number is more likely feet or a wrong unit.
SITE_ALTITUDE_M = (-500.0, 20000.0)

# WGS-84 normal gravity (NIMA TR8350.2, 3rd ed. 2000, eq. 4-1 and table 3.4): Somigliana's closed form
# on the ellipsoid, γ(φ) = γ_e (1 + k sin²φ) / √(1 − e² sin²φ), k = b γ_p / (a γ_e) − 1.
WGS84_GAMMA_EQUATOR = 9.7803253359      # γ_e [m/s²]
WGS84_GAMMA_POLE = 9.8321849378         # γ_p [m/s²]
WGS84_K = 0.00193185265241              # k [1]
WGS84_E2 = 0.00669437999013             # e² [1], first eccentricity squared
#: Free-air gradient of normal gravity [m/s² per m of height] (Hofmann-Wellenhof & Moritz, Physical
#: Geodesy, 2nd ed. 2006, eq. 2-124: −0.3086 mGal/m).
FREE_AIR_GRADIENT = -3.086e-6


def normal_gravity(latitude_deg: float, altitude_m: float = 0.0) -> float:
    """Normal gravity [m/s²] of the WGS-84 ellipsoid at geodetic latitude [deg] and height [m]:
    Somigliana's closed form γ(φ) = γ_e (1 + k sin²φ) / √(1 − e² sin²φ) (NIMA TR8350.2 eq. 4-1) plus the
    free-air correction FREE_AIR_GRADIENT · h. Real gravity departs from it by the local anomaly, typically
    below 0.001 m/s² (100 mGal, 0.01 %)."""
    s2 = math.sin(math.radians(latitude_deg)) ** 2
    return WGS84_GAMMA_EQUATOR * (1.0 + WGS84_K * s2) / math.sqrt(1.0 - WGS84_E2 * s2) + FREE_AIR_GRADIENT * altitude_m


def site_altitude_m(site: dict) -> float | None:
    """The site's altitude [m] from 'altitude_m' or 'altitude_km' (both accepted; ARCHITECTURE.md names
    altitude_m, the first sidecars altitude_km); None when neither is given (or both are null)."""
    if site.get("altitude_m") is not None:
        return float(site["altitude_m"])
    if site.get("altitude_km") is not None:
        return 1000.0 * float(site["altitude_km"])
    return None


def local_gravity(meta: dict) -> tuple[float, str]:
    """(g [m/s²], where it came from) for a recording's sidecar: 'gravity_mps2' when it gives one; else
    the normal gravity at its site's latitude and altitude (`normal_gravity`; sea level when the site
    gives no altitude); else STANDARD_GRAVITY. The one source of the g that the accelerometer is
    scaled to (self-calibration, held-out scores, specific-force references). ValueError names a
    value that is not a number (training/data/sidecar.py refuses those when a file is read)."""
    try:
        value = meta.get("gravity_mps2")
        if value is not None:
            return float(value), "the sidecar's gravity_mps2"
        site = meta.get("site") or {}
        if site.get("latitude_deg") is not None:
            latitude, altitude = float(site["latitude_deg"]), site_altitude_m(site)
            where = f"latitude {latitude:g}°, " + (f"altitude {altitude:g} m" if altitude is not None
                                                   else "altitude not given: sea level")
            return normal_gravity(latitude, altitude or 0.0), f"WGS-84 normal gravity at the sidecar's site ({where})"
    except (AttributeError, TypeError, ValueError) as e:
        raise ValueError(f"sidecar gravity_mps2 {meta.get('gravity_mps2')!r} / site {meta.get('site')!r}: "
                         f"{e} (expected numbers: gravity_mps2 in m/s², site latitude_deg, altitude_m)") from None
    return STANDARD_GRAVITY, "standard gravity (the sidecar gives neither gravity_mps2 nor a site latitude)"


def recordings_gravity(recordings) -> tuple[float, str]:
    """(g [m/s²], a note line) for the recordings of one sensor unit (objects with .meta and .name, e.g.
    ImuData): `local_gravity` of each, their mean when they differ (recordings at several sites), with
    what each came from. ModelError names a recording whose sidecar gravity or site is not a number."""
    from contract.errors import ModelError
    values = []
    for r in recordings:
        try:
            values.append(local_gravity(r.meta))
        except ValueError as e:
            raise ModelError(f"{r.name}: {e}") from None
    if not values:
        return STANDARD_GRAVITY, "gravity: standard gravity (no recording)"
    g = float(np.mean([v for v, _ in values]))
    sources = sorted({s for _, s in values})
    if max(v for v, _ in values) > min(v for v, _ in values):
        return g, (f"gravity: {g:.5f} m/s², the mean of the recordings' {', '.join(f'{v:.5f}' for v, _ in values)} "
                   f"m/s² ({'; '.join(sources)}); the accelerometer is scaled to it")
    return g, f"gravity: {g:.5f} m/s² from {sources[0]}; the accelerometer is scaled to it"


def gravity_ned(g: float) -> np.ndarray:
    """Gravity vector (3,) in NED [m/s²] of magnitude g: [0, 0, g]."""
    return np.array([0.0, 0.0, float(g)])


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
