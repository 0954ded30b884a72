"""A depth survey graded against IHO S-44: the share of soundings whose TVU meets Order 1a/1b and Special,
and where they do not (the time, the depth and the term that costs most), as one ``qa.depth.s44`` finding.

Each sounding's TVU comes from forcemap.host.fuse.tvu (sounder, attitude, position x slope, water level).
Soundings in a stretch where the bottom was lost have no TVU (they are no measurement of the bed): they
are left out of the shares and counted. S-44 asks that 95 % of the soundings meet an order's TVU: that
is the green line for Order 1a/1b.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from forcemap.host.fuse import tvu
from forcemap.host.log.qa_records import QaFinding

MEET_SHARE = 0.95  # S-44: an order is met where 95 % of the soundings meet its TVU
MIN_RUN = 10  # soundings in a row that miss Order 1b: a stretch named
TOP_STRETCHES = 3


def _stretches(miss: np.ndarray, t: np.ndarray, largest: np.ndarray) -> list[str]:
    edges = np.flatnonzero(np.diff(np.r_[0, miss.astype(int), 0]))
    runs = [
        (a, b) for a, b in zip(edges[::2], edges[1::2] - 1, strict=True) if b - a + 1 >= MIN_RUN
    ]
    runs.sort(key=lambda r: r[0] - r[1])
    out = []
    for a, b in runs[:TOP_STRETCHES]:
        names, counts = np.unique(largest[a : b + 1], return_counts=True)
        out.append(
            f"{(t[a] - t[0]) / 60:.1f}-{(t[b] - t[0]) / 60:.1f} min ({names[np.argmax(counts)]})"
        )
    return out


def s44_finding(
    c: Mapping[str, np.ndarray],
    xy: np.ndarray,
    source: str,
    recorded: Sequence[QaFinding] = (),
    calibration: Mapping[str, str] | None = None,
) -> QaFinding | None:
    """The S-44 grade of a table's soundings (``c``: its columns, ``xy`` its positions in metres)."""
    depth = np.asarray(c["depth"], float)
    n = len(depth)
    have = np.isfinite(depth)
    if have.sum() < 10:
        return None
    lost = np.nan_to_num(c.get("bottom_lost", np.zeros(n))) > 0
    sd_pos, pos_from = tvu.position_sd(recorded, source)
    spec = tvu.spec_of(calibration)
    offset = float((calibration or {}).get("depth_offset_m", 0.0) or 0.0)
    t_ = tvu.table_tvu(
        depth, xy, spec, c.get("depth_raw"), c.get("roll"), c.get("pitch"), sd_pos, 0.0, offset
    )
    u = t_.tvu
    use = have & ~lost & np.isfinite(u)
    if not use.any():
        return None
    code = tvu.order_met(u, depth)
    order1 = (code >= 1) & (code <= tvu.ORDER_CODES["1a/1b"])
    special = (code >= 1) & (code <= tvu.ORDER_CODES["special"])
    s1, ss = float(order1[use].mean()), float(special[use].mean())
    largest = t_.largest()
    miss = use & ~order1
    where = _stretches(miss[use], c["t"][use], largest[use])
    deep = ""
    if miss.any():
        deep = f"; the misses lie at {np.nanmin(depth[miss]):.1f}-{np.nanmax(depth[miss]):.1f} m"
    names, counts = np.unique(largest[use], return_counts=True)
    verdict = "green" if s1 >= MEET_SHARE else ("yellow" if s1 >= 0.5 else "red")
    msg = (
        f"IHO S-44: {100 * s1:.1f} % of {int(use.sum())} soundings meet Order 1a/1b, "
        f"{100 * ss:.1f} % Special (TVU {np.nanpercentile(u[use], 5):.2f}-"
        f"{np.nanpercentile(u[use], 95):.2f} m at 95 %, largest term: {names[np.argmax(counts)]})"
    )
    if where:
        msg += "; not Order 1a/1b: " + ", ".join(where) + " into the survey"
    msg += deep
    if lost.any():
        msg += f"; {int((have & lost).sum())} soundings where the bottom was lost left out"
    return QaFinding(
        "depth", "s44", verdict, msg, source, 100 * s1, unit="%",
        threshold="95 % of the soundings within Order 1a/1b's TVU, sqrt(0.5^2 + (0.013 d)^2) m "
        "(S-44 6th ed.); Special: sqrt(0.25^2 + (0.0075 d)^2)",
        evidence=f"TVU = 1.96 x sqrt(sounder^2 + attitude^2 + (position sd x slope)^2 + level^2); "
        f"sounder {spec.accuracy_m:g} m + {100 * spec.accuracy_share:g} % of depth "
        f"({'boat.toml' if spec.stated else 'default'}), position sd {sd_pos:.2f} m ({pos_from}), "
        "slope along the track, no water level (depth below the surface of its moment)",
        fix="" if verdict == "green" else "the largest term says what to improve: a sounder with a "
        "stated accuracy in boat.toml [sounder], the hull's attitude (roll, pitch), a better fix",
        extra={"special_share": repr(100 * ss), "order_1b_share": repr(100 * s1),
               "soundings": str(int(use.sum()))},
    )  # fmt: skip
