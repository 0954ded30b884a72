"""Pure functions that remove the boat's motion from wind and current readings (docs/COMPENSATION.md).

Vectors are (east, north) in the world frame or (forward, starboard) in the boat frame, in m/s, and
always the velocity of the medium (where the air or water moves TO). Angles in arguments and results
are degrees: compass angles clockwise from true north, relative angles clockwise from the bow.
"""

from __future__ import annotations

import math
from itertools import product

from forcemap.host.vessel.geodesy import (  # noqa: F401  (the conventions this module computes in)
    Vec,
    boat_to_world,
    from_direction,
    to_direction,
    velocity,
    world_to_boat,
    wrap360,
    wrap_to_180,
)

UNDER_WAY = 0.3  # m/s of water past the hull above which the boat is taken to make way


# --- wind -----------------------------------------------------------------------------------------


def apparent_wind_speed(
    rate_hz: float, mps_per_hz: float = 0.6667, min_speed: float = 0.0
) -> float:
    """Apparent wind speed from the anemometer's closure rate."""
    v = rate_hz * mps_per_hz
    return v if v >= min_speed else 0.0


def apparent_wind_boat(speed: float, angle_deg: float) -> Vec:
    """Air velocity relative to the boat, boat frame, from the apparent wind speed and the angle it
    comes FROM (clockwise from the bow)."""
    a = math.radians(angle_deg)
    return -speed * math.cos(a), -speed * math.sin(a)


def true_wind(
    app_speed: float, app_angle_deg: float, heading_deg: float, boat_east: float, boat_north: float
) -> Vec:
    """Air velocity over ground W = R + V_boat (east, north).

    ``R`` is the apparent wind rotated from the boat frame by the heading; ``V_boat`` the boat's
    velocity over ground. Signal K's ground wind uses ``V_boat`` = SOG along the heading.
    """
    f, s = apparent_wind_boat(app_speed, app_angle_deg)
    re, rn = boat_to_world(f, s, heading_deg)
    return re + boat_east, rn + boat_north


def apparent_from_true(
    wind_east: float, wind_north: float, heading_deg: float, boat_east: float, boat_north: float
) -> tuple[float, float]:
    """Inverse of ``true_wind``: (apparent speed, apparent angle FROM relative to the bow)."""
    f, s = world_to_boat(wind_east - boat_east, wind_north - boat_north, heading_deg)
    return math.hypot(f, s), wrap_to_180(math.degrees(math.atan2(-s, -f)))


# --- current --------------------------------------------------------------------------------------


def wheel_speed(rate_hz: float, pulses_per_m: float, min_speed: float = 0.0) -> float:
    """Unsigned water speed along a paddle wheel's axis; below the cut-off it reads 0."""
    v = rate_hz / pulses_per_m
    return v if v >= min_speed else 0.0


def wheel_readings(
    flow_fwd: float, flow_stbd: float, angles_deg: list[float] | tuple[float, ...]
) -> list[float]:
    """What ideal wheels read for a water velocity relative to the hull: |F . axis_i| (the model)."""
    out = []
    for a in angles_deg:
        r = math.radians(a)
        out.append(abs(flow_fwd * math.cos(r) + flow_stbd * math.sin(r)))
    return out


def current_paper(
    speeds: list[float] | tuple[float, ...], angles_deg: list[float] | tuple[float, ...]
) -> Vec:
    """The paper's F1/F2 estimate of the water velocity relative to the hull, boat frame.

    F1 is the highest wheel, F2 the higher of its two neighbours around the hull. The water comes
    from the quadrant between them: from ``a1 + atan2(F2, F1)`` turned toward ``a2`` (the paper's
    ``theta - 45 deg`` with its wheels at 45 deg off the bow), with speed ``hypot(F1, F2)``.
    """
    n = len(speeds)
    order = sorted(range(n), key=lambda i: wrap360(angles_deg[i]))
    i = max(range(n), key=lambda k: speeds[k])
    pos = order.index(i)
    left, right = order[(pos - 1) % n], order[(pos + 1) % n]
    j = left if speeds[left] > speeds[right] else right
    f1, f2 = speeds[i], speeds[j]
    if f1 <= 0.0:
        return 0.0, 0.0
    delta = wrap_to_180(angles_deg[j] - angles_deg[i])
    theta = math.degrees(math.atan2(f2, f1)) * abs(delta) / 90.0
    beta = math.radians(angles_deg[i] + math.copysign(theta, delta))
    mag = math.hypot(f1, f2)
    return -mag * math.cos(beta), -mag * math.sin(beta)


class LsqGeometry:
    """Precomputed pseudo-inverses of the wheel geometry for ``current_lsq``."""

    def __init__(self, angles_deg: list[float] | tuple[float, ...]) -> None:
        self.angles = tuple(float(a) for a in angles_deg)
        self.u = [(math.cos(math.radians(a)), math.sin(math.radians(a))) for a in self.angles]
        sxx = sum(c * c for c, _ in self.u)
        sxy = sum(c * s for c, s in self.u)
        syy = sum(s * s for _, s in self.u)
        det = sxx * syy - sxy * sxy
        if abs(det) < 1e-9:
            raise ValueError("wheel axes are all parallel: the flow is not observable")
        ixx, ixy, iyy = syy / det, -sxy / det, sxx / det
        # rows of (U^T U)^-1 U^T
        self.p = [(ixx * c + ixy * s, ixy * c + iyy * s) for c, s in self.u]
        n = len(self.u)
        self.signs = [(1.0, *rest) for rest in product((1.0, -1.0), repeat=n - 1)]


_GEOMS: dict[tuple[float, ...], LsqGeometry] = {}


def _geometry(angles_deg: list[float] | tuple[float, ...]) -> LsqGeometry:
    key = tuple(float(a) for a in angles_deg)
    g = _GEOMS.get(key)
    if g is None:
        g = _GEOMS[key] = LsqGeometry(key)
    return g


def current_lsq_candidates(
    speeds: list[float] | tuple[float, ...], angles_deg: list[float] | tuple[float, ...]
) -> list[tuple[float, Vec]]:
    """Every local solution of min sum (m_i - |u_i . F|)^2 as (residual, F), best first.

    For a fixed sign of each wheel's component the problem is linear, so trying every sign pattern
    (the multiple starts) finds the global minimum. F and -F fit equally: both are listed.
    """
    g = _geometry(angles_deg)
    out = []
    for sg in g.signs:
        f = s = 0.0
        for k, (pf, ps) in enumerate(g.p):
            v = sg[k] * speeds[k]
            f += pf * v
            s += ps * v
        res = 0.0
        for k, (c, si) in enumerate(g.u):
            d = speeds[k] - abs(f * c + s * si)
            res += d * d
        out.append((res, (f, s)))
        out.append((res, (-f, -s)))
    out.sort(key=lambda x: x[0])
    return out


def current_lsq(
    speeds: list[float] | tuple[float, ...],
    angles_deg: list[float] | tuple[float, ...],
    noise: float = 0.03,
) -> tuple[Vec, bool]:
    """Least-squares water velocity relative to the hull, boat frame, and whether it is doubtful.

    A wheel has no sign, so F and -F always fit alike, and with opposite wheels sharing an axis
    (the usual +-45/+-135 mounting) so does F mirrored across a wheel axis. Among the solutions that
    fit within the wheel noise, the one with the water coming most from ahead wins: a boat under
    way meets the water bow first (leeway under 45 deg). The result is doubtful when other
    solutions fit as well and that prior is weak: the water passes slower than ``UNDER_WAY``
    (the boat hardly makes way) or even the chosen one comes from more than 45 deg off the bow.
    """
    cands = current_lsq_candidates(speeds, angles_deg)
    best = cands[0][0]
    tol = best + 4.0 * len(speeds) * noise * noise
    good = [fs for r, fs in cands if r <= tol]
    f, s = min(good, key=lambda fs: fs[0])
    distinct = {(round(a, 3), round(b, 3)) for a, b in good if a < 0.0}
    weak = math.hypot(f, s) < UNDER_WAY or -f < abs(s)
    return (f, s), len(distinct) > 1 and weak


def current_over_ground(
    flow_fwd: float, flow_stbd: float, heading_deg: float, boat_east: float, boat_north: float
) -> Vec:
    """Water velocity over ground C = F + V_boat, world frame (east, north)."""
    fe, fn = boat_to_world(flow_fwd, flow_stbd, heading_deg)
    return fe + boat_east, fn + boat_north


def current_from_stw(stw: float, heading_deg: float, boat_east: float, boat_north: float) -> Vec:
    """Set and drift: water velocity over ground = ground velocity - STW along the heading.

    The log measures the water passing the hull along the keel only; leeway (the hull slipping
    sideways) is taken as zero, so it shows up as a cross-track current (docs/COMPENSATION.md).
    """
    return current_over_ground(-stw, 0.0, heading_deg, boat_east, boat_north)
