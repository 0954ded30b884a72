"""Existing logs through the live pipeline: NMEA 0183 captures, MAVLink telemetry logs (tlog) and
ArduPilot DataFlash logs (.BIN).

NMEA captures carry no receive times. Each line gets one from the sentences' own UTC: every line
where the UTC time of day (RMC, GGA, GLL, ZDA) moves forward is an anchor, and lines between
anchors are spread evenly; the date comes from the RMC and ZDA of valid fixes, the day most of them
give (a date without a fix never dates a log, and what was overruled is said: nmea_prepass), else
from `--date` (else 1970-01-01, and the import says what that day gets wrong).
A capture with no UTC at all is paced at 1 s per line. tlogs carry the ground station's receive
time (8-byte big-endian UNIX microseconds) before each packet, used as the arrival time. DataFlash
logs are read by ``forcemap.host.convert.dataflash``. A gzipped NMEA capture or tlog is read as the
file it holds (``forcemap.host.convert.capture_file``).

An import that gives no samples says why in one line (no position, no time, no measurements), and
``import_to_mcap`` then leaves no file behind.
"""

from __future__ import annotations

import json
import struct
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from forcemap.host.convert.adcp_read import is_pd0
from forcemap.host.convert.capture_file import (
    ImportFailed,
    capture_bytes,
    capture_head,
    plain_file_format,
    sentence_offset,
)
from forcemap.host.convert.dataflash import DataflashDecoder
from forcemap.host.convert.nav_findings import Collector
from forcemap.host.convert.nmea_prepass import (  # noqa: F401 - nmea_line_times: part of this API
    finding_notes,
    nmea_line_times,
    prepass,
    why_no_time,
)
from forcemap.host.fuse.calibration import Calibration
from forcemap.host.fuse.pipeline import Pipeline, Sink
from forcemap.host.log.mcap import McapLog
from forcemap.host.outputs import atomic_path

FORMATS = ("nmea", "tlog", "dataflash", "adcp")  # adcp: forcemap.host.convert.adcp_import
DATAFLASH_MAGIC = b"\xa3\x95"
MAX_TLOG_US = (1 << 63) // 1000  # the latest time an MCAP log can hold (year 2262)
# a DataFlash log starts with its FMT records: the magic, then message type 128 (FMT), 89 bytes each
DATAFLASH_FMT = DATAFLASH_MAGIC + b"\x80"
DATAFLASH_FMT_LEN = 89
IMPORT_DIAG_PERIOD_S = 10.0  # /diagnostics every 10 s of log time (the daemon: every second)


@dataclass
class ImportResult:
    """What an import did: the pipeline's counters and the number of records read."""

    path: str
    format: str
    records: int = 0
    counters: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)


def is_dataflash(head: bytes) -> bool:
    """True when ``head`` (the first bytes of a file) is the start of a DataFlash log: FMT records."""
    if not head.startswith(DATAFLASH_FMT):
        return False
    nxt = head[DATAFLASH_FMT_LEN : DATAFLASH_FMT_LEN + len(DATAFLASH_MAGIC)]
    return len(head) < DATAFLASH_FMT_LEN + 2 or nxt == DATAFLASH_MAGIC


def detect_format(path: str | Path) -> str:
    """``nmea``, ``tlog``, ``dataflash`` or ``adcp`` from the name and the first bytes; else ImportFailed."""
    p = Path(path)
    try:
        head = capture_head(p)
    except OSError as e:
        raise ImportFailed(f"{p}: cannot read: {e.strerror or e}") from None
    if is_dataflash(head):
        return plain_file_format(p, "dataflash")
    if is_pd0(head):
        return plain_file_format(p, "adcp")
    if p.suffix.lower() == ".tlog" or p.name.lower().endswith(".tlog.gz"):
        return "tlog"
    if len(head) > 8 and head[8] in (0xFD, 0xFE):
        return "tlog"
    lines = [ln.strip() for ln in head.splitlines()]
    if sum(sentence_offset(ln) >= 0 for ln in lines) >= max(1, len(lines) // 10):
        return "nmea"
    raise ImportFailed(
        f"{p.name}: not a format forcemap recognises (NMEA 0183 text, a MAVLink tlog or an "
        "ArduPilot .BIN log, a TRDI PD0 ADCP file); if it is one of them, give "
        "--from nmea|tlog|dataflash|adcp"
    )


def check_importable(path: str | Path, fmt: str | None = None) -> str:
    """The format to import ``path`` with: ``fmt`` if given, else detected."""
    if fmt is None:
        return detect_format(path)
    if fmt not in FORMATS:
        raise ImportFailed(f"unknown format {fmt!r}: expected one of {FORMATS}")
    try:
        return fmt if fmt in ("nmea", "tlog") else plain_file_format(Path(path), fmt)
    except OSError as e:
        raise ImportFailed(f"{path}: cannot read: {e.strerror or e}") from None


def _pipeline(
    path: str | Path,
    fmt: str,
    timing: str,
    sink: Sink,
    calibration: Calibration | None,
    sync: str | None,
    sample_rate_hz: float | None,
    nmea_checksum: str = "strict",
) -> Pipeline:
    """The live pipeline for an import, with the file, its format and its timing in the metadata."""
    config = {"import": str(path), "format": fmt, "timing": timing}
    if fmt == "nmea":
        config["nmea_checksum"] = nmea_checksum
    return Pipeline(
        calibration,
        sink,
        sync=sync,
        sample_rate_hz=sample_rate_hz,
        config=config,
        diagnostics_period_s=IMPORT_DIAG_PERIOD_S,
        nmea_checksum=nmea_checksum,
    )


def import_nmea(
    path: str | Path,
    sink: Sink,
    calibration: Calibration | None = None,
    sync: str | None = None,
    sample_rate_hz: float | None = None,
    nmea_checksum: str = "strict",
    day: float | None = None,
) -> ImportResult:
    """An NMEA 0183 capture through the pipeline's NMEA path (``nmea_checksum``: strict or
    lenient, forcemap.host.decode.nmea_checksum; ``day``: the UTC midnight a log without a date
    starts on, `import --date`)."""
    pre = prepass(path, nmea_checksum, day)
    if not pre.has_time:
        raise ImportFailed(why_no_time(pre.lines, Path(path).name, nmea_checksum))
    pipe = _pipeline(path, "nmea", pre.how, sink, calibration, sync, sample_rate_hz, nmea_checksum)
    if pre.seed is not None:
        pipe.nmea.jumps.seed(*pre.seed)
    for line, t in zip(pre.lines, pre.times, strict=True):
        ns = int(t * 1e9)
        pipe.feed("nmea", ns, ns, line + b"\n")
    pipe.close()
    if pre.day_finding is not None:  # what the log's day overruled (its line is in pre.how)
        sink.metadata(pre.day_finding.name, pre.day_finding.to_metadata())
    res = ImportResult(str(path), "nmea", len(pre.lines), pipe.counters(), [*pre.notes, pre.how])
    _check_errors(pipe, res)
    return res


def import_dataflash(
    path: str | Path,
    sink: Sink,
    calibration: Calibration | None = None,
    sync: str | None = None,
    sample_rate_hz: float | None = None,
) -> ImportResult:
    """An ArduPilot DataFlash log (.BIN) through the sample assembler (forcemap.host.convert.dataflash)."""
    pipe = _pipeline(
        path, "dataflash", "the log's own clock", sink, calibration, sync, sample_rate_hz
    )
    reader = DataflashDecoder(pipe, pipe.mav)
    try:
        reader.read(str(path))
    except Exception as e:  # DFReader on a file that is not DataFlash
        raise ImportFailed(f"{Path(path).name}: not a readable DataFlash log ({e})") from None
    pipe.close()
    used = ", ".join(f"{k} {n}" for k, n in sorted(reader.used.items())) or "none"
    res = ImportResult(str(path), "dataflash", reader.records, pipe.counters())
    res.notes.append(f"DataFlash records used: {used}")
    _check_errors(pipe, res)
    return res


def tlog_records(data: bytes) -> Iterator[tuple[int, bytes]]:
    """(UNIX µs, packet bytes) for each record of a tlog. Bytes that don't frame are skipped."""
    i, n = 0, len(data)
    while i + 9 <= n:
        magic = data[i + 8]
        if magic == 0xFE:
            size = data[i + 9] + 8 if i + 9 < n else 0
        elif magic == 0xFD and i + 10 < n:
            size = data[i + 9] + 12 + (13 if data[i + 10] & 0x01 else 0)
        else:
            i += 1
            continue
        (us,) = struct.unpack_from(">Q", data, i)
        if us > MAX_TLOG_US:  # not a time: these bytes do not frame a record
            i += 1
            continue
        yield us, data[i + 8 : i + 8 + size]
        i += 8 + size


def import_tlog(
    path: str | Path,
    sink: Sink,
    calibration: Calibration | None = None,
    sync: str | None = None,
    sample_rate_hz: float | None = None,
) -> ImportResult:
    """A MAVLink telemetry log through the pipeline's MAVLink path, at its recorded arrival times."""
    notes: list[str] = []
    data = capture_bytes(path, notes)
    pipe = _pipeline(path, "tlog", "tlog receive times", sink, calibration, sync, sample_rate_hz)
    records = 0
    for us, packet in tlog_records(data):
        records += 1
        ns = us * 1000
        pipe.feed("mavlink", ns, ns, packet)
    pipe.close()
    res = ImportResult(str(path), "tlog", records, pipe.counters(), notes)
    _check_errors(pipe, res)
    return res


def source_notes(report: dict[str, str]) -> list[str]:
    """One line per quantity with several sources: the one used, and each other one's latency."""
    out = []
    for q, text in report.items():
        d = json.loads(text)
        others = [(n, r) for n, r in d["sources"].items() if n != d["chosen"]]
        if not others:
            continue
        late = [
            f"{n} (latency {r['latency_s']:+.2f} s)" if r.get("latency_s") is not None else n
            for n, r in others
        ]
        out.append(f"{q}: used {d['chosen']} ({d['why']}); also {', '.join(late)}")
    return out


def _check_errors(pipe: Pipeline, res: ImportResult) -> None:
    res.notes.extend(source_notes(pipe.sources_report))
    res.notes.extend(finding_notes(pipe.findings))
    if pipe.errors:
        res.notes.append(
            f"internal errors: {dict(pipe.errors)}; last: {pipe.last_error.strip().splitlines()[-1]}"
        )


def import_file(
    path: str | Path,
    sink: Sink,
    fmt: str | None = None,
    calibration: Calibration | None = None,
    sync: str | None = None,
    sample_rate_hz: float | None = None,
    nmea_checksum: str = "strict",
    day: float | None = None,
) -> ImportResult:
    """Import one file in the given or detected format (``day``: for an NMEA log without a date)."""
    fmt = check_importable(path, fmt)
    if fmt == "nmea":
        return import_nmea(path, sink, calibration, sync, sample_rate_hz, nmea_checksum, day)
    readers = {"tlog": import_tlog, "dataflash": import_dataflash}
    if fmt in readers:
        return readers[fmt](path, sink, calibration, sync, sample_rate_hz)
    raise ImportFailed(f"unknown format {fmt!r}: expected one of {FORMATS}")


def _navigation_findings(tee: Collector, cal: Calibration | None, res: ImportResult) -> None:
    """Each navigation source's latency, noise, bias and outliers into the log (qa.* metadata);
    the ones that are not green in the import's notes (issue 29, docs/NAVIGATION.md)."""
    keep = cal is not None and cal.latency == "keep"
    for f in tee.write_findings(remove_latency=not keep):
        if f.verdict != "green":
            res.notes.append(f"navigation: {f.message}")


def why_no_samples(res: ImportResult) -> str:
    """One line on why an import gave no samples ('' if it gave some)."""
    c = res.counters
    if c["samples"]["emitted"]:
        return ""
    name = Path(res.path).name
    if not c.get("last_fix"):
        return f"{name}: no position in this log (no GPS fix), so no samples"
    return (
        f"{name}: no measurements in this log (no wind, depth, speed through water or water "
        "temperature), so no samples"
    )


def import_to_mcap(
    path: str | Path,
    out: str | Path,
    fmt: str | None = None,
    calibration: Calibration | None = None,
    sync: str | None = None,
    check: Callable[[ImportResult], None] | None = None,
    sample_rate_hz: float | None = None,
    nmea_checksum: str = "strict",
    metadata: dict[str, dict[str, str]] | None = None,
    day: float | None = None,
) -> ImportResult:
    """Import ``path`` into the MCAP file ``out``, which appears whole or not at all.

    ImportFailed (and no file) when the log cannot give samples; the message says why. ``check``
    may refuse the result first (by raising), with the same effect. ``metadata``: more records to
    write (the ``qa.*`` findings of forcemap.host.convert.self_calibration).
    """
    fmt = check_importable(path, fmt)
    with atomic_path(out) as tmp:
        log = McapLog(
            Path(tmp).parent, first_path=tmp, rotate_bytes=1 << 62, rotate_seconds=float("inf")
        )
        try:
            tee = Collector(log)
            res = import_file(
                path, tee, fmt, calibration, sync, sample_rate_hz, nmea_checksum, day
            )
            _navigation_findings(tee, calibration, res)
            for name, data in (metadata or {}).items():
                log.metadata(name, data)
        finally:
            log.close()
        if check is not None:
            check(res)
        reason = why_no_samples(res)
        if reason:
            raise ImportFailed(reason)
    return res
