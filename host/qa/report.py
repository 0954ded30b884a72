"""A log's quality report in QRev's form: every ``qa.*`` finding of the log and the checks computed now,
graded per category (green, yellow, red) with the number behind each verdict and its fix."""

from __future__ import annotations

import math
import tempfile
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from forcemap.host.convert import self_calibration as sc
from forcemap.host.log.qa_records import CATEGORIES, QaFinding, is_finding, worst
from forcemap.host.qa import checks

MCAP_MAGIC = b"\x89MCAP"
COLUMNS = (
    "t", "lat", "lon", "heading", "yaw_rate", "sog", "cog", "depth", "stw", "app_wind_speed",
    "wind_speed", "current_east", "current_north", "roll", "pitch", "depth_raw", "bottom_lost",
)  # fmt: skip


@dataclass
class CheckReport:
    """Every finding of one log, by category."""

    path: str
    rows: int
    findings: list[QaFinding] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def by_category(self) -> dict[str, list[QaFinding]]:
        out: dict[str, list[QaFinding]] = {c: [] for c in CATEGORIES}
        for f in self.findings:
            out[f.category if f.category in out else "other"].append(f)
        return {c: fs for c, fs in out.items() if fs}

    @property
    def verdict(self) -> str:
        return worst([f.verdict for f in self.findings])


def _metadata(path: str | Path, keep) -> dict[str, dict[str, str]]:
    """The last metadata record of each name ``keep(name)`` accepts, of an MCAP log."""
    from forcemap.host.log.mcap import FileScan, iter_records
    from mcap.reader import make_reader
    from mcap.records import Metadata

    found: dict[str, dict[str, str]] = {}
    try:
        with open(path, "rb") as f:
            for m in make_reader(f).iter_metadata():
                if keep(m.name):
                    found[m.name] = dict(m.metadata)
    except Exception:  # no summary (a killed log): read the records themselves
        for record in iter_records(path, FileScan(path)):
            if isinstance(record, Metadata) and keep(record.name):
                found[record.name] = dict(record.metadata)
    return found


def log_findings(path: str | Path) -> list[QaFinding]:
    """Every ``qa.*`` metadata record of an MCAP log (the last of each name)."""
    out = []
    for data in _metadata(path, is_finding).values():
        try:
            out.append(QaFinding.from_metadata(data))
        except (TypeError, ValueError):  # a record of another shape: shown as is
            msg = "; ".join(f"{k}={v}" for k, v in data.items())[:200]
            out.append(QaFinding("other", "unreadable", "yellow", msg))
    return out


def sources_report(path: str | Path) -> dict[str, dict[str, Any]]:
    """The log's last ``sources`` record: per quantity, every source against the chosen one."""
    import json

    rec = _metadata(path, lambda n: n == "sources").get("sources", {})
    out = {}
    for q, text in rec.items():
        try:
            out[q] = json.loads(text)
        except ValueError:
            continue
    return out


def arrays(raw: Mapping[str, list]) -> dict[str, np.ndarray]:
    """The checked columns of a table as float arrays (NaN where empty or not a number)."""

    def num(v: Any) -> float:
        try:
            x = float(v)
        except (TypeError, ValueError):
            return math.nan
        return x if math.isfinite(x) else math.nan

    n = len(raw.get("t", []))
    return {
        c: np.array([num(v) for v in raw[c]], float) if c in raw else np.full(n, np.nan)
        for c in COLUMNS
    }


def _first(columns: Mapping[str, str], col: str) -> str:
    return columns.get(col, "").split(";")[0].strip()


def computed_findings(
    c: Mapping[str, np.ndarray],
    columns: Mapping[str, str],
    recorded: list[QaFinding] | None = None,
    calibration: Mapping[str, str] | None = None,
) -> list[QaFinding]:
    """The checks computed on the samples themselves (``recorded``: the log's own findings, whose
    bottom lost is not estimated again; ``calibration``: its boat file, for the sounder)."""
    from forcemap.host.convert.depth_findings import local_xy, lost_finding
    from forcemap.host.qa.soundings import s44_finding

    recorded = recorded or []
    depth_src = _first(columns, "depth")
    out: list[QaFinding | None] = [checks.time_finding(c)]
    if not any(f.check == "bottom_lost" for f in recorded) and np.isfinite(c["depth"]).any():
        lost, _ = lost_finding(c, depth_src)
        marked = np.nan_to_num(c["bottom_lost"]) > 0
        if lost is not None and lost.applied and marked.any():  # a table an import marked
            fix = f"the table marks {int(marked.sum())} rows bottom_lost = 1: depth maps leave them out"
            lost = QaFinding(**{**asdict(lost), "fix": fix, "applied": False})
        elif lost is not None and lost.applied:  # estimated now: the rows are not marked in the file
            lost = _not_applied(lost)
            c = {**c, "bottom_lost": _marks(c, lost)}
        out.append(lost)
    if np.isfinite(c["depth"]).any() and np.isfinite(c["lat"]).any():
        out.append(s44_finding(c, local_xy(c["lat"], c["lon"]), depth_src, recorded, calibration))
    out.append(checks.position_finding(c, _first(columns, "lat")))
    out += checks.heading_findings(c, _first(columns, "heading"))
    out.append(checks.wind_finding(c, _first(columns, "app_wind_speed")))
    out.append(checks.depth_finding(c, depth_src))
    out.append(checks.current_finding(c, _first(columns, "stw")))
    return [f for f in out if f is not None]


def _marks(c: Mapping[str, np.ndarray], f: QaFinding) -> np.ndarray:
    """The rows inside a bottom-lost finding's stretches (UNIX s)."""
    out = np.zeros(len(c["t"]))
    for span in f.extra.get("stretches", "").split(";"):
        if span:
            a, b = (float(x) for x in span.split("-", 1))
            out[(c["t"] >= a) & (c["t"] <= b)] = 1.0
    return out


def _not_applied(f: QaFinding) -> QaFinding:
    """An estimate made on a table: it says how to apply it, never that it was."""
    if not f.applied:
        return f
    fix = "to apply (import the raw log again, or pin in boat.toml): " + f.fix.removeprefix(
        "applied:"
    ).removeprefix("marked:").strip()
    return QaFinding(**{**asdict(f), "fix": fix, "applied": False})


def check_table(path: str | Path) -> CheckReport:
    """A samples table (CSV, Parquet) or an MCAP log: its recorded findings and the checks now."""
    from forcemap.host.workbench.survey.table_files import mcap_provenance, read_raw

    p = Path(path)
    raw = read_raw(p)
    is_mcap = p.suffix.lower() == ".mcap"
    columns = mcap_provenance(p) if is_mcap else {}
    recorded = log_findings(p) if is_mcap else []
    c = arrays(raw)
    rep = CheckReport(str(path), len(c["t"]), recorded)
    done = {(f.category, f.check) for f in recorded}
    if not any(k in done for k in (("speed_through_water", "gain"), ("rate_of_turn", "unit"))):
        rows = [{k: (None if math.isnan(v[i]) else float(v[i])) for k, v in c.items()}
                for i in range(len(c["t"]))]  # fmt: skip
        cols = dict(columns) or {"yaw_rate": "yaw_rate", "heading": "heading", "stw": "stw"}
        est = sc.estimate(rows, cols, sc.Calibration())
        rep.findings += [_not_applied(sc.on_table(f)) for f in est.findings]
        rep.notes.append("no estimates recorded in this file: estimated now, not applied")
    cal = _metadata(p, lambda n: n == "calibration").get("calibration") if is_mcap else None
    rep.findings += computed_findings(c, columns, recorded, cal)
    if is_mcap:
        rep.findings += checks.compass_offsets(sources_report(p))
    return rep


def is_mcap(path: str | Path) -> bool:
    try:
        with open(path, "rb") as f:
            return f.read(len(MCAP_MAGIC)) == MCAP_MAGIC
    except OSError:
        return False


def check_path(
    path: str | Path,
    calibration: Any = None,
    nmea_checksum: str = "strict",
    day: float | None = None,
) -> CheckReport:
    """``check``'s input: an MCAP log, a samples table, or a raw capture imported to a temporary log
    (``nmea_checksum``, ``day``: as `import --nmea-checksum` and `--date`)."""
    p = Path(path)
    if is_mcap(p) or p.suffix.lower() in (".csv", ".parquet", ".pq"):
        return check_table(p)
    from forcemap.host.convert.importers import ImportFailed, check_importable

    try:
        fmt = check_importable(p)
    except ImportFailed:
        return check_table(p)  # a table with another suffix: read_raw says what is wrong
    with tempfile.TemporaryDirectory(prefix="forcemap-check-") as tmp:
        out = Path(tmp) / (p.stem + ".mcap")
        try:
            res, _ = sc.import_calibrated(
                p, out, fmt, calibration, nmea_checksum=nmea_checksum, day=day
            )
        except ImportFailed as e:  # a log that gives no samples is graded, not refused
            why = QaFinding("time", "samples", "red", str(e), value=0.0,
                            fix="nothing to map from this log")  # fmt: skip
            return CheckReport(str(path), 0, [why], [f"not importable as {fmt}"])
        rep = check_table(out)
    rep.path = str(path)
    rep.notes.insert(0, f"imported as {res.format} ({res.records} records) to a temporary log")
    return rep


def _number(f: QaFinding) -> str:
    if math.isnan(f.value):
        return ""
    sd = "" if math.isnan(f.sd) else f" ± {f.sd:.3g}"
    return f"{f.value:.4g}{sd} {f.unit}".rstrip()


def text(rep: CheckReport) -> list[str]:
    """The report as lines: per category its verdict, then each finding with its number and fix."""
    out = [f"{rep.path}: {rep.rows} samples; overall {rep.verdict.upper()}"]
    out += [f"  note: {n}" for n in rep.notes]
    for cat, fs in rep.by_category().items():
        out.append(f"  {cat.replace('_', ' '):<22}{worst([f.verdict for f in fs]).upper()}")
        for f in fs:
            src = f" [{f.source}]" if f.source else ""
            out.append(f"    {f.verdict:<7}{f.check}{src}: {f.message}")
            if f.threshold or _number(f):
                out.append(f"           number: {_number(f) or '-'}; rule: {f.threshold or '-'}")
            if f.evidence:
                out.append(f"           evidence: {f.evidence}")
            if f.fix:
                out.append(f"           fix: {f.fix}")
    return out


def summary(findings: list[QaFinding]) -> list[str]:
    """The short form for `import`, `log info`, `fit` and the report: the verdict per category and
    every finding that is not green or was applied, in one line each."""
    if not findings:
        return []
    cats: dict[str, list[str]] = {}
    for f in findings:
        cats.setdefault(f.category, []).append(f.verdict)
    head = ", ".join(f"{c} {worst(v)}" for c, v in cats.items())
    out = [f"quality: {worst([f.verdict for f in findings]).upper()} ({head})"]
    for f in findings:
        if f.verdict != "green" or f.applied:
            fix = f"; {f.fix}" if f.fix else ""
            out.append(f"  {f.verdict}: {f.message}{fix}")
    return out


def to_json(rep: CheckReport) -> dict[str, Any]:
    """The report for machines: overall verdict, per category its verdict and findings."""

    def one(f: QaFinding) -> dict[str, Any]:
        d = asdict(f)
        d["name"] = f.name
        for k in ("value", "sd"):
            d[k] = None if math.isnan(d[k]) else d[k]
        return d

    return {
        "path": rep.path,
        "rows": rep.rows,
        "verdict": rep.verdict,
        "notes": rep.notes,
        "categories": {
            c: {"verdict": worst([f.verdict for f in fs]), "findings": [one(f) for f in fs]}
            for c, fs in rep.by_category().items()
        },
    }
