"""The water level under every depth: a gauge's record read and the soundings reduced to its datum, or the
level estimated from the survey itself (the `water_level` term, a smooth function of time seen where the
track crosses or revisits itself), and the datum a depth map is given in.

A sounder measures the depth below the water's surface at that moment. With a gauge (`--water-level
GAUGE.csv`: a USGS RDB or CSV export, a NOAA CO-OPS CSV export, or a plain `time,level` CSV) a sounding
becomes the depth below the gauge's datum, `depth - level(t)` (IHO S-44's reduction). Without one, the
model `const + gp(position) + water_level` fits the bed and the level together: the level is what differs
between two passes over the same place, the crossline differences of CARIS HIPS and QPS Qimera.
"""

from __future__ import annotations

import csv
import re
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta, timezone
from pathlib import Path

import numpy as np
from forcemap.host.fuse.crossings import crossing_pairs
from forcemap.host.workbench.errors import WorkbenchError

FEET = 0.3048
# the US time zones a USGS RDB's tz_cd column gives, in hours east of UTC
TZ_HOURS = {"UTC": 0, "GMT": 0, "Z": 0, "EST": -5, "EDT": -4, "CST": -6, "CDT": -5, "MST": -7,
            "MDT": -6, "PST": -8, "PDT": -7, "AKST": -9, "AKDT": -8, "HST": -10}  # fmt: skip
# a gauge record's gap longer than this leaves the samples in it without a level
MAX_GAP_S = 3 * 3600.0
# a gauge must cover at least this share of the survey's samples
MIN_COVERED = 0.5
# two samples are a revisit when they are this close (m) and this far apart in time (s)
REVISIT_RADIUS_M = 3.0
REVISIT_MIN_DT_S = 120.0
# revisit CV: the survey's time in this many stretches; at least REVISIT_MIN_ROWS revisited samples
REVISIT_STRETCHES = 20
REVISIT_MIN_ROWS = 50

_TIME_NAMES = ("datetime", "date time", "time", "timestamp", "t", "date", "time_s", "unix_time")
_LEVEL_HINTS = ("water level", "water_level", "verified", "preliminary", "predicted", "level",
                "stage", "gage height", "gauge height", "height", "value", "elevation")  # fmt: skip


@dataclass
class Gauge:
    """A water-level record: UNIX times (s) and levels (m above the gauge's datum)."""

    t: np.ndarray
    level: np.ndarray
    source: Path
    layout: str  # "USGS RDB", "NOAA CO-OPS CSV", "CSV"
    datum: str  # what the levels are measured from, for captions and metadata
    notes: list[str]

    def at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The level at UNIX times `t` (linear between records) and which times the record covers."""
        t = np.asarray(t, float)
        k = np.clip(np.searchsorted(self.t, t), 1, len(self.t) - 1)
        lo, hi = self.t[k - 1], self.t[k]
        covered = (t >= self.t[0]) & (t <= self.t[-1]) & (hi - lo <= MAX_GAP_S)
        w = np.clip((t - lo) / np.maximum(hi - lo, 1e-9), 0.0, 1.0)
        return self.level[k - 1] + w * (self.level[k] - self.level[k - 1]), covered


def _bad(path: Path, why: str) -> WorkbenchError:
    return WorkbenchError(f"{path}: not a water-level record ({why}); give a USGS RDB or CSV export, a "
                          "NOAA CO-OPS CSV export, or a CSV of time,level")  # fmt: skip


def _parse_time(text: str, offset_h: float | None) -> float:
    """UNIX seconds from a number, or an ISO-like date and time (UTC unless it says otherwise)."""
    text = text.strip()
    try:
        return float(text)
    except ValueError:
        pass
    iso = text.replace("/", "-").replace(" ", "T", 1).removesuffix("Z").removesuffix("UTC").strip()
    d = datetime.fromisoformat(iso)
    if d.tzinfo is None:
        d = d.replace(tzinfo=UTC if offset_h is None else timezone(timedelta(hours=offset_h)))
    return d.timestamp()


def _rows(path: Path) -> tuple[list[str], list[list[str]]]:
    try:
        text = path.read_text(encoding="utf-8-sig", errors="strict")
    except FileNotFoundError:
        raise WorkbenchError(f"{path}: no such water-level file") from None
    except IsADirectoryError:
        raise WorkbenchError(f"{path} is a folder; give a water-level CSV file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise _bad(path, f"cannot read it as text: {exc}") from None
    comments = [ln for ln in text.splitlines() if ln.startswith("#")]
    body = [ln for ln in text.splitlines() if ln.strip() and not ln.startswith("#")]
    if not body:
        raise _bad(path, "no rows")
    delim = "\t" if "\t" in body[0] else ","
    return comments, [[c.strip() for c in r] for r in csv.reader(body, delimiter=delim)]


def _unit_scale(name: str, unit: str = "") -> float:
    text = f"{name} {unit}".lower()
    return FEET if re.search(r"\bft\b|feet|foot|\(ft\)|_ft\b", text) else 1.0


def read_gauge(path: str | Path) -> Gauge:
    """A gauge's record from a USGS RDB (tab-separated, `#` comments, a field-size line; gage height in
    feet), a NOAA CO-OPS CSV (`Date Time, Water Level, ...`, or `Date, Time (GMT), Verified (m), ...`), or a
    plain CSV (a time column and a level column, with or without a header; `_ft`/`(ft)` means feet)."""
    path = Path(path)
    comments, rows = _rows(path)
    head = [h.lower() for h in rows[0]]
    if "agency_cd" in head:
        return _usgs_rdb(path, comments, rows)
    if any(re.match(r"^-?\d", h) for h in head):  # no header
        header, data = ["time", "level"], rows
    else:
        header, data = rows[0], rows[1:]
    return _table(path, header, data)


def _usgs_rdb(path: Path, comments: list[str], rows: list[list[str]]) -> Gauge:
    header, data = rows[0], rows[1:]
    if data and all(re.fullmatch(r"\d+[sdn]", c) for c in data[0] if c):
        data = data[1:]  # the field-size line
    names = [h.lower() for h in header]
    values = [i for i, h in enumerate(names) if re.fullmatch(r"\d+_\d{5}", h)]
    if "datetime" not in names or not values:
        raise _bad(path, "a USGS RDB needs datetime and a value column such as 123456_00065")
    ti, vi = names.index("datetime"), values[0]
    tz = names.index("tz_cd") if "tz_cd" in names else None
    t, v = [], []
    for r in data:
        if len(r) <= max(ti, vi) or not r[vi]:
            continue
        try:
            off = TZ_HOURS.get(r[tz].upper()) if tz is not None and tz < len(r) else 0
            t.append(_parse_time(r[ti], 0 if off is None else off))
            v.append(float(r[vi]) * FEET)
        except ValueError:
            continue
    site = next((r[1] for r in data if len(r) > 1), "")
    datum = f"the gauge datum of USGS {site}".strip()
    return _gauge(
        path, t, v, "USGS RDB", datum, ["USGS values read as feet and turned into metres"]
    )


def _pick_level(names: list[str]) -> list[int]:
    """The level columns in order of preference (NOAA: verified before preliminary before predicted)."""
    out = []
    for hint in _LEVEL_HINTS:
        out += [i for i, h in enumerate(names) if hint in h and i not in out and "sigma" not in h]
    return out


def _table(path: Path, header: list[str], data: list[list[str]]) -> Gauge:
    names = [h.strip().lower() for h in header]
    noaa = "date time" in names or any(h.startswith("time (") for h in names)
    zone = next((h for h in names if h.startswith("time (")), "")
    if zone and "gmt" not in zone and "utc" not in zone:
        raise _bad(path, f"times are '{zone}': download the record in GMT")
    ti = next((names.index(n) for n in _TIME_NAMES if n in names), None)
    date_i = names.index("date") if "date" in names and zone else None
    if zone:
        ti = names.index(zone)
    level_cols = [i for i in _pick_level(names) if i != ti and i != date_i]
    if ti is None or not level_cols:
        raise _bad(path, "no time and level columns")
    unit_i = names.index("unit_of_measure") if "unit_of_measure" in names else None
    t, v = [], []
    for r in data:
        try:
            stamp = f"{r[date_i]} {r[ti]}" if date_i is not None else r[ti]
            cell = next((r[i] for i in level_cols if i < len(r) and r[i] not in ("", "-")), None)
            if cell is None:
                continue
            unit = r[unit_i] if unit_i is not None and unit_i < len(r) else ""
            scale = _unit_scale(header[level_cols[0]], unit)
            t.append(_parse_time(stamp, None))
            v.append(float(cell) * scale)
        except (ValueError, IndexError):
            continue
    layout = "NOAA CO-OPS CSV" if noaa else "CSV"
    return _gauge(path, t, v, layout, f"the datum of the gauge record {path.name}", [])


def _gauge(path: Path, t: list, v: list, layout: str, datum: str, notes: list[str]) -> Gauge:
    tt, vv = np.asarray(t, float), np.asarray(v, float)
    ok = np.isfinite(tt) & np.isfinite(vv)
    if ok.sum() < 2:
        raise _bad(path, f"{int(ok.sum())} readable time,level row(s); it needs at least 2")
    order = np.argsort(tt[ok], kind="stable")
    tt, vv = tt[ok][order], vv[ok][order]
    keep = np.concatenate([[True], np.diff(tt) > 0])
    return Gauge(tt[keep], vv[keep], path, layout, datum, notes)


def reduce_to_gauge(survey, gauge: Gauge):
    """The survey with its depth below the gauge's datum (`depth - level(t)`); samples the record does not
    cover are left out, counted in a note. A survey without depth is returned unchanged."""
    if "depth" not in survey.columns:
        survey.notes.append(f"--water-level {gauge.source}: the table has no depth to reduce")
        return survey
    level, covered = gauge.at(survey.columns["t"])
    if covered.mean() < MIN_COVERED:
        raise WorkbenchError(
            f"{gauge.source}: the water-level record covers {covered.mean():.0%} of the survey's time; "
            "give the gauge's record for the survey's day(s)"
        )
    if not covered.all():
        survey = survey.subset(covered)
        level = level[covered]
        survey.notes.append(
            f"left out {int((~covered).sum())} sample(s) the water-level record does not cover"
        )
    survey.columns["depth"] = survey.columns["depth"] - level
    survey.datum = f"depth below {gauge.datum} ({gauge.layout})"
    survey.notes += gauge.notes
    return survey


def revisits(xy: np.ndarray, t: np.ndarray, radius_m: float = REVISIT_RADIUS_M) -> np.ndarray:
    """Pairs (i, j) of samples within `radius_m` of each other and at least REVISIT_MIN_DT_S apart:
    the places where the track crosses or revisits itself."""
    return crossing_pairs(xy, t, radius_m, REVISIT_MIN_DT_S)


def revisit_folds(
    xy: np.ndarray,
    t: np.ndarray,
    k: int = 5,
    min_rows: int = REVISIT_MIN_ROWS,
    radius_m: float = REVISIT_RADIUS_M,
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Folds for judging what changes in time where the track revisits itself: the survey's time cut into
    REVISIT_STRETCHES stretches dealt to `k` folds in turn; the samples another fold's pass revisits (the
    rows to score) and their stretch (the paired unit). None when fewer than `min_rows` are revisited."""
    span = max(float(np.ptp(t)), 1e-9)
    stretch = np.minimum(
        (REVISIT_STRETCHES * (t - t.min()) / span).astype(int), REVISIT_STRETCHES - 1
    )
    folds = stretch % max(2, min(k, REVISIT_STRETCHES // 2))
    rows = revisited_rows(xy, t, folds, radius_m)
    if len(rows) < min_rows:
        return None
    return folds, rows, stretch[rows]


def revisited_rows(
    xy: np.ndarray, t: np.ndarray, folds: np.ndarray, radius_m: float = REVISIT_RADIUS_M
) -> np.ndarray:
    """The samples with a sample of another fold within `radius_m` and at least REVISIT_MIN_DT_S
    apart (the rows of `revisits`' pairs that join two folds), without listing the pairs: a week at 1 Hz
    over one reach has ~10^8 of them. Each fold's samples ask a tree of the others' for the nearest; only
    those within REVISIT_MIN_DT_S of another fold's sample in time (where one stretch meets the next) look
    at every neighbour's time."""
    from scipy.spatial import cKDTree

    hit = np.zeros(len(t), bool)
    order = np.argsort(t, kind="stable")
    ts, fs = t[order], folds[order]
    for f in np.unique(folds):
        mine, others = np.flatnonzero(folds == f), np.flatnonzero(folds != f)
        if not len(others):
            continue
        # unbalanced, uncompacted: the same answers, the fastest to ask on a survey that revisits its ground
        tree = cKDTree(xy[others], balanced_tree=False, compact_nodes=False)
        d, _ = tree.query(xy[mine], distance_upper_bound=np.nextafter(radius_m, np.inf))
        near = d <= radius_m
        # another fold's sample closer in time than REVISIT_MIN_DT_S: the nearest may not count, look at all
        other_t = ts[fs != f]
        lo = np.searchsorted(other_t, t[mine] - REVISIT_MIN_DT_S, side="right")
        hi = np.searchsorted(other_t, t[mine] + REVISIT_MIN_DT_S, side="left")
        close = near & (hi > lo)
        hit[mine[near & ~close]] = True
        rows = mine[close]
        # the 16 nearest first (the pass itself is a handful of them), every neighbour where those do not say
        dk, jk = tree.query(
            xy[rows], k=16, distance_upper_bound=np.nextafter(radius_m, np.inf)
        )
        found = dk <= radius_m
        far = (
            np.abs(t[others[np.minimum(jk, len(others) - 1)]] - t[rows][:, None])
            >= REVISIT_MIN_DT_S
        )
        hit[rows[(found & far).any(axis=1)]] = True
        todo = rows[~(found & far).any(axis=1) & found.all(axis=1)]
        for i, nb in zip(todo, tree.query_ball_point(xy[todo], radius_m), strict=True):
            hit[i] = bool(np.any(np.abs(t[others[nb]] - t[i]) >= REVISIT_MIN_DT_S))
    return np.flatnonzero(hit)


def crossline_errors(sm, radius_m: float = REVISIT_RADIUS_M) -> tuple[np.ndarray, np.ndarray] | None:
    """A fitted `SurveyModel`'s held-out errors where the track revisits itself (each time stretch predicted
    from the others, scored where another pass comes within `radius_m`), and each scored sample's stretch.
    None when the survey hardly revisits itself."""
    plan = revisit_folds(sm.survey.xy, sm.survey.trel, radius_m=radius_m)
    if plan is None:
        return None
    folds, rows, stretch = plan
    return sm.cv(folds, interval=False).error[rows], stretch


def crossline_rmse(sm, radius_m: float = REVISIT_RADIUS_M, errors=None) -> dict | None:
    """The RMS of `crossline_errors` (given, or computed): the error a moving surface, a tide or a seiche
    leaves, which blocked CV cannot see. None when the survey hardly revisits itself."""
    found = crossline_errors(sm, radius_m) if errors is None else errors
    if found is None:
        return None
    err = found[0]
    return {"crossline_rmse": float(np.sqrt(np.mean(err**2))), "crossline_samples": len(err)}


def crossings(xy: np.ndarray, t: np.ndarray) -> int:
    """How many times the track meets an earlier stretch of itself: revisit pairs counted once per
    minute of each pass."""
    p = revisits(xy, t)
    if not len(p):
        return 0
    a, b = np.floor(t[p[:, 0]] / 60.0), np.floor(t[p[:, 1]] / 60.0)
    return len(np.unique(np.column_stack([np.minimum(a, b), np.maximum(a, b)]), axis=0))


def level_term(model):
    """The index of a fitted model's level term (`water_level`, or a `tide`'s uniform part), or None."""
    return next((i for i, t in enumerate(model.feat_terms_) if t.is_level), None)


def level_estimate(model, t: np.ndarray, t0: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The fitted water level at survey times `t` (s since the survey's start, UNIX time `t0`: for a tide,
    its first sample's by default), centred on its mean over `t`, and its posterior sd (m). The level is the
    `water_level` term's, or the tidal term's (its uniform part: the tide at the gauge the survey is)."""
    from scipy import linalg

    k = level_term(model)
    if k is None:
        raise WorkbenchError("the model has no water_level or tide term")
    term = model.feat_terms_[k]
    start = int(sum(model.design_.sizes[:k]))
    t = np.asarray(t, float)
    phi = term.level_features(t, t0)
    m = phi.shape[1]
    phi = phi - phi.mean(axis=0)
    post = model.posterior_
    mu = phi @ post["mu"][start : start + m] * model.y_scale_
    full = np.zeros((len(phi), len(post["mu"])))
    full[:, start : start + m] = phi
    V = linalg.solve_triangular(post["L"], (full * post["s"]).T, lower=True, check_finite=False)
    return mu, np.sqrt((V**2).sum(axis=0)) * model.y_scale_


def surface_datum(n_crossings: int) -> str:
    """The datum of a depth map without a gauge."""
    return (
        "depth below the surface at the survey's mid-time level, estimated from "
        f"{n_crossings} crossing{'s' if n_crossings != 1 else ''}"
    )


def map_datum(survey, terms: list[str] | None = None, at: float | None = None) -> str:
    """What a depth map of `survey` is measured from: the gauge's datum, the survey's mean level when the
    model estimates the level (`water_level`), the level the tidal fit predicts at the map's time (`tide`:
    mid-survey, or `at`), else the surface as it was at each sounding."""
    if getattr(survey, "datum", None):
        return survey.datum
    from forcemap.host.workbench.survey.table import is_circular
    from forcemap.host.workbench.terms import registry

    levels = [s for s in (registry.parse_term(str(t), is_circular) for t in terms or []) if registry.caps(s).is_level]
    tidal = [s for s in levels if registry.caps(s).predicts_in_time]
    if tidal:
        import time

        when = (
            "the survey's mid-time"
            if at is None
            else time.strftime("%Y-%m-%dT%H:%MZ", time.gmtime(at))
        )
        return (
            f"depth below the water surface as the tidal fit ({tidal[0]}) "
            f"predicts it at {when}, from {crossings(survey.xy, survey.trel)} crossings"
        )
    if levels:
        return surface_datum(crossings(survey.xy, survey.trel))
    return "depth below the water surface at the time of each sounding (not reduced to a datum)"
