"""The real logs of tests/data/real, imported once per test run and shared by every module that reads
them (tests/cache.py: one build for all xdist workers).

- `imported(factory, log, *options)`: ``forcemap import LOG -o log.mcap [options]`` as a user runs it
  (the log's own calibration applied), with its exit code, stdout and stderr; the MCAP when it made one.
- `exported(...)`: that import's ``forcemap export`` to a CSV samples table.
- `raw_import(factory, log, nmea_checksum)`: ``import_to_mcap`` without calibration (the navigation
  tests' view of a log), its MCAP.

A test reads what it is given and writes nothing into it: the folders are shared.
"""

from __future__ import annotations

import contextlib
import io
import json
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.cache import shared_dir
from tests.tools import real_data


@dataclass(frozen=True)
class Imported:
    """One ``forcemap import`` of a real log."""

    log: str  # the path under tests/data/real
    rc: int
    out: str  # its stdout
    err: str  # its stderr
    mcap: Path | None  # None when the import refused the log

    def topic_counts(self) -> Counter[str]:
        """Messages per topic in the MCAP, counted from its records (no payload decoded)."""
        from forcemap.host.log.mcap import FileScan, iter_records
        from mcap.records import Message

        assert self.mcap is not None, f"{self.log} did not import: {self.err}"
        scan = FileScan(self.mcap)
        counts: Counter[int] = Counter(
            r.channel_id for r in iter_records(self.mcap, scan) if isinstance(r, Message)
        )
        return Counter({scan.channels[c].topic: n for c, n in counts.items()})


def _key(*parts: str) -> str:
    return "-".join(p.replace("/", "_").lstrip("-") for p in parts if p)


def _cli(argv: list[str]) -> tuple[int, str, str]:
    """``forcemap ARGV`` in this process: exit code, stdout, stderr."""
    from forcemap.host.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main(argv)
    return rc, out.getvalue(), err.getvalue()


def imported(factory: pytest.TempPathFactory, log: str, *options: str) -> Imported:
    """``forcemap import`` of ``tests/data/real/<log>`` with ``options``, once per test run."""

    def build(folder: Path) -> None:
        rc, out, err = _cli(["import", str(real_data() / log), "-o", str(folder / "log.mcap"), *options])  # fmt: skip
        (folder / "result.json").write_text(json.dumps({"rc": rc, "out": out, "err": err}))

    folder = shared_dir(factory, _key("import", log, *options), build)
    r = json.loads((folder / "result.json").read_text())
    mcap = folder / "log.mcap"
    return Imported(log, r["rc"], r["out"], r["err"], mcap if mcap.is_file() else None)


def exported(factory: pytest.TempPathFactory, log: str, *options: str) -> Path:
    """The CSV ``forcemap export`` makes of `imported`'s MCAP, once per test run."""
    imp = imported(factory, log, *options)
    assert imp.mcap is not None, f"{log} did not import: {imp.err}"

    def build(folder: Path) -> None:
        rc, _, err = _cli(["export", str(imp.mcap), "-o", str(folder / "samples.csv")])
        assert rc == 0, err

    return shared_dir(factory, _key("export", log, *options), build) / "samples.csv"


def raw_import(factory: pytest.TempPathFactory, log: str, nmea_checksum: str = "strict") -> Path:
    """``import_to_mcap(log, nmea_checksum=...)``: the log as read, no calibration; its MCAP."""
    from forcemap.host.convert.importers import import_to_mcap

    def build(folder: Path) -> None:
        import_to_mcap(real_data() / log, folder / "log.mcap", nmea_checksum=nmea_checksum)

    return shared_dir(factory, _key("raw", log, nmea_checksum), build) / "log.mcap"
