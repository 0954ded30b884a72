"""A log's soundings checked at import: the bottom lost, sounder against sounder, and the transducer's tilt.

Each check reads the first pass's samples (and every depth source's readings) and gives a ``qa.depth.*``
finding (forcemap.host.log.qa_records) with its number and evidence; what is safe is applied in the
second pass through the calibration (forcemap.host.convert.self_calibration):

- ``bottom_lost``: the stretches where the soundings stop agreeing with any seabed
  (forcemap.host.fuse.bottom_lost), their rows marked ``bottom_lost`` (every row kept) and left out of
  depth maps;
- ``sounders``: every other depth source against the one the samples use (forcemap.host.fuse.sounders):
  their offset, where they disagree, which one the evidence trusts;
- ``tilt``: where the log has the hull's roll and pitch, the beam angle that makes the soundings agree
  best where the track crosses itself (when boat.toml does not give it), applied when it is surer than
  no correction (docs/SOUNDINGS.md).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
from forcemap.host.fuse import attitude, sounders
from forcemap.host.fuse.bottom_lost import depth_lost
from forcemap.host.fuse.calibration import Calibration
from forcemap.host.fuse.crossings import MAX_PAIRS, crossing_pairs
from forcemap.host.log.qa_records import QaFinding
from forcemap.host.vessel.geodesy import LocalFrame

THRESH_LOST = (
    "no stretch where the soundings scatter or climb and fall more than a seabed can: green; lost "
    "for up to 25 % of the soundings: yellow; more: red (QRev's invalid-ensemble share)"
)
LOST_RED = 0.25
BEAMS = np.arange(0.0, 61.0, 1.0)  # deg: the beam angles tried
CROSS_RADIUS_M = 3.0
CROSS_DT_S = 60.0
JACKKNIFE_BLOCKS = 10
MIN_CROSSINGS = 30


def arrays(rows: list[Mapping[str, Any]], names: tuple[str, ...]) -> dict[str, np.ndarray]:
    """Columns of float arrays (NaN where empty) from row dicts."""

    def num(v: Any) -> float:
        return float(v) if isinstance(v, int | float) and not isinstance(v, bool) else math.nan

    return {c: np.array([num(r.get(c)) for r in rows], float) for c in names}


def raw_depth(c: Mapping[str, np.ndarray]) -> np.ndarray:
    """The soundings as read: ``depth_raw`` where a tilt correction was made, else ``depth``."""
    raw = c.get("depth_raw")
    d = c["depth"]
    return d if raw is None else np.where(np.isfinite(raw), raw, d)


def local_xy(lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
    """Positions in metres east/north of the track's median (NaN where there is none)."""
    ok = np.isfinite(lat) & np.isfinite(lon)
    if not ok.any():
        return np.full((len(lat), 2), np.nan)
    x, y = LocalFrame(float(np.median(lat[ok])), float(np.median(lon[ok]))).to_local(lat, lon)
    return np.column_stack([x, y])


def lost_finding(
    c: Mapping[str, np.ndarray], source: str
) -> tuple[QaFinding | None, tuple[tuple[float, float], ...]]:
    """The bottom lost: a finding and its stretches in UNIX seconds (for the rows to mark)."""
    d, t = raw_depth(c), c["t"]
    have = np.isfinite(d)
    if have.sum() < 10:
        return None, ()
    found = depth_lost(d, t - t[0], local_xy(c["lat"], c["lon"]))
    n_lost, n = int((found.rows & have).sum()), int(have.sum())
    share = n_lost / n
    if not found.stretches:
        return QaFinding(
            "depth", "bottom_lost", "green",
            f"the sounder held the bottom: no stretch of {n} soundings scatters or climbs and falls "
            "more than a seabed can", source, 0.0, unit="%", threshold=THRESH_LOST,
        ), ()  # fmt: skip
    spans = [found.row_span(s) for s in found.stretches]
    unix = tuple((float(t[a]), float(t[b])) for a, b in spans)
    where = "; ".join(s.text() for s in found.stretches)
    spread = "; ".join(
        f"{np.nanmin(d[a : b + 1]):.1f}-{np.nanmax(d[a : b + 1]):.1f} m" for a, b in spans
    )
    verdict = "red" if share > LOST_RED else "yellow"
    return QaFinding(
        "depth", "bottom_lost", verdict,
        f"the bottom lost in {len(spans)} stretch(es): {where} into the log; {n_lost} of {n} "
        f"soundings ({100 * share:.1f} %)", source, 100 * share, unit="%", threshold=THRESH_LOST,
        evidence=f"the soundings in each stretch read {spread}; its seabed path jumps from ping to "
        "ping or climbs and falls faster than 1 in 2 against the distance travelled",
        fix="marked: the rows stay, with bottom_lost = 1, and are left out of depth maps",
        applied=True,
        extra={"stretches": ";".join(f"{a!r}-{b!r}" for a, b in unix),
               "soundings": str(n_lost)},
    ), unix  # fmt: skip


def _pair_error(c1: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    return np.abs(c1[pairs[:, 0]] - c1[pairs[:, 1]])


def beam_profile(
    raw: np.ndarray, roll: np.ndarray, pitch: np.ndarray, offset: float, pairs: np.ndarray
) -> np.ndarray:
    """The crossings' mean |difference| (m) of the soundings corrected with each of BEAMS; the last
    entry is without correction."""
    out = [
        float(np.mean(_pair_error(attitude.corrected(raw, offset, roll, pitch, b), pairs)))
        for b in BEAMS
    ]
    return np.array(out + [float(np.mean(_pair_error(raw, pairs)))])


def _jackknife(values: Callable[[np.ndarray], float], blocks: np.ndarray) -> float:
    """The delete-a-block jackknife's sd of a statistic of the pairs."""
    est = np.array([values(blocks != k) for k in np.unique(blocks)])
    k = len(est)
    return float(np.sqrt((k - 1) / k * np.sum((est - est.mean()) ** 2))) if k > 1 else math.nan


def tilt_finding(
    c: Mapping[str, np.ndarray], source: str, pinned: Calibration
) -> tuple[QaFinding | None, float | None]:
    """The transducer's tilt: the beam angle from the crossings (where not pinned) and how much the
    correction changes the soundings. Returns the finding and the beam angle to apply (or None)."""
    roll, pitch = c.get("roll"), c.get("pitch")
    if roll is None or not np.isfinite(roll).any():
        return None, None
    raw, t = raw_depth(c), c["t"]
    tilt = attitude.tilt_deg(roll, pitch)
    have = np.isfinite(raw) & np.isfinite(roll)
    xy = local_xy(c["lat"], c["lon"])
    xy[~have] = np.nan
    pairs = crossing_pairs(xy, t, CROSS_RADIUS_M, CROSS_DT_S, MAX_PAIRS)
    off = pinned.depth_offset_m
    p95 = float(np.nanpercentile(tilt[have], 95)) if have.any() else 0.0
    beam = pinned.sounder_beam_deg
    if len(pairs) < MIN_CROSSINGS:
        why = f"{len(pairs)} crossings (at least {MIN_CROSSINGS} are needed)"
        fix = "pinned" if beam is not None else "not estimated"
        return QaFinding(
            "depth", "tilt", "green" if beam is not None or p95 < 5 else "yellow",
            f"the hull's tilt reaches {p95:.1f}° (95th percentile); beam angle {fix}: {why}", source,
            p95, unit="deg", threshold="a beam angle from boat.toml [sounder], or from the crossings",
            fix="" if beam is not None else "give [sounder] beam_angle_deg in boat.toml",
        ), None  # fmt: skip
    # the pairs in JACKKNIFE_BLOCKS stretches of the log, by the time of their first sounding
    span = max(float(np.ptp(t)), 1e-9)
    blocks = np.minimum(
        (JACKKNIFE_BLOCKS * (t[pairs[:, 0]] - t[0]) / span).astype(int), JACKKNIFE_BLOCKS - 1
    )

    def best(m: np.ndarray) -> float:  # the beam whose correction makes pairs[m] agree best
        return float(BEAMS[int(np.argmin(beam_profile(raw, roll, pitch, off, pairs[m])[:-1]))])

    b = beam if beam is not None else best(np.ones(len(pairs), bool))
    corr = attitude.corrected(raw, off, roll, pitch, b)
    gain = _pair_error(raw, pairs) - _pair_error(corr, pairs)
    gain_sd = _jackknife(lambda m: float(np.mean(gain[m])), blocks)
    beam_sd = 0.0 if beam is not None else _jackknife(best, blocks)
    before = float(np.mean(_pair_error(raw, pairs)))
    return _tilt_result(
        source, b, beam is not None, before, gain, gain_sd, beam_sd, p95, len(pairs)
    )


def _tilt_result(
    source: str,
    b: float,
    pinned: bool,
    before: float,
    gain: np.ndarray,
    gain_sd: float,
    beam_sd: float,
    p95: float,
    n: int,
) -> tuple[QaFinding, float | None]:
    """The finding of a beam angle ``b`` (pinned or estimated) and whether to apply it."""
    after = before - float(np.mean(gain))
    sure = np.mean(gain) > 2.0 * gain_sd if np.isfinite(gain_sd) else False
    what = f"beam angle {b:.0f}° (boat.toml)" if pinned else f"beam angle {b:.0f} ± {beam_sd:.0f}°"
    msg = (
        f"{what}: the tilt correction brings the crossings' mean disagreement from {before:.2f} to "
        f"{after:.2f} m ({n} crossings; the hull's tilt reaches {p95:.1f}°, 95th percentile)"
    )
    if pinned:
        fix, apply = f"applied: pinned in boat.toml, beam_angle_deg = {b:g}", None
    elif sure and b < BEAMS[-1]:
        fix, apply = f"applied: soundings corrected with a {b:.0f}° beam (depth_raw keeps them)", b
    else:
        fix = "not applied: no surer than no correction; give [sounder] beam_angle_deg in boat.toml"
        apply = None
    verdict = "green" if before - after < 0.05 or apply is not None or pinned else "yellow"
    return QaFinding(
        "depth", "tilt", verdict, msg, source, b, beam_sd if not pinned else math.nan, "deg",
        "applied when the crossings agree better by more than twice the jackknife's sd",
        f"crossings within {CROSS_RADIUS_M:g} m and {CROSS_DT_S:g} s apart; improvement "
        f"{np.mean(gain):.3f} ± {gain_sd:.3f} m (jackknife over {JACKKNIFE_BLOCKS} stretches)",
        fix, fix.startswith("applied"),
        {"before_m": repr(float(before)), "after_m": repr(float(after)), "crossings": str(n)},
    ), apply  # fmt: skip


def sounder_findings(
    readings: Mapping[str, tuple[np.ndarray, np.ndarray]], chosen: str, c: Mapping[str, np.ndarray]
) -> list[QaFinding]:
    """Every other depth source against the samples' (forcemap.host.fuse.sounders)."""
    if len(readings) < 2:
        return []
    t, xy = c["t"], local_xy(c["lat"], c["lon"])
    ok = np.isfinite(xy).all(axis=1)

    def position(tt: np.ndarray) -> np.ndarray:
        return np.column_stack([np.interp(tt, t[ok], xy[ok, i]) for i in (0, 1)])

    t0 = float(np.nanmin(t)) if len(t) else 0.0
    out = []
    for cmp in sounders.compare(dict(readings), chosen, position if ok.sum() > 1 else None):
        where = ", ".join(f"{(a - t0) / 60:.1f}-{(b - t0) / 60:.1f} min" for a, b in cmp.stretches)
        verdict = "green" if cmp.disagree_share < 0.05 and abs(cmp.offset_m) < 0.1 else "yellow"
        if cmp.disagree_share > LOST_RED:
            verdict = "red"
        msg = (
            f"{cmp.other.name} reads {cmp.offset_m:+.2f} m from {cmp.chosen.name} (median of "
            f"{cmp.matched}); beyond that they disagree in {100 * cmp.disagree_share:.1f} % of the "
            f"readings{' (' + where + ' into the log)' if where else ''}; the evidence trusts "
            f"{cmp.trusted}: {cmp.why}"
        )
        fix = "" if cmp.trusted == chosen else (
            f'the samples use {chosen}: prefer {cmp.trusted} in boat.toml [sources] depth = '
            f'["{cmp.trusted.split(" ", 1)[-1]}"]'
        )  # fmt: skip
        if abs(cmp.offset_m) >= 0.1:
            fix = (fix + "; " if fix else "") + (
                "a constant offset is a transducer depth one source carries and the other does not: "
                "give [depth] offset_m"
            )
        out.append(
            QaFinding(
                "depth", "sounders", verdict, msg, cmp.other.name, cmp.offset_m, unit="m",
                threshold="offset under 0.1 m and under 5 % of the readings beyond 4 x their "
                "scatter: green; over 25 % disagreeing: red",
                evidence=f"{cmp.chosen.text()}; {cmp.other.text()}", fix=fix,
                extra={"trusted": cmp.trusted, "disagree_share": repr(cmp.disagree_share),
                       "stretches": ";".join(f"{a:.3f}-{b:.3f}" for a, b in cmp.stretches)},
            )
        )  # fmt: skip
    return out


def estimate(
    rows: list[Mapping[str, Any]],
    columns: Mapping[str, str],
    readings: Mapping[str, tuple[np.ndarray, np.ndarray]],
    chosen: str,
    pinned: Calibration,
) -> tuple[list[QaFinding], dict[str, Any]]:
    """The depth findings of a log's first pass, and the calibration's updates (lost stretches, a
    beam angle) for the second."""
    names = ("t", "lat", "lon", "depth", "depth_raw", "roll", "pitch")
    c = arrays(rows, names)
    if not np.isfinite(c["depth"]).any():
        return [], {}
    source = columns.get("depth", "").split(";")[0].strip()
    out: list[QaFinding] = []
    upd: dict[str, Any] = {}
    lost, unix = lost_finding(c, source)
    if lost is not None:
        out.append(lost)
    if unix:
        upd["depth_lost"] = unix
    tilt, beam = tilt_finding(c, source, pinned)
    if tilt is not None:
        out.append(tilt)
    if beam is not None:
        upd["sounder_beam_deg"] = beam
    out += sounder_findings(readings, chosen or source, c)
    return out, upd
