"""The samples table (CSV, Parquet) and the track (GeoJSON, KML) from MCAP logs."""

from __future__ import annotations

import dataclasses
import datetime as dt
import io
import json
import math
import os
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any, TextIO
from xml.sax.saxutils import escape

import numpy as np
from forcemap.host.errors import CliError
from forcemap.host.log.mcap import MCAP_MAGIC, FileScan, read_messages
from forcemap.host.log.messages import SAMPLE_COLUMNS
from forcemap.host.outputs import atomic_path, atomic_write

# docs/CONVENTIONS.md, "The samples table": these first, in this order; other numeric fields follow.
COLUMNS: tuple[str, ...] = SAMPLE_COLUMNS
FORMATS = ("csv", "parquet", "geojson", "kml")
# at most this many sample points in a GeoJSON (the track line keeps every position)
MAX_POINTS = 5000


def _number(value: Any) -> float | None:
    if isinstance(value, bool):
        return float(value)
    if isinstance(value, int | float):
        f = float(value)
        return f if math.isfinite(f) else None
    return None


TRUNCATED = " is truncated ("  # in every truncation note, for commands that pick them out


@dataclasses.dataclass
class Cut:
    """A truncated log: why reading stopped, and the ``/samples`` rows read before (their time span)."""

    path: str
    error: str
    rows: int
    t0: float | None
    t1: float | None

    def note(self) -> str:
        """One line: how much was read, and that `forcemap log recover` exists."""
        span = ""
        if self.t0 is not None and self.t1 is not None:
            span = f" ({(self.t1 - self.t0) / 60:.1f} min of survey, to {_iso(self.t1)[11:19]} UTC)"
        why = self.error.rstrip(": ")
        if not why or why.startswith("EndOfFile"):  # the mcap reader's word for a cut file
            why = "it ends mid-record, as a killed or cut log does"
        return (
            f"{self.path}{TRUNCATED}{why}): read {self.rows:,} "
            f"samples{span}, up to its last complete chunk; `forcemap log recover {self.path}` "
            "rewrites it as a complete file"
        )


class Table:
    """Columns of floats (None for missing), in the conventions' order; ``cuts``: truncated inputs."""

    def __init__(
        self, columns: list[str], rows: list[list[float | None]], cuts: list[Cut] | None = None
    ):
        self.columns = columns
        self.rows = rows
        self.cuts = cuts or []

    def notes(self) -> list[str]:
        """One line per truncated input (empty when every log was complete)."""
        return [c.note() for c in self.cuts]

    def column(self, name: str) -> list[float | None]:
        i = self.columns.index(name)
        return [r[i] for r in self.rows]

    def __len__(self) -> int:
        return len(self.rows)


def check_logs(paths: Sequence[str | os.PathLike[str]]) -> None:
    """Refuse, in one line, any path that is not an MCAP file (a table given by mistake, a folder)."""
    for path in paths:
        try:
            with open(path, "rb") as f:
                head = f.read(len(MCAP_MAGIC))
        except IsADirectoryError:
            raise CliError(
                f"{path} is a folder; give MCAP logs, or a folder that holds some"
            ) from None
        except OSError as exc:
            raise CliError(f"{path}: cannot read it ({exc.strerror or exc})") from None
        if head != MCAP_MAGIC:
            raise CliError(
                f"{path} is not an MCAP log; give the logs that `forcemap run` or "
                "`forcemap import` wrote"
            )


def samples_table(
    paths: Sequence[str | os.PathLike[str]],
    navigation: str | None = None,
    remove_latency: bool | None = None,
) -> Table:
    """Every ``/samples`` row of the given files, ordered by ``t``, duplicates (same ``t``) dropped.

    ``navigation``: "smoothed" (each row's navigation estimated from every source at its own time,
    and its compensation done again: forcemap.host.convert.navigation_table) or "logged" (the rows
    as the pipeline made them); None follows the log's boat file (``[sync] navigation``), and so
    does ``remove_latency`` (``[sync] latency``).

    Columns are the conventions' columns first, then any other numeric field in order of first
    appearance. A column that is empty in every row is left out (``t`` always stays).
    """
    from forcemap.host.convert import navigation_table as nt

    settings = nt.settings(paths)
    smooth = (navigation or settings[0]) != "logged"
    nav_messages: list[tuple[str, int, dict]] = []
    records: list[dict[str, Any]] = []
    extra: dict[str, None] = {}
    known = set(COLUMNS)
    cuts: list[Cut] = []
    topics = ("/samples", *nt.READING_TOPICS) if smooth else "/samples"
    for path in paths:
        scan, first = FileScan(Path(path)), len(records)
        for m in read_messages(path, topics, scan=scan, accept=nt.wanted):
            if m.topic != "/samples":
                nav_messages.append((m.topic, m.log_time_ns, m.message))
                continue
            row = m.message
            if not isinstance(row, dict):
                continue
            if "t" not in row or _number(row.get("t")) is None:
                row = {**row, "t": m.log_time_ns / 1e9}
            records.append(row)
            for k in row:
                if k not in known and k not in extra:
                    extra[k] = None
        if scan.truncated:
            times = [_number(r.get("t")) for r in records[first:]]
            times = [t for t in times if t is not None]
            t0, t1 = (min(times), max(times)) if times else (None, None)
            cuts.append(Cut(os.fspath(path), scan.error, len(records) - first, t0, t1))
    records.sort(key=lambda r: float(r["t"]))
    unique: list[dict[str, Any]] = []
    for r in records:
        if unique and float(unique[-1]["t"]) == float(r["t"]):
            continue
        unique.append(r)
    candidates = list(COLUMNS) + list(extra)
    keep = [c for c in candidates if c == "t" or any(_number(r.get(c)) is not None for r in unique)]
    rows = [[_number(r.get(c)) for c in keep] for r in unique]
    if not smooth or not rows:
        return with_tvu(Table(keep, rows, cuts), paths)
    remove = remove_latency if remove_latency is not None else settings[1] != "keep"
    columns, rows, _ = nt.smooth(keep, rows, paths, nav_messages, remove_latency=remove)
    return with_tvu(Table(columns, rows, cuts), paths)


def with_tvu(table: Table, paths: Sequence[str | os.PathLike[str]]) -> Table:
    """The table with each sounding's TVU, ``depth_tvu`` (m, 95 %; forcemap.host.fuse.tvu): the log's
    sounder (boat.toml [sounder]) and measured position noise; empty where the bottom was lost."""
    if "depth" not in table.columns or not len(table):
        return table
    from forcemap.host.convert.depth_findings import local_xy
    from forcemap.host.convert.nav_findings import log_findings
    from forcemap.host.convert.navigation_table import log_metadata
    from forcemap.host.fuse import tvu

    def col(name: str) -> np.ndarray | None:
        if name not in table.columns:
            return None
        return np.array([np.nan if v is None else v for v in table.column(name)], float)

    cal = log_metadata(paths, "calibration")
    pos = log_metadata(paths, "columns").get("lat", "").split(";")[0].strip()
    sd, _ = tvu.position_sd(log_findings(paths, compute=False), pos)
    offset = _number(cal.get("depth_offset_m")) or 0.0
    depth, lost = col("depth"), col("bottom_lost")
    lat, lon = col("lat"), col("lon")
    # a log with no position (an ADCP on bottom track alone): no slope along a track, so no such term
    xy = np.full((len(depth), 2), np.nan) if lat is None or lon is None else local_xy(lat, lon)
    u = tvu.table_tvu(
        depth, xy, tvu.spec_of(cal), col("depth_raw"), col("roll"), col("pitch"), sd, 0.0, offset
    ).tvu  # type: ignore[arg-type]
    if lost is not None:
        u[np.nan_to_num(lost) > 0] = np.nan
    table.columns.append("depth_tvu")
    for row, value in zip(table.rows, u.tolist(), strict=True):
        row.append(None if not math.isfinite(value) else round(value, 4))
    return table


def _cell(value: float | None) -> str:
    if value is None:
        return ""
    if value == int(value) and abs(value) < 1e15:
        return str(int(value))
    return repr(value)


def write_csv(table: Table, out: TextIO) -> None:
    out.write(",".join(table.columns) + "\n")
    for row in table.rows:
        out.write(",".join(_cell(v) for v in row) + "\n")


def write_parquet(table: Table, path: str | os.PathLike[str]) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    arrays = [pa.array(table.column(c), type=pa.float64()) for c in table.columns]
    pq.write_table(pa.table(arrays, names=table.columns), path)


def track(paths: Sequence[str | os.PathLike[str]]) -> list[tuple[float, float, float]]:
    """(t, lat, lon) of the boat: from ``/fix`` if the log has it, else from ``/samples``."""
    points: list[tuple[float, float, float]] = []
    for m in read_messages(paths, "/fix"):
        lat, lon = _number(m.message.get("latitude")), _number(m.message.get("longitude"))
        if lat is not None and lon is not None and (lat, lon) != (0.0, 0.0):
            ts = m.message.get("timestamp") or {}
            t = (
                ts["sec"] + ts.get("nsec", 0) / 1e9
                if isinstance(ts, dict) and isinstance(ts.get("sec"), int | float)
                else m.log_time_ns / 1e9
            )
            points.append((t, lat, lon))
    if not points:
        table = samples_table(paths)
        if "lat" in table.columns and "lon" in table.columns:
            for t, lat, lon in zip(
                table.column("t"), table.column("lat"), table.column("lon"), strict=True
            ):
                if t is not None and lat is not None and lon is not None:
                    points.append((t, lat, lon))
    points.sort()
    return points


def _iso(t: float) -> str:
    return dt.datetime.fromtimestamp(t, dt.UTC).isoformat().replace("+00:00", "Z")


def geojson(points: list[tuple[float, float, float]], table: Table | None = None) -> dict[str, Any]:
    """A FeatureCollection: the track as a LineString, and (thinned) samples as Points."""
    features: list[dict[str, Any]] = []
    if points:
        features.append(
            {
                "type": "Feature",
                "geometry": {
                    "type": "LineString",
                    "coordinates": [[lon, lat] for _, lat, lon in points],
                },
                "properties": {
                    "name": "track",
                    "start": _iso(points[0][0]),
                    "end": _iso(points[-1][0]),
                    "points": len(points),
                },
            }
        )
    if table is not None and "lat" in table.columns and "lon" in table.columns:
        rows = [
            r
            for r in table.rows
            if r[table.columns.index("lat")] is not None
            and r[table.columns.index("lon")] is not None
        ]
        step = max(1, math.ceil(len(rows) / MAX_POINTS))
        for r in rows[::step]:
            props = {c: v for c, v in zip(table.columns, r, strict=True) if v is not None}
            props["time"] = _iso(props["t"])
            features.append(
                {
                    "type": "Feature",
                    "geometry": {"type": "Point", "coordinates": [props["lon"], props["lat"]]},
                    "properties": props,
                }
            )
    return {"type": "FeatureCollection", "features": features}


def kml(points: list[tuple[float, float, float]], name: str = "forcemap track") -> str:
    """A KML document with the track as a LineString and placemarks at its start and end."""
    out = io.StringIO()
    out.write('<?xml version="1.0" encoding="UTF-8"?>\n')
    out.write('<kml xmlns="http://www.opengis.net/kml/2.2">\n<Document>\n')
    out.write(f"<name>{escape(name)}</name>\n")
    out.write(
        '<Style id="track"><LineStyle><color>ff0000ff</color><width>3</width></LineStyle></Style>\n'
    )
    if points:
        out.write("<Placemark><name>track</name><styleUrl>#track</styleUrl>\n")
        out.write(
            f"<TimeSpan><begin>{_iso(points[0][0])}</begin><end>{_iso(points[-1][0])}</end></TimeSpan>\n"
        )
        out.write("<LineString><tessellate>1</tessellate><coordinates>\n")
        for _, lat, lon in points:
            out.write(f"{lon:.7f},{lat:.7f},0\n")
        out.write("</coordinates></LineString></Placemark>\n")
        for label, (t, lat, lon) in (("start", points[0]), ("end", points[-1])):
            out.write(
                f"<Placemark><name>{label}</name><TimeStamp><when>{_iso(t)}</when></TimeStamp>"
                f"<Point><coordinates>{lon:.7f},{lat:.7f},0</coordinates></Point></Placemark>\n"
            )
    out.write("</Document>\n</kml>\n")
    return out.getvalue()


def export(
    paths: Iterable[str | os.PathLike[str]], fmt: str, out: str, notes: list[str] | None = None
) -> str:
    """Write ``fmt`` to ``out`` ("-" is stdout for text formats). Returns a one-line summary.

    The file appears whole or not at all; a log with nothing to write writes nothing (CliError).
    ``notes`` gets one line per truncated log (how much of it was read).
    """
    paths = list(paths)
    if fmt not in FORMATS:
        raise CliError(f"unknown format {fmt!r}: expected one of {', '.join(FORMATS)}")
    if fmt == "parquet" and out == "-":
        raise CliError("parquet needs an output file (-o FILE)")
    names = ", ".join(str(p) for p in paths)
    if fmt in ("csv", "parquet"):
        table = samples_table(paths)
        if notes is not None:
            notes += table.notes()
        if not len(table):
            raise CliError(
                f"no samples in {names}: the log has no /samples rows; "
                "`forcemap log info FILE` shows what it holds"
            )
        if fmt == "parquet":
            with atomic_path(out) as tmp:
                write_parquet(table, tmp)
        else:
            _write_text(out, lambda f: write_csv(table, f))
        return f"{len(table)} samples, {len(table.columns)} columns -> {out}"
    points = track(paths)
    if not points:
        raise CliError(
            f"no position in {names}: neither /fix nor /samples has a latitude and longitude"
        )
    if fmt == "geojson":
        table = samples_table(paths)
        if notes is not None:
            notes += table.notes()
        doc = geojson(points, table)
        _write_text(out, lambda f: json.dump(doc, f))
    else:
        text = kml(points, name=os.path.basename(str(paths[0])) if paths else "forcemap track")
        _write_text(out, lambda f: f.write(text))
    return f"{len(points)} track points -> {out}"


def _write_text(out: str, write) -> None:
    import sys

    if out == "-":
        write(sys.stdout)
        sys.stdout.flush()
        return
    with atomic_write(out) as f:
        write(f)
