"""The one geodesy: WGS-84 local tangent plane, compass angles and the vector conventions.

Local frames are metres east (x) and north (y) of a reference point: an equirectangular projection
scaled by the WGS-84 ellipsoid's radii of curvature at the reference latitude. Against WGS-84 geodesics
(tests/test_vessel.py) distances along x or y are right to 3 mm over 2 km; diagonal ones are off by
about 1 part in 10,000 of the distance at 50 deg latitude (7 cm in 1.9 km at 34 deg, 14 cm at 51 deg),
because the meridians converge and the projection keeps them parallel. Angles are compass degrees, clockwise from true north; vectors are
(east, north) in the world or (forward, starboard) on the boat; a medium's vector is where it moves TO.
"""

from __future__ import annotations

import math

import numpy as np

A_WGS84 = 6378137.0
E2_WGS84 = 6.69437999014e-3

Vec = tuple[float, float]


class LocalFrame:
    """Metres east and north of (lat0, lon0) with WGS-84's radii of curvature there, and back."""

    def __init__(self, lat0: float, lon0: float) -> None:
        self.lat0, self.lon0 = lat0, lon0
        s = math.sin(math.radians(lat0))
        w = math.sqrt(1.0 - E2_WGS84 * s * s)
        self.m_per_deg_lat = math.radians(1.0) * A_WGS84 * (1.0 - E2_WGS84) / w**3
        self.m_per_deg_lon = math.radians(1.0) * A_WGS84 / w * math.cos(math.radians(lat0))

    def to_latlon(self, x, y):  # type: ignore[no-untyped-def]
        """(lat, lon) in degrees of local (x, y) in metres (scalars or arrays)."""
        return self.lat0 + np.asarray(y) / self.m_per_deg_lat, self.lon0 + np.asarray(
            x
        ) / self.m_per_deg_lon

    def to_local(self, lat, lon):  # type: ignore[no-untyped-def]
        """(x east, y north) in metres of (lat, lon) in degrees (scalars or arrays)."""
        return (np.asarray(lon) - self.lon0) * self.m_per_deg_lon, (
            np.asarray(lat) - self.lat0
        ) * self.m_per_deg_lat

    def points_to_local(self, latlon: np.ndarray) -> np.ndarray:
        """Points (..., 2) of (lat, lon) as points (..., 2) of (x, y)."""
        ll = np.asarray(latlon, dtype=float)
        return np.stack(self.to_local(ll[..., 0], ll[..., 1]), axis=-1)

    def points_to_latlon(self, xy: np.ndarray) -> np.ndarray:
        """Points (..., 2) of (x, y) as points (..., 2) of (lat, lon)."""
        p = np.asarray(xy, dtype=float)
        return np.stack(self.to_latlon(p[..., 0], p[..., 1]), axis=-1)


# --- angles ------------------------------------------------------------------------------------------


def wrap360(deg: float) -> float:
    """An angle in [0, 360)."""
    a = deg % 360.0
    return 0.0 if a >= 360.0 else a


def wrap_to_180(deg: float) -> float:
    """An angle in (-180, 180]: +180 stays +180 (a relative angle: astern is 180, not -180)."""
    a = deg % 360.0
    return a - 360.0 if a > 180.0 else a


def wrap_from_minus180(deg: np.ndarray) -> np.ndarray:
    """Angles (an array) in [-180, 180): +180 becomes -180 (a deviation; only its size matters)."""
    return (deg + 180.0) % 360.0 - 180.0


def wrap_from_minus_pi(rad: float) -> float:
    """An angle in radians in [-pi, pi) (a heading error for the autopilot)."""
    return (rad + math.pi) % (2.0 * math.pi) - math.pi


# --- vectors -----------------------------------------------------------------------------------------


def boat_to_world(fwd: float, stbd: float, heading_deg: float) -> Vec:
    """A boat-frame vector (forward, starboard) in the world frame (east, north)."""
    h = math.radians(heading_deg)
    s, c = math.sin(h), math.cos(h)
    return fwd * s + stbd * c, fwd * c - stbd * s


def world_to_boat(east: float, north: float, heading_deg: float) -> Vec:
    """A world-frame vector (east, north) in the boat frame (forward, starboard)."""
    h = math.radians(heading_deg)
    s, c = math.sin(h), math.cos(h)
    return east * s + north * c, east * c - north * s


def from_direction(east: float, north: float) -> float:
    """Compass direction a medium comes FROM (wind convention)."""
    return wrap360(math.degrees(math.atan2(-east, -north)))


def to_direction(east: float, north: float) -> float:
    """Compass direction a medium flows TO (current convention, also course over ground)."""
    return wrap360(math.degrees(math.atan2(east, north)))


def velocity(speed: float, course_deg: float) -> Vec:
    """(east, north) of a velocity given as speed and compass course (TO)."""
    c = math.radians(course_deg)
    return speed * math.sin(c), speed * math.cos(c)
