"""Real logs imported and exported once per test run, shared by every test module that asks.

A case is a real NMEA log of tests/data/real as recorded (named by its path there), or one with a known
effect injected (bench/inject_cases.py: ``geneva_seiche``, ``lake_drift``, ``fjord_tide``, ``fjord_seiche``,
``fjord_level``, ``plaka_level``). Building one runs what a user runs: ``bench/inject_nmea.py`` (injected
cases), ``forcemap import`` (calibrated) and ``forcemap export`` to CSV; ``uncalibrated()`` adds, on demand,
the pipeline's rows as the instruments read them (``import_to_mcap`` with no calibration).

The sfbay log takes about 100 s of CPU to import, a 4-hour race 35 s: each is built once per run,
also under ``pytest -n 2``, where each worker is its own session. The cases then live in a folder
both workers share (the parent of the workers' temporary folders), and a case is built by the first
worker that asks, under an exclusive ``flock`` on its lock file, into a temporary folder renamed
into place when whole (tests/cache.py's ``build_once``); the other worker waits for it and reads it.
A folder belongs to one test run (each run has its own base temporary folder), so a changed pipeline
never reads an old build.
"""

from __future__ import annotations

import contextlib
import io
import json
from collections import Counter
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

from forcemap.host.cli import main

from bench.inject_cases import Case, case
from tests.cache import build_once as _once
from tests.cache import run_dir
from tests.tools import real_data

FOLDER = "forcemap-real-cases"


def shared_root(tmp_path_factory) -> Path:  # type: ignore[no-untyped-def]
    """Where this run's cases live: beside the xdist workers' folders, else in the run's own."""
    root = run_dir(tmp_path_factory) / FOLDER
    root.mkdir(exist_ok=True)
    return root


def topic_counts(mcap: Path) -> Counter[str]:
    """Messages per topic of a complete MCAP log, from its summary."""
    from mcap.reader import make_reader

    with open(mcap, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None and summary.statistics is not None, mcap
    counts: Counter[str] = Counter()
    for cid, n in summary.statistics.channel_message_counts.items():
        counts[summary.channels[cid].topic] += n
    return counts


def _cli(argv: list[str]) -> tuple[int, str]:
    """A forcemap command run in this process: its exit code and what it printed."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        rc = main(argv)
    return rc, out.getvalue()


@dataclass(frozen=True)
class Built:
    """One case's files: the capture imported, its MCAP log and samples table, the import's
    summary, and the truth of an injected case."""

    name: str
    case: Case
    folder: Path

    @cached_property
    def record(self) -> dict:
        return json.loads((self.folder / "built.json").read_text())

    @property
    def capture(self) -> Path:
        """The capture imported: the repository's log, or the injected one in the case's folder."""
        return (
            self.folder / self.record["capture"]
            if self.case.effect
            else real_data() / self.case.source
        )

    @property
    def mcap(self) -> Path:
        return self.folder / "log.mcap"

    @property
    def csv(self) -> Path:
        return self.folder / "log.csv"

    @property
    def truth(self) -> Path | None:
        return self.folder / "log.truth.csv" if self.case.effect else None

    @property
    def import_rc(self) -> int:
        return self.record["import_rc"]

    @property
    def import_text(self) -> str:
        return self.record["import_text"]

    def check(self) -> dict:
        """``forcemap check`` of the case's MCAP log (its JSON report), once per run."""

        def build(tmp: Path) -> None:
            rc, text = _cli(["check", str(self.mcap), "--json", str(tmp / "check.json")])
            assert rc == 0, text

        folder = _once(self.folder.with_name(self.folder.name + ".check"), build)
        return json.loads((folder / "check.json").read_text())

    def uncalibrated(self) -> Path:
        """The same capture imported without calibration (the instruments as read)."""
        from forcemap.host.convert.importers import import_to_mcap

        def build(tmp: Path) -> None:
            import_to_mcap(self.capture, tmp / "log.mcap", nmea_checksum=self.case.checksum)

        return _once(self.folder.with_name(self.folder.name + ".uncalibrated"), build) / "log.mcap"


def _build(name: str, c: Case, tmp: Path) -> None:
    capture = real_data() / c.source
    if c.effect is not None:
        from bench.inject_nmea import inject

        injected = tmp / ("log.nmea" + (".gz" if capture.name.endswith(".gz") else ""))
        inject(capture, injected, c.effect, tmp / "log.truth.csv")
        capture = injected
    checksum = ["--nmea-checksum", c.checksum]
    rc, text = _cli(["import", str(capture), "-o", str(tmp / "log.mcap"), *checksum])
    if rc == 0:
        erc, etext = _cli(["export", str(tmp / "log.mcap"), "-o", str(tmp / "log.csv")])
        assert erc == 0, etext
    record = {"name": name, "capture": capture.name, "import_rc": rc, "import_text": text}
    (tmp / "built.json").write_text(json.dumps(record))


class Cases:
    """``cases(name)``: a case built once for the whole run (see the module docstring)."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self._built: dict[str, Built] = {}

    def __call__(self, name: str) -> Built:
        if name not in self._built:
            c = case(name)
            folder = self.root / name.replace("/", "_").replace(".", "_")
            _once(folder, lambda tmp: _build(name, c, tmp))
            self._built[name] = Built(name, c, folder)
        return self._built[name]
