"""Earth-field norm, dip and declination from position and date (IGRF via the `ppigrf` package).

`ppigrf` (PyPI, MIT) evaluates the current IGRF model with its maintained coefficient file; no
coefficients are written by hand here. Geodetic latitude/longitude in degrees, altitude in km
above the WGS-84 ellipsoid.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import datetime


@dataclass(frozen=True)
class EarthField:
    """norm_ut [µT], dip_deg [deg, positive down], declination_deg [deg, positive east],
    north_ut/east_ut/down_ut: the NED components [µT]."""

    norm_ut: float
    dip_deg: float
    declination_deg: float
    north_ut: float
    east_ut: float
    down_ut: float


def site_field(meta: dict) -> EarthField | None:
    """The IGRF field at the sidecar's optional site {"latitude_deg", "longitude_deg", "altitude_m" or
    "altitude_km" (default 0), "date" (ISO, default today)}; None when the sidecar gives no site or its
    latitude or longitude is null (unknown). ValueError names a malformed site."""
    from training.data.earth import site_altitude_m
    site = meta.get("site")
    if not site:
        return None
    try:
        lat, lon = (None if site.get(k) is None else float(site[k]) for k in ("latitude_deg", "longitude_deg"))
        if lat is None or lon is None:
            return None
        date = datetime.fromisoformat(str(site["date"])) if site.get("date") else datetime.now()
        return earth_field(lat, lon, (site_altitude_m(site) or 0.0) / 1000.0, date)
    except (AttributeError, KeyError, TypeError, ValueError) as e:
        raise ValueError(f"sidecar site {site}: {e!r} (expected latitude_deg, longitude_deg, "
                         "altitude_m or altitude_km, date)") from None


def earth_field(latitude_deg: float, longitude_deg: float, altitude_km: float,
                date: datetime) -> EarthField:
    """IGRF main field at a geodetic position and date."""
    import ppigrf  # lazy: only this function needs it

    east, north, up = ppigrf.igrf(longitude_deg, latitude_deg, altitude_km, date)
    e, n, d = float(east.squeeze()) / 1e3, float(north.squeeze()) / 1e3, -float(up.squeeze()) / 1e3
    horizontal = math.hypot(n, e)
    return EarthField(norm_ut=math.sqrt(n * n + e * e + d * d),
                      dip_deg=math.degrees(math.atan2(d, horizontal)),
                      declination_deg=math.degrees(math.atan2(e, n)),
                      north_ut=n, east_ut=e, down_ut=d)
