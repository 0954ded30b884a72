"""A reference current: the predicted tidal current of one or more stations, as a sailor already has it.

Two forms are read (`read_reference`):

- **harmonic constants** in NOAA's fields (JSON: `stations` by id, each `name`, `lat`, `lon`, `flood_dir`
  (deg true), `z0` (the mean flow along the flood axis) and `constituents` (`name`, `amplitude` along the
  flood axis, `phase`: Greenwich, UTC); speeds in knots unless `units` says `m/s`). The prediction is
  `z0 + sum f A cos(V + u - G)` with the nodal corrections f, u and the equilibrium argument V of
  `tides.py` at the exact time (checked against UTide). NOAA's `M1` and `2MK3` are UTide's `NO1`, `MO3`.
- **a time series** of a station's predicted current, as a tide program exports it (CSV): a time column
  (ISO 8601 with its zone, UNIX seconds, or zone-less times under a header or a `# time_zone: UTC` line
  that says UTC/GMT), the speed along the flood axis (positive flood; its unit in the header, `speed_kn`,
  `Velocity_Major (knots)`, `speed (m/s)`, `cm/s`, or a `# units:` line) and the flood direction (a
  column, or a `# flood_dir:` line). `# station:`, `# name:`, `# lat:`, `# lon:` lines, or `station`,
  `lat`, `lon` columns (several stations in one file), place it. Between its times the series is a
  cubic spline; outside them it has no prediction (NaN).

Each station predicts its speed along its flood axis (m/s, positive flood) and its rate (m/s per s) at
any UNIX time; a place takes its nearest station unless one is chosen (`choose`).
"""

from __future__ import annotations

import csv
import io
import json
import math
import re
from dataclasses import dataclass, field, replace
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
from forcemap.host.vessel import tides

KNOT = 1852.0 / 3600.0
# NOAA's names of two constituents, as UTide's table has them (the same speeds)
ALIASES = {"M1": "NO1", "2MK3": "MO3"}
UNITS = {"kn": KNOT, "knots": KNOT, "knot": KNOT, "kt": KNOT, "kts": KNOT, "m/s": 1.0, "cm/s": 0.01}
# the rate of a harmonic prediction by a central difference over this (s): exact to 1e-7 of M2's
RATE_DT_S = 30.0


@dataclass(frozen=True)
class Station:
    """One reference station: where it is (None for a series without a position), its flood axis (deg
    true, the ebb the reciprocal) and its prediction, from harmonic constants or a time series."""

    id: str
    name: str
    lat: float | None
    lon: float | None
    flood_dir: float
    z0: float = 0.0  # m/s along the flood axis
    constituents: tuple[str, ...] = ()
    amplitude: np.ndarray = field(default_factory=lambda: np.zeros(0))  # m/s
    phase_deg: np.ndarray = field(default_factory=lambda: np.zeros(0))
    series_t: np.ndarray | None = None  # UNIX s
    series_v: np.ndarray | None = None  # m/s

    @property
    def form(self) -> str:
        return "time series" if self.series_t is not None else "harmonic constants"

    @property
    def span(self) -> tuple[float, float] | None:
        """The series' first and last time (None: harmonic constants predict at any time)."""
        if self.series_t is None:
            return None
        return float(self.series_t[0]), float(self.series_t[-1])

    def speed(self, utc: np.ndarray) -> np.ndarray:
        """The predicted current along the flood axis (m/s, positive flood) at UNIX times `utc`."""
        utc = np.atleast_1d(np.asarray(utc, float))
        if self.series_t is not None:
            return self._spline()(utc)
        lat = 37.0 if self.lat is None else self.lat
        F, U, V = tides.fuv(utc, self.constituents, lat)
        arg = 2 * np.pi * (V + U) - np.radians(self.phase_deg)
        return self.z0 + (F * self.amplitude * np.cos(arg)).sum(axis=1)

    def rate(self, utc: np.ndarray) -> np.ndarray:
        """The prediction's rate of change (m/s per s) at UNIX times `utc`."""
        utc = np.atleast_1d(np.asarray(utc, float))
        if self.series_t is not None:
            return self._spline().derivative()(utc)
        return (self.speed(utc + RATE_DT_S) - self.speed(utc - RATE_DT_S)) / (2 * RATE_DT_S)

    def _spline(self):  # type: ignore[no-untyped-def]
        from scipy.interpolate import CubicSpline

        spline = self.__dict__.get("_cached_spline")
        if spline is None:
            spline = CubicSpline(self.series_t, self.series_v, extrapolate=False)
            object.__setattr__(self, "_cached_spline", spline)
        return spline

    def describe(self) -> str:
        where = "" if self.lat is None else f" ({self.lat:.4f}, {self.lon:.4f})"
        return f"{self.id} {self.name}{where}, flood toward {self.flood_dir:.1f} deg, {self.form}"


@dataclass(frozen=True)
class ReferenceCurrent:
    """The stations of a reference file; each place takes its nearest (or the `chosen` one)."""

    stations: dict[str, Station]
    source: str
    chosen: str | None = None

    @property
    def ids(self) -> tuple[str, ...]:
        return tuple(self.stations)

    def choose(self, station: str | None) -> ReferenceCurrent:
        """The same reference with every place on `station` (None: each place's nearest)."""
        if station is None:
            return replace(self, chosen=None)
        key = {k.upper(): k for k in self.stations}.get(station.strip().upper())
        if key is None:
            raise ValueError(
                f"no station {station!r} in {self.source}; it has {', '.join(self.stations)}"
            )
        return replace(self, chosen=key)

    def station_index(self, lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
        """Each place's station (an index into `ids`): the chosen one, else the nearest; a station
        without a position is nearest only when it is the file's only one."""
        lat, lon = np.atleast_1d(np.asarray(lat, float)), np.atleast_1d(np.asarray(lon, float))
        ids = self.ids
        if self.chosen is not None:
            return np.full(len(lat), ids.index(self.chosen))
        placed = [i for i, s in enumerate(self.stations.values()) if s.lat is not None]
        if not placed:
            return np.zeros(len(lat), int)
        slat = np.array([self.stations[ids[i]].lat for i in placed])
        slon = np.array([self.stations[ids[i]].lon for i in placed])
        coslat = math.cos(math.radians(float(np.nanmean(slat))))
        d2 = (lat[:, None] - slat[None]) ** 2 + ((lon[:, None] - slon[None]) * coslat) ** 2
        return np.asarray(placed)[np.argmin(d2, axis=1)]

    def at(self, lat, lon, utc) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """At each (place, UNIX time): the station's speed along its flood axis (m/s), its rate (m/s per
        s), its flood direction (deg true) and the station's index."""
        idx = self.station_index(lat, lon)
        utc = np.broadcast_to(np.asarray(utc, float), idx.shape)
        speed, rate, flood = np.empty(len(idx)), np.empty(len(idx)), np.empty(len(idx))
        for i in np.unique(idx):
            st = self.stations[self.ids[i]]
            m = idx == i
            speed[m], rate[m], flood[m] = st.speed(utc[m]), st.rate(utc[m]), st.flood_dir
        return speed, rate, flood, idx

    def used(self, idx: np.ndarray) -> list[Station]:
        """The stations the indices `idx` name, most used first."""
        counts = np.bincount(np.asarray(idx, int), minlength=len(self.ids))
        return [self.stations[self.ids[i]] for i in np.argsort(-counts, kind="stable") if counts[i]]


def read_reference(path: str | Path, station: str | None = None) -> ReferenceCurrent:
    """A reference file (harmonic constants as JSON, or a CSV time series) with every station; ValueError
    saying what is wrong with it otherwise. `station` chooses one for every place."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise ValueError(
            f"cannot read the reference current {path}: {exc.strerror or exc}"
        ) from None
    if text.lstrip().startswith("{"):
        stations = _from_json(path, text)
    else:
        stations = _from_series(path, text)
    if not stations:
        raise ValueError(f"{path}: no station in this reference current")
    return ReferenceCurrent(stations, str(path)).choose(station)


def _from_json(path: Path, text: str) -> dict[str, Station]:
    try:
        raw = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not valid JSON ({exc.msg}, line {exc.lineno})") from None
    table = raw.get("stations") if isinstance(raw, dict) else None
    if not isinstance(table, dict):
        raise ValueError(f"{path}: harmonic constants need a 'stations' object (NOAA's fields)")
    scale = _unit(str(raw.get("units", {}).get("amplitude", "knots")).split(",")[0], path)
    return {str(k): _station(path, str(k), s, scale) for k, s in table.items()}


def _station(path: Path, sid: str, s: dict, scale: float) -> Station:
    try:
        names, amps, phases = [], [], []
        for c in s["constituents"]:
            name = ALIASES.get(c["name"], c["name"])
            names.append(tides.constituent(name).name)
            amps.append(float(c["amplitude"]) * scale)
            phases.append(float(c["phase"]))
        return Station(
            sid, str(s.get("name", sid)), float(s["lat"]), float(s["lon"]), float(s["flood_dir"]) % 360,
            float(s.get("z0", 0.0)) * scale, tuple(names), np.array(amps), np.array(phases),
        )  # fmt: skip
    except KeyError as exc:
        raise ValueError(f"{path}: station {sid} has no {exc.args[0]!r}") from None
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{path}: station {sid}: {exc}") from None


def _unit(text: str, path: Path) -> float:
    t = text.strip().lower()
    for key in sorted(UNITS, key=len, reverse=True):
        if re.search(rf"(^|[^a-z/]){re.escape(key)}($|[^a-z/])", t):
            return UNITS[key]
    if t in ("m_s", "ms", "mps") or t.endswith(("_m_s", "_ms", "(m s-1)")):
        return 1.0
    if t.endswith(("_kn", "_kt", "_kts", "_knots")):
        return KNOT
    if t.endswith("_cm_s"):
        return 0.01
    raise ValueError(f"{path}: the speed's unit {text!r} is not one of knots, m/s, cm/s")


def _comments(text: str) -> tuple[dict[str, str], list[str]]:
    """`# key: value` lines by key, and the other lines."""
    meta, rows = {}, []
    for line in text.splitlines():
        s = line.strip()
        if s.startswith("#"):
            m = re.match(r"#\s*([\w ]+?)\s*[:=]\s*(.+)$", s)
            if m:
                meta[m.group(1).strip().lower().replace(" ", "_")] = m.group(2).strip()
        elif s:
            rows.append(line)
    return meta, rows


def _column(header: list[str], *starts: str) -> int | None:
    for i, h in enumerate(header):
        name = re.sub(r"\(.*?\)", "", h).strip().lower().replace(" ", "_")
        if any(name == s or name.startswith(s + "_") or name.startswith(s) for s in starts):
            return i
    return None


def _from_series(path: Path, text: str) -> dict[str, Station]:
    meta, lines = _comments(text)
    rows = list(csv.reader(io.StringIO("\n".join(lines))))
    if len(rows) < 3:
        raise ValueError(f"{path}: a time series needs a header and at least two rows")
    header = [h.strip() for h in rows[0]]
    it, iv = (
        _column(header, "time", "date", "t", "utc"),
        _column(header, "speed", "velocity", "current"),
    )
    if it is None or iv is None:
        raise ValueError(
            f"{path}: a time series needs a time column and a speed column (along the flood axis); "
            f"its header is {', '.join(header)}"
        )
    unit = meta.get("units") or header[iv]
    scale = _unit(re.search(r"\((.*?)\)", unit).group(1) if "(" in unit else unit, path)
    utc_ok = bool(
        re.search(r"gmt|utc", header[it].lower() + " " + meta.get("time_zone", "").lower())
    )
    cols = {k: _column(header, *names) for k, names in
            (("flood", ("flood_dir", "meanflooddir", "flood")), ("station", ("station",)),
             ("lat", ("lat",)), ("lon", ("lon",)))}  # fmt: skip
    groups: dict[str, list] = {}
    for n, row in enumerate(rows[1:], start=2):
        if not any(c.strip() for c in row):
            continue
        try:
            key = (
                row[cols["station"]].strip()
                if cols["station"] is not None
                else meta.get("station", path.stem)
            )
            groups.setdefault(key.split()[0] if key else path.stem, []).append(
                (_time(row[it], utc_ok), float(row[iv]) * scale, row)
            )
        except (ValueError, IndexError) as exc:
            raise ValueError(f"{path}, line {n}: {exc}") from None
    return {sid: _series_station(path, sid, g, cols, meta) for sid, g in groups.items()}


def _series_station(path: Path, sid: str, g: list, cols: dict, meta: dict) -> Station:
    g.sort(key=lambda r: r[0])
    t = np.array([r[0] for r in g])
    v = np.array([r[1] for r in g])
    keep = np.concatenate([[True], np.diff(t) > 0])
    t, v = t[keep], v[keep]

    def first(key: str) -> float | None:
        if cols[key] is not None:
            return float(g[0][2][cols[key]])
        return float(meta[key]) if key in meta else None

    flood = (
        first("flood")
        if cols["flood"] is not None
        else (float(meta["flood_dir"]) if "flood_dir" in meta else None)
    )
    if flood is None:
        raise ValueError(
            f"{path}: station {sid} has no flood direction (a flood_dir column or line)"
        )
    if len(t) < 4 or not np.all(np.isfinite(v)):
        raise ValueError(f"{path}: station {sid} needs at least 4 finite speeds")
    lat, lon = first("lat"), first("lon")
    name = meta.get("name", sid)
    return Station(sid, name, lat, lon, flood % 360, series_t=t, series_v=v)


def _time(cell: str, utc_ok: bool) -> float:
    s = cell.strip()
    try:
        return float(s)
    except ValueError:
        pass
    iso = s[:-1] + "+00:00" if s.endswith(("Z", "z")) else s
    when = datetime.fromisoformat(iso)
    if when.tzinfo is None:
        if not utc_ok:
            raise ValueError(
                f"the time {s!r} has no zone: give it (Z, +hh:mm), or say UTC in the time column's "
                "header (Time (GMT)) or on a '# time_zone: UTC' line"
            )
        when = when.replace(tzinfo=UTC)
    return when.timestamp()
