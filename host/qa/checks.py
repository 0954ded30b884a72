"""The checks `forcemap check` computes itself on a samples table: time, position against SOG, heading,
wind, depth continuity and the mean current, each a graded ``QaFinding`` (thresholds: docs/QA.md)."""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
from forcemap.host.fuse import redundancy as rd
from forcemap.host.log.qa_records import QaFinding

# QRev's invalid-ensemble rule, on time without samples: one gap over 3 % of the log (caution) or 5 %
# (warning); all gaps over 2 s together over 10 % (caution) or 25 % (warning)
GAP_S = 2.0
ONE_GAP = (0.03, 0.05)
ALL_GAPS = (0.10, 0.25)
POS_WINDOW_S = 30.0
POS_MIN_SOG = 1.0
POS_TOL = 0.2  # a window whose path differs from SOG x time by over 20 % disagrees
POS_MEDIAN = (0.05, 0.15)  # |median ratio - 1|: green, yellow
POS_BAD = (0.05, 0.20)  # share of windows that disagree: green, yellow
DEPTH_JUMP_M = 1.0
DEPTH_SLOPE = 0.5  # a seabed rises or falls less than 1 in 2 along the track
DEPTH_BAD = (0.01, 0.05)
LAKE_CURRENT = 0.1  # m/s
HDG_COG_OK = 5.0
COMPASS_OFFSET = (2.0, 5.0)  # deg between two compasses: green, yellow
EARTH_R = 6_371_000.0
VERDICT_ORDER = ("green", "yellow", "red")
DEPTH_REL = 0.1  # a sounder's scatter grows with depth: 10 % of it is not a jump


def _f(c: Mapping[str, np.ndarray], name: str) -> np.ndarray:
    n = len(c["t"])
    return c.get(name, np.full(n, np.nan))


def _grade(x: float, limits: tuple[float, float]) -> str:
    return "green" if x <= limits[0] else ("yellow" if x <= limits[1] else "red")


def time_finding(c: Mapping[str, np.ndarray]) -> QaFinding:
    t = c["t"][np.isfinite(c["t"])]
    if len(t) < 2:
        return QaFinding("time", "gaps", "red", f"{len(t)} samples: no time span", value=0.0)
    span = float(t[-1] - t[0])
    dt = np.diff(t)
    back = int(np.sum(dt < 0))
    gap_s = max(GAP_S, 2.5 * float(np.median(dt)))  # a log paced every 2 s has no 2 s gaps
    gaps = dt[dt > gap_s]
    longest = float(gaps.max()) if len(gaps) else 0.0
    total = float(gaps.sum())
    v1 = _grade(longest / span, ONE_GAP)
    v2 = _grade(total / span, ALL_GAPS)
    verdict = "red" if back else max(v1, v2, key=VERDICT_ORDER.index)
    msg = (
        f"{len(t)} samples over {span / 60:.1f} min; longest gap {longest:.1f} s "
        f"({100 * longest / span:.1f} %), gaps over {gap_s:.3g} s {100 * total / span:.1f} % in all"
    )
    if back:
        msg += f"; time goes backwards {back} times"
    return QaFinding(
        "time", "gaps", verdict, msg, value=100 * longest / span, unit="%",
        threshold="one gap <= 3 % (5 % red), all gaps <= 10 % (25 % red) of the log (QRev's "
        "invalid-ensemble rule)",
        fix="" if verdict == "green" else "a source stopped: see `forcemap log info` for its outages",
    )  # fmt: skip


def _local_xy(lat: np.ndarray, lon: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    lat0 = float(np.nanmedian(lat))
    x = np.radians(lon - np.nanmedian(lon)) * EARTH_R * math.cos(math.radians(lat0))
    y = np.radians(lat - lat0) * EARTH_R
    return x, y


def position_finding(c: Mapping[str, np.ndarray], source: str) -> QaFinding | None:
    """The displacement between fixes against the integrated ground velocity (SOG along COG), over
    30 s windows under way: a position source and a velocity source that disagree, or one late."""
    t, lat, lon, sog, cog = c["t"], _f(c, "lat"), _f(c, "lon"), _f(c, "sog"), _f(c, "cog")
    ok = np.isfinite(t) & np.isfinite(lat) & np.isfinite(lon) & np.isfinite(sog) & np.isfinite(cog)
    if ok.sum() < 10:
        return None
    t = t[ok]
    x, y = _local_xy(lat[ok], lon[ok])
    ve, vn = sog[ok] * np.sin(np.radians(cog[ok])), sog[ok] * np.cos(np.radians(cog[ok]))
    dt = np.diff(t)
    win = np.floor((t[1:] - t[0]) / POS_WINDOW_S).astype(int)
    good = dt < 5.0
    ie = np.bincount(win, np.where(good, 0.5 * (ve[1:] + ve[:-1]) * dt, 0.0))
    inn = np.bincount(win, np.where(good, 0.5 * (vn[1:] + vn[:-1]) * dt, 0.0))
    de = np.bincount(win, np.where(good, np.diff(x), 0.0))
    dn = np.bincount(win, np.where(good, np.diff(y), 0.0))
    span = np.bincount(win, np.where(good, dt, 0.0))
    run = np.hypot(ie, inn)
    use = (run > POS_MIN_SOG * POS_WINDOW_S * 0.8) & (span > 0.8 * POS_WINDOW_S)
    if use.sum() < 3:
        return QaFinding("position", "vs_sog", "green", "position vs SOG: never under way "
                         f"({POS_MIN_SOG:g} m/s for 30 s)", source)  # fmt: skip
    ratio = np.hypot(de[use], dn[use]) / run[use]
    err = np.hypot(de[use] - ie[use], dn[use] - inn[use]) / run[use]
    med = float(np.median(ratio))
    bad = float(np.mean(err > POS_TOL))
    verdict = max(_grade(abs(med - 1), POS_MEDIAN), _grade(bad, POS_BAD), key=VERDICT_ORDER.index)
    return QaFinding(
        "position", "vs_sog", verdict,
        f"displacement between fixes / SOG along COG x time: median {med:.3f}, {100 * bad:.1f} % "
        f"of {int(use.sum())} windows of 30 s off by over 20 %", source, med, unit="1",
        threshold="median within 5 % (15 %), windows off by > 20 % under 5 % (20 %)",
        evidence="the fixes' displacement against the integrated ground velocity, under way",
        fix="" if verdict == "green" else "a position or velocity source is wrong or late: "
        "compare the sources in `forcemap log info`",
    )  # fmt: skip


def heading_findings(c: Mapping[str, np.ndarray], source: str) -> list[QaFinding]:
    """Whether there is a heading, and course over ground against it when going straight at speed."""
    h = _f(c, "heading")
    n = len(h)
    have = float(np.mean(np.isfinite(h))) if n else 0.0
    needs = np.isfinite(_f(c, "stw")).any() or np.isfinite(_f(c, "app_wind_speed")).any()
    if have == 0.0:
        verdict = "red" if needs else "yellow"
        return [
            QaFinding(
                "heading", "present", verdict,
                "no heading in any sample: no true wind and no current from the speed log "
                "(no heading sentence with a value, or a magnetic one without variation)",
                value=0.0, unit="%", threshold="a heading in the samples where wind or STW is logged",
                fix="a magnetic heading without variation is dropped: give [compass] variation_deg "
                "in boat.toml (or a log with HDT, or HDG/RMC with variation)",
            )
        ]  # fmt: skip
    out = [
        QaFinding("heading", "present", "green" if have > 0.9 else "yellow",
                  f"heading in {100 * have:.1f} % of the samples", source, 100 * have, unit="%",
                  threshold="over 90 % of the samples")
    ]  # fmt: skip
    hc = rd.heading_vs_cog(h, _f(c, "cog"), _f(c, "sog"), _f(c, "yaw_rate"))
    if hc is not None:
        out.append(
            QaFinding(
                "heading", "vs_cog", "green" if abs(hc.offset_deg) <= HDG_COG_OK else "yellow",
                f"course over ground - heading, straight at speed: {hc.offset_deg:+.1f}° "
                f"(spread {hc.spread_deg:.1f}°, leeway and current included)", source,
                hc.offset_deg, hc.spread_deg / math.sqrt(hc.rows), "deg",
                f"|offset| <= {HDG_COG_OK:g}° (a compass offset shows here; evidence, not applied)",
                f"{hc.rows} samples with |rate of turn| <= 1°/s and SOG >= 1.5 m/s",
                "" if abs(hc.offset_deg) <= HDG_COG_OK else "check the compass's deviation and "
                "variation; pin [compass] variation_deg",
            )
        )  # fmt: skip
    return out


def wind_finding(c: Mapping[str, np.ndarray], source: str) -> QaFinding | None:
    app = np.isfinite(_f(c, "app_wind_speed"))
    true = np.isfinite(_f(c, "wind_speed"))
    if not app.any() and not true.any():
        return None
    share = float(np.mean(true[app])) if app.any() else 1.0
    fast = int(np.sum(_f(c, "app_wind_speed")[app] > 60.0))
    verdict = "green" if share > 0.9 and not fast else ("red" if share < 0.5 or fast else "yellow")
    msg = f"true wind in {100 * share:.1f} % of the samples with apparent wind"
    if fast:
        msg += f"; {fast} apparent winds over 60 m/s"
    return QaFinding(
        "wind", "true_wind", verdict, msg, source, 100 * share, unit="%",
        threshold="true wind in over 90 % (50 %) of the apparent-wind samples; none over 60 m/s",
        fix="" if verdict == "green" else "true wind needs a heading and a ground velocity",
    )  # fmt: skip


def depth_finding(c: Mapping[str, np.ndarray], source: str) -> QaFinding | None:
    """Consecutive soundings against the distance travelled between them."""
    d = _f(c, "depth")
    ok = np.isfinite(d) & np.isfinite(_f(c, "lat")) & np.isfinite(_f(c, "lon"))
    if ok.sum() < 10:
        return None
    x, y = _local_xy(c["lat"][ok], c["lon"][ok])
    dd = np.abs(np.diff(d[ok]))
    ds = np.hypot(np.diff(x), np.diff(y))
    moved = dd > 0
    dmax = np.maximum(d[ok][1:], d[ok][:-1])
    jump = dd > DEPTH_JUMP_M + DEPTH_REL * dmax + DEPTH_SLOPE * ds
    share = float(jump.sum() / max(moved.sum(), 1))
    verdict = _grade(share, DEPTH_BAD)
    return QaFinding(
        "depth", "continuity", verdict,
        f"{int(jump.sum())} of {int(moved.sum())} depth changes ({100 * share:.1f} %) steeper than a "
        "seabed (1 m + 10 % of the depth + 1 in 2 of the distance)", source, 100 * share, unit="%",
        threshold="jumps under 1 % (5 %) of the depth changes",
        fix="" if verdict == "green" else "false echoes or the bottom lost: spikes are left out "
        "of the depth fit (docs/WORKBENCH.md)",
    )  # fmt: skip


def current_finding(c: Mapping[str, np.ndarray], source: str) -> QaFinding | None:
    """The mean current from the speed log: on a lake, what is not water is instrument error."""
    ce, cn, stw = _f(c, "current_east"), _f(c, "current_north"), _f(c, "stw")
    ok = np.isfinite(ce) & np.isfinite(cn) & np.isfinite(stw)
    if ok.sum() < 30:
        return None
    me, mn = float(np.mean(ce[ok])), float(np.mean(cn[ok]))
    speed = math.hypot(me, mn)
    to = math.degrees(math.atan2(me, mn)) % 360
    small = speed < LAKE_CURRENT
    return QaFinding(
        "speed_through_water", "current_mean", "green" if small else "yellow",
        f"mean current from the speed log {speed:.3f} m/s toward {to:.0f}° over {int(ok.sum())} "
        "samples", source, speed, unit="m/s",
        threshold=f"on a lake (still water) under {LAKE_CURRENT:g} m/s",
        evidence=f"east {me:+.3f}, north {mn:+.3f} m/s",
        fix="" if small else "if the water is still, this is leeway (the log reads along the "
        "keel), a compass offset (see heading vs COG) or an uncalibrated speed log",
        extra={"east": repr(me), "north": repr(mn)},
    )  # fmt: skip


def compass_offsets(sources: Mapping[str, Mapping]) -> list[QaFinding]:
    """Every other compass against the one used: the median of their difference is its offset."""
    h = sources.get("heading")
    if not h:
        return []
    out = []
    for name, row in h.get("sources", {}).items():
        med = row.get("diff_median")
        if name == h.get("chosen") or med is None:
            continue
        p95 = row.get("diff_p95")
        verdict = _grade(abs(med), COMPASS_OFFSET)
        out.append(
            QaFinding(
                "heading", "offset", verdict,
                f"{name} reads {med:+.1f}° from {h['chosen']} (median; 95 % within {p95}°)", name,
                float(med), unit="deg",
                threshold=f"|median| <= {COMPASS_OFFSET[0]:g}° ({COMPASS_OFFSET[1]:g}°)",
                evidence="the two compasses at the same instants over the whole log",
                fix="" if verdict == "green" else "swing the compass (deviation) or check its "
                "variation; the heading used is the chosen one's",
            )
        )  # fmt: skip
    return out
