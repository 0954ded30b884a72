"""Local ENU metres to WGS-84 latitude and longitude and back, near a reference point."""

from __future__ import annotations

import math

import numpy as np

A_WGS84 = 6378137.0
E2_WGS84 = 6.69437999014e-3


class Geo:
    """Tangent-plane conversion with the ellipsoid's radii of curvature at the reference latitude."""

    def __init__(self, lat0: float, lon0: float) -> None:
        self.lat0, self.lon0 = lat0, lon0
        s = math.sin(math.radians(lat0))
        w = math.sqrt(1.0 - E2_WGS84 * s * s)
        self.m_per_deg_lat = math.radians(1.0) * A_WGS84 * (1.0 - E2_WGS84) / w**3
        self.m_per_deg_lon = math.radians(1.0) * A_WGS84 / w * math.cos(math.radians(lat0))

    def to_latlon(self, x, y):  # type: ignore[no-untyped-def]
        return self.lat0 + np.asarray(y) / self.m_per_deg_lat, self.lon0 + np.asarray(
            x
        ) / self.m_per_deg_lon

    def to_local(self, lat, lon):  # type: ignore[no-untyped-def]
        return (np.asarray(lon) - self.lon0) * self.m_per_deg_lon, (
            np.asarray(lat) - self.lat0
        ) * self.m_per_deg_lat
