"""Each sounding's total vertical uncertainty (TVU) from its sources, and the IHO S-44 order it meets.

IHO S-44 (6th ed., 2020) states the maximum allowable TVU of a sounding at the 95 % confidence level as
``sqrt(a^2 + (b d)^2)`` at depth ``d``, per order (ORDERS). A sounding's TVU is propagated from what adds
to it (each term a 1-sd error in metres, combined in quadrature and scaled by 1.96 to 95 %):

- the sounder: its stated accuracy, ``accuracy_m + accuracy_share x depth`` (boat.toml ``[sounder]``;
  SOUNDER_DEFAULT where not given: a small boat's single-beam sounder), and its resolution (a reading
  quantised to ``q`` has an sd of ``q / sqrt 12``);
- the attitude: what the transducer's tilt leaves after its correction (forcemap.host.fuse.attitude);
- the position: a horizontal error ``sigma_h`` moves a sounding along a bed that slopes by ``k``, so it
  reads ``sigma_h x k`` off (``k`` the bed's slope along the track, from the soundings themselves);
- the water level: the uncertainty of the datum the sounding is reduced to (a gauge, or the level
  estimated from the survey's crossings), zero where the depth stays below the surface of its moment.

Heave, sound speed and the draft's change with load are not measured by the boats forcemap serves; they
are not in the sum (docs/SOUNDINGS.md says what that leaves out).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from forcemap.host.fuse import attitude
from forcemap.host.fuse.attitude import ATTITUDE_SD_DEG
from forcemap.host.log.qa_records import QaFinding

Z95 = 1.96
# S-44 6th ed., table 1: (a m, b) of the maximum allowable TVU at 95 %, strictest first
ORDERS: dict[str, tuple[float, float]] = {
    "exclusive": (0.15, 0.0075),
    "special": (0.25, 0.0075),
    "1a/1b": (0.5, 0.013),
    "2": (1.0, 0.023),
}
ORDER_CODES = {name: i + 1 for i, name in enumerate(ORDERS)}  # 0: none met
SOUNDER_DEFAULT = (0.1, 0.005)  # m + share of depth, 1 sd: a small boat's single-beam sounder
POSITION_SD_M = 2.0  # an autonomous GNSS fix, horizontal 1 sd, where the log states none
SLOPE_WINDOW = 9  # soundings along the track over which the bed's slope is taken (their median)


@dataclass(frozen=True)
class SounderSpec:
    """A sounder's stated accuracy (1 sd): ``accuracy_m + accuracy_share x depth``."""

    accuracy_m: float = SOUNDER_DEFAULT[0]
    accuracy_share: float = SOUNDER_DEFAULT[1]
    stated: bool = False  # given in the boat file, or the default

    def sd(self, depth: np.ndarray) -> np.ndarray:
        return self.accuracy_m + self.accuracy_share * np.abs(np.asarray(depth, float))


def position_sd(recorded: Sequence[QaFinding], source: str) -> tuple[float, str]:
    """The horizontal 1-sd error of the positions (m): the noise the import measured of the source that
    fed them (its ``qa.position.latency`` finding), else POSITION_SD_M; and where it came from."""
    best = None
    for f in recorded:
        if f.category == "position" and f.extra.get("quantity") == "position":
            try:
                noise = float(f.extra.get("noise", "nan"))
            except ValueError:
                continue
            if math.isfinite(noise) and (best is None or f.source == source):
                best = (noise, f"the navigation's measured noise of {f.source}")
    if best is None:
        return POSITION_SD_M, f"{POSITION_SD_M:g} m, an autonomous GNSS fix's"
    return max(best[0], 0.1), best[1]


def spec_of(calibration: Mapping[str, str] | None) -> SounderSpec:
    """The sounder's stated accuracy from a log's calibration record (boat.toml [sounder]), else the
    default."""
    cal = calibration or {}
    try:
        a, b = cal.get("sounder_accuracy_m"), cal.get("sounder_accuracy_share")
        a = None if a in (None, "None") else float(a)
        b = None if b in (None, "None") else float(b)
    except ValueError:
        a = b = None
    if a is None and b is None:
        return SounderSpec()
    return SounderSpec(
        a if a is not None else SOUNDER_DEFAULT[0],
        b if b is not None else SOUNDER_DEFAULT[1],
        True,
    )


def allowed(depth: np.ndarray, order: str) -> np.ndarray:
    """S-44's maximum allowable TVU (m, 95 %) of ``order`` at ``depth``."""
    a, b = ORDERS[order]
    return np.sqrt(a**2 + (b * np.asarray(depth, float)) ** 2)


def order_met(tvu: np.ndarray, depth: np.ndarray) -> np.ndarray:
    """Per sounding, the strictest S-44 order its TVU (95 %) meets: ORDER_CODES, 0 for none, -1 for no
    sounding (NaN)."""
    tvu, depth = np.asarray(tvu, float), np.asarray(depth, float)
    out = np.zeros(len(tvu), int)
    for name in reversed(list(ORDERS)):  # the strictest met wins
        out = np.where(tvu <= allowed(depth, name), ORDER_CODES[name], out)
    return np.where(np.isfinite(tvu) & np.isfinite(depth), out, -1)


def meets(tvu: np.ndarray, depth: np.ndarray, order: str) -> np.ndarray:
    """Per sounding, whether its TVU meets ``order`` (or a stricter one)."""
    code = order_met(tvu, depth)
    return (code >= 1) & (code <= ORDER_CODES[order])


def resolution_sd(depth: np.ndarray) -> float:
    """The quantisation's sd: the smallest change between successive soundings over sqrt 12."""
    d = np.abs(np.diff(depth[np.isfinite(depth)]))
    d = d[d > 1e-9]
    return float(np.min(d)) / np.sqrt(12.0) if len(d) else 0.0


def along_track_slope(depth: np.ndarray, step_m: np.ndarray) -> np.ndarray:
    """The bed's slope (m/m) along the track at each sounding: the median over SLOPE_WINDOW soundings
    of the change in depth per metre travelled (a lower bound of the full slope: across the track it
    is not seen)."""
    d = np.asarray(depth, float)
    ok = np.flatnonzero(np.isfinite(d))
    out = np.zeros(len(d))
    if len(ok) < 3:
        return out
    travelled = np.cumsum(np.nan_to_num(step_m))[ok]
    dd, ds = np.abs(np.diff(d[ok])), np.diff(travelled)
    slope = np.where(ds > 0.5, dd / np.maximum(ds, 0.5), np.nan)
    slope = np.r_[slope[0], slope]
    half = SLOPE_WINDOW // 2
    padded = np.r_[np.full(half, np.nan), slope, np.full(half, np.nan)]
    view = np.lib.stride_tricks.sliding_window_view(padded, SLOPE_WINDOW)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a window of no slope gives NaN: none known
        med = np.nanmedian(view, axis=1)
    out[ok] = np.nan_to_num(med)
    return np.clip(out, 0.0, 1.0)


@dataclass
class Tvu:
    """Each sounding's TVU (95 %) and its terms (1 sd), metres."""

    sounder: np.ndarray
    attitude: np.ndarray
    position: np.ndarray
    level: np.ndarray

    @property
    def sd(self) -> np.ndarray:
        return np.sqrt(self.sounder**2 + self.attitude**2 + self.position**2 + self.level**2)

    @property
    def tvu(self) -> np.ndarray:
        return Z95 * self.sd

    def largest(self) -> np.ndarray:
        """Per sounding, the name of its largest term."""
        names = np.array(["sounder", "attitude", "position", "level"])
        stack = np.vstack([self.sounder, self.attitude, self.position, self.level])
        return names[np.argmax(stack, axis=0)]


def sounding_tvu(
    depth: np.ndarray,
    spec: SounderSpec,
    attitude_sd: np.ndarray | float = 0.0,
    slope: np.ndarray | float = 0.0,
    position_sd: float = POSITION_SD_M,
    level_sd: np.ndarray | float = 0.0,
) -> Tvu:
    """The TVU of each sounding from its sources (module docstring)."""
    depth = np.asarray(depth, float)
    n = len(depth)
    sounder = np.hypot(spec.sd(depth), resolution_sd(depth))
    return Tvu(
        np.where(np.isfinite(depth), sounder, np.nan),
        np.broadcast_to(np.asarray(attitude_sd, float), (n,)).copy(),
        position_sd * np.broadcast_to(np.asarray(slope, float), (n,)),
        np.broadcast_to(np.asarray(level_sd, float), (n,)).copy(),
    )


def attitude_sd(
    depth: np.ndarray,
    depth_raw: np.ndarray | None,
    roll: np.ndarray | None,
    pitch: np.ndarray | None,
    offset_m: float = 0.0,
    attitude_sd_deg: float = ATTITUDE_SD_DEG,
) -> np.ndarray:
    """The attitude's term (1 sd, m) of each sounding of a table: where it was corrected (``depth_raw``
    kept) the correction's sensitivity to the attitude's error, from the slant angle the correction
    used, ``cos phi = depth / depth_raw`` below the transducer; where the hull's attitude is known but
    no correction was made, the whole slant (attitude.correction_sd); without attitude, none."""
    depth = np.asarray(depth, float)
    out = np.zeros(len(depth))
    if roll is not None:
        out = np.nan_to_num(attitude.correction_sd(depth, offset_m, roll, pitch, None))
    if depth_raw is not None:
        rng = np.asarray(depth_raw, float) - offset_m
        with np.errstate(all="ignore"):
            cosphi = np.clip((depth - offset_m) / rng, 0.0, 1.0)
        sd = rng * np.sqrt(1.0 - cosphi**2) * np.radians(attitude_sd_deg)
        out = np.where(np.isfinite(sd), sd, out)
    return out


def table_tvu(
    depth: np.ndarray,
    xy: np.ndarray,
    spec: SounderSpec,
    depth_raw: np.ndarray | None = None,
    roll: np.ndarray | None = None,
    pitch: np.ndarray | None = None,
    position_sd: float = POSITION_SD_M,
    level_sd: np.ndarray | float = 0.0,
    offset_m: float = 0.0,
) -> Tvu:
    """Each sounding's TVU of a samples table (rows in time order, ``xy`` metres): the bed's slope from
    the soundings along the track, the attitude's term from the table's own columns."""
    step = np.r_[0.0, np.hypot(*np.diff(np.asarray(xy, float), axis=0).T)]
    slope = along_track_slope(depth, step)
    att = attitude_sd(depth, depth_raw, roll, pitch, offset_m)
    return sounding_tvu(depth, spec, att, slope, position_sd, level_sd)
