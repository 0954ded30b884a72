"""Sounder against sounder: where a log has two depth sources, where they disagree and which one the
evidence trusts.

Two sources of depth (two talkers, DPT and DBT of different transducers, an autopilot's rangefinder and
an NMEA sounder) measure one bed. Their difference at the same instants (the other one's nearest reading
within MATCH_S) is split into a constant offset (its median: a transducer depth one sentence carries and
the other does not) and what is left. A reading disagrees where what is left exceeds Z times the two
sources' own scatter (each one's ping-to-ping noise along its seabed path, robust); runs of at least
MIN_RUN disagreeing readings are the stretches named.

Which one the evidence trusts is judged on each source alone, never on the other:

- continuity: the share of its soundings on one seabed (not in a stretch where the bottom was lost,
  not off the seabed's continuous path: forcemap.host.fuse.bottom_lost);
- scatter: its ping-to-ping noise on that path;
- agreement at crossings: where the track revisits itself, the median difference between its own
  soundings of one spot (forcemap.host.fuse.crossings).

The source with the larger share on a seabed is trusted; where the shares are within SHARE_TIE, the
smaller disagreement at crossings, then the smaller scatter; where nothing tells them apart, the one
the samples use.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from forcemap.host.fuse.bottom_lost import depth_lost
from forcemap.host.fuse.crossings import crossing_pairs

MATCH_S = 2.0  # a reading of the other source this close in time is "the same instant"
Z = 4.0  # disagreement beyond the sources' own scatter
MIN_RUN = 5  # readings in a row that disagree: a stretch
MIN_READINGS = 30
SHARE_TIE = 0.02
CROSS_RADIUS_M = 3.0
CROSS_DT_S = 60.0


@dataclass
class SourceEvidence:
    """What one depth source shows on its own."""

    name: str
    readings: int
    on_seabed: float  # share of its soundings on one continuous seabed
    scatter_m: float  # ping-to-ping noise on that seabed (1 sd)
    crossing_m: float  # median |difference| of its own soundings of one spot (NaN: no crossings)
    crossings: int

    def text(self) -> str:
        cross = (
            f", crossings agree within {self.crossing_m:.2f} m (median of {self.crossings})"
            if self.crossings
            else ""
        )
        return (
            f"{self.name}: {self.on_seabed:.0%} of {self.readings} soundings on one seabed, "
            f"scatter {self.scatter_m:.2f} m{cross}"
        )


@dataclass
class Comparison:
    """One source against the one the samples use."""

    chosen: SourceEvidence
    other: SourceEvidence
    offset_m: float  # other - chosen, median
    matched: int  # readings of the other with one of the chosen's within MATCH_S
    disagree_share: float
    stretches: list[tuple[float, float]] = field(default_factory=list)  # UNIX s
    trusted: str = ""
    why: str = ""


def _evidence(name: str, t: np.ndarray, d: np.ndarray, xy: np.ndarray | None) -> SourceEvidence:
    found = depth_lost(d, t - t[0], xy)
    on = found.on_path & ~found.lost
    path = found.first[on]
    steps = np.diff(d[path])
    scatter = float(1.4826 * np.median(np.abs(steps - np.median(steps))) / np.sqrt(2.0))
    crossing, n = np.nan, 0
    if xy is not None:
        pairs = crossing_pairs(xy, t, CROSS_RADIUS_M, CROSS_DT_S, max_pairs=5000)
        keep = found.rows[pairs].sum(axis=1) == 0 if len(pairs) else np.zeros(0, bool)
        pairs = pairs[keep]
        if len(pairs):
            crossing, n = float(np.median(np.abs(d[pairs[:, 0]] - d[pairs[:, 1]]))), len(pairs)
    return SourceEvidence(name, len(d), float(np.mean(on)), scatter, crossing, n)


def _nearest(t_ref: np.ndarray, t: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``v`` at the reading of ``t`` nearest each ``t_ref``, NaN farther than MATCH_S."""
    j = np.clip(np.searchsorted(t, t_ref), 1, len(t) - 1)
    j = np.where(np.abs(t[j - 1] - t_ref) <= np.abs(t[j] - t_ref), j - 1, j)
    return np.where(np.abs(t[j] - t_ref) <= MATCH_S, v[j], np.nan)


def _runs(mask: np.ndarray, t: np.ndarray) -> list[tuple[float, float]]:
    """Runs of at least MIN_RUN disagreeing readings, those fewer than MIN_RUN apart joined (a
    scattered reading agrees now and then by chance)."""
    edges = np.flatnonzero(np.diff(np.r_[0, mask.astype(int), 0]))
    runs: list[list[int]] = []
    for a, b in zip(edges[::2], edges[1::2] - 1, strict=True):
        if runs and a - runs[-1][1] <= MIN_RUN:
            runs[-1][1] = b
        else:
            runs.append([a, b])
    return [(float(t[a]), float(t[b])) for a, b in runs if b - a + 1 >= MIN_RUN]


def _trust(a: SourceEvidence, b: SourceEvidence) -> tuple[str, str]:
    if abs(a.on_seabed - b.on_seabed) > SHARE_TIE:
        best, other = (a, b) if a.on_seabed > b.on_seabed else (b, a)
        return (
            best.name,
            f"more of its soundings on one seabed ({best.on_seabed:.0%} against {other.on_seabed:.0%})",
        )
    if a.crossings and b.crossings and abs(a.crossing_m - b.crossing_m) > 0.01:
        best, other = (a, b) if a.crossing_m < b.crossing_m else (b, a)
        return best.name, (
            f"its crossings agree better ({best.crossing_m:.2f} m against {other.crossing_m:.2f} m)"
        )
    if abs(a.scatter_m - b.scatter_m) > 0.01:
        best, other = (a, b) if a.scatter_m < b.scatter_m else (b, a)
        return best.name, f"less scatter ({best.scatter_m:.2f} m against {other.scatter_m:.2f} m)"
    return a.name, "nothing tells them apart (as continuous, as scattered): the one used is kept"


def compare(
    readings: dict[str, tuple[np.ndarray, np.ndarray]],
    chosen: str,
    position=None,
) -> list[Comparison]:
    """Every other depth source against ``chosen``: ``readings`` maps a source to (UNIX s, depth m),
    ``position(t)`` gives local (x, y) m at times (None: no crossings, no steepness test)."""
    if chosen not in readings or len(readings) < 2:
        return []
    out = []
    sorted_ = {k: _sorted(*v) for k, v in readings.items()}
    # a handful of readings (a sentence spliced under another talker) is not a sounder
    sorted_ = {k: v for k, v in sorted_.items() if len(v[0]) >= MIN_READINGS or k == chosen}
    if len(sorted_) < 2 or len(sorted_[chosen][0]) < MIN_READINGS:
        return []
    ev = {k: _evidence(k, t, d, position(t) if position else None) for k, (t, d) in sorted_.items()}
    tc, dc = sorted_[chosen]
    for name, (t, d) in sorted_.items():
        if name == chosen or len(t) < 2:
            continue
        ref = _nearest(t, tc, dc)
        diff = d - ref
        ok = np.isfinite(diff)
        if ok.sum() < MIN_RUN:
            continue
        offset = float(np.median(diff[ok]))
        noise = np.hypot(ev[name].scatter_m, ev[chosen].scatter_m)
        tol = Z * max(noise, 0.05) + 0.01 * np.abs(ref)
        bad = ok & (np.abs(diff - offset) > tol)
        trusted, why = _trust(ev[chosen], ev[name])
        out.append(
            Comparison(
                ev[chosen], ev[name], offset, int(ok.sum()), float(bad[ok].mean()),
                _runs(bad, t), trusted, why,
            )
        )  # fmt: skip
    return out


def _sorted(t: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    t, d = np.asarray(t, float), np.asarray(d, float)
    ok = np.isfinite(t) & np.isfinite(d)
    order = np.argsort(t[ok], kind="stable")
    return t[ok][order], d[ok][order]
