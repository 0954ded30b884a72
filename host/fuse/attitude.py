"""A single-beam sounding on a tilted hull: the slant the beam hides, the depth corrected, the error left.

A single-beam sounder's first return comes from the nearest point of the bed inside its cone (half-angle
``a``, half the beam angle). The hull's roll and pitch tilt the transducer's axis by ``theta`` from the
vertical, ``cos theta = cos roll cos pitch``. Over a flat bed at depth ``D`` below the transducer:

- within half the beam of vertical (``theta <= a``) the vertical ray is inside the cone: it is the
  nearest, and the sounder reads ``D`` (the slant is hidden);
- beyond it (``theta > a``) the nearest ray is the cone's edge, ``theta - a`` from the vertical: the
  sounder reads ``R = D / cos(theta - a)``, long, from a point ``D tan(theta - a)`` to the side the
  transducer leans.

So ``D = R cos(max(theta - a, 0))``. Over a bed that slopes by ``s`` the nearest point lies along the
bed's normal: with ``g`` the angle between the beam's axis and that normal, ``R = D cos s / cos(max(g - a,
0))``; upright on the slope (``g = s``) a beam wider than the slope reads short by ``cos s``. The correction
here assumes a flat bed (the slope is not known when a sounding is made); what a slope leaves is part of
the sounding's uncertainty (forcemap.host.fuse.tvu) and of docs/SOUNDINGS.md's worked example.

Conventions (docs/CONVENTIONS.md): roll in degrees, positive starboard down; pitch in degrees, positive
bow up; the beam angle is the full angle between the cone's -3 dB edges.
"""

from __future__ import annotations

import numpy as np

ATTITUDE_SD_DEG = 1.0  # a small boat's attitude sensor, 1 sd (an XDR heel sensor reads to 0.1 deg)


def tilt_deg(roll: np.ndarray, pitch: np.ndarray) -> np.ndarray:
    """The transducer axis's angle from the vertical (deg): ``cos theta = cos roll cos pitch``; a
    missing pitch (a heel sensor alone) counts as level."""
    r = np.radians(np.nan_to_num(np.asarray(roll, float)))
    p = np.radians(np.nan_to_num(np.asarray(pitch, float)))
    return np.degrees(np.arccos(np.clip(np.cos(r) * np.cos(p), -1.0, 1.0)))


def slant_angle(tilt: np.ndarray, beam_deg: float) -> np.ndarray:
    """The nearest ray's angle from the vertical over a flat bed (deg): ``max(tilt - beam / 2, 0)``."""
    return np.maximum(np.asarray(tilt, float) - 0.5 * beam_deg, 0.0)


def corrected(
    reading: np.ndarray, offset_m: float, roll: np.ndarray, pitch: np.ndarray, beam_deg: float
) -> np.ndarray:
    """Soundings below the surface corrected for the transducer's tilt over a flat bed: the range
    below the transducer (``reading - offset_m``) times ``cos(max(tilt - beam / 2, 0))``, plus the
    offset again. NaN roll leaves a sounding as read."""
    reading = np.asarray(reading, float)
    phi = np.radians(slant_angle(tilt_deg(roll, pitch), beam_deg))
    out = offset_m + (reading - offset_m) * np.cos(phi)
    return np.where(np.isfinite(np.asarray(roll, float)), out, reading)


def reading_over_slope(
    depth: float, tilt: float, slope: float, beam_deg: float, toward: float = 0.0
) -> float:
    """What a sounder reads (range along its nearest ray) at vertical depth ``depth`` below the
    transducer over a bed sloping by ``slope`` deg, its axis tilted by ``tilt`` deg in a direction
    ``toward`` deg from the bed's down-slope direction (0: leaning down the slope)."""
    s, t, w = np.radians(slope), np.radians(tilt), np.radians(toward)
    # the bed's upward normal leans up-slope by s; the axis leans by t at w from down-slope
    normal = np.array([-np.sin(s), 0.0, np.cos(s)])
    axis = np.array([np.sin(t) * np.cos(w), np.sin(t) * np.sin(w), np.cos(t)])
    g = np.arccos(np.clip(float(normal @ axis), -1.0, 1.0))
    return float(depth * np.cos(s) / np.cos(max(g - np.radians(0.5 * beam_deg), 0.0)))


def correction_sd(
    reading: np.ndarray,
    offset_m: float,
    roll: np.ndarray,
    pitch: np.ndarray,
    beam_deg: float | None,
    attitude_sd: float = ATTITUDE_SD_DEG,
    beam_sd: float = 0.0,
) -> np.ndarray:
    """The 1-sd uncertainty (m) the tilt leaves in a sounding: the correction's sensitivity to the
    attitude's and the beam angle's errors, ``R sin(tilt - a) x their sd``; with no beam angle (no
    correction made) the whole slant, ``R (1 - cos tilt)``, a bias counted as an uncertainty. Zero
    where there is no attitude (nothing known: docs/SOUNDINGS.md)."""
    rng = np.maximum(np.asarray(reading, float) - offset_m, 0.0)
    tilt = tilt_deg(roll, pitch)
    have = np.isfinite(np.asarray(roll, float))
    if beam_deg is None:
        out = rng * (1.0 - np.cos(np.radians(tilt)))
    else:
        phi = np.radians(slant_angle(tilt, beam_deg))
        sd = np.radians(np.hypot(attitude_sd, 0.5 * beam_sd))
        out = rng * np.sin(phi) * sd
    return np.where(have, out, 0.0)
