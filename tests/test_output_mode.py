"""Output files honour the umask, as every other tool's do (0644 under the usual 022), although each is
written to a temporary file first and renamed (issue 20, item 9: they were 0600, mkstemp's mode)."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest
from forcemap.host.cli import main
from forcemap.host.outputs import atomic_path, atomic_write

from bench.synth_survey import make_survey
from tests.test_io_bad_input import nmea_capture


@pytest.fixture
def umask():
    """Set the process's umask for one test, and put the old one back."""
    old = os.umask(0o022)
    try:
        yield os.umask
    finally:
        os.umask(old)


def mode(path: Path) -> int:
    return stat.S_IMODE(path.stat().st_mode)


@pytest.mark.parametrize(
    "mask, expected", [(0o022, 0o644), (0o027, 0o640), (0o077, 0o600), (0o002, 0o664)]
)
def test_atomic_writes_take_the_umask(tmp_path, umask, mask, expected):
    umask(mask)
    with atomic_write(tmp_path / "a.json") as f:
        f.write("{}\n")
    with atomic_path(tmp_path / "b.parquet") as tmp:
        tmp.write_bytes(b"PAR1")
    assert mode(tmp_path / "a.json") == expected and mode(tmp_path / "b.parquet") == expected
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "a.json",
        "b.parquet",
    ]  # no temporary left


def test_the_commands_outputs_are_0644_under_umask_022(tmp_path, umask, capsys):
    umask(0o022)
    capture = nmea_capture(tmp_path / "capture.txt")
    log = tmp_path / "capture.mcap"
    assert main(["import", str(capture), "-o", str(log)]) == 0
    assert main(["export", str(log), "-o", str(tmp_path / "survey.csv")]) == 0
    assert main(["export", str(log), "-o", str(tmp_path / "survey.parquet")]) == 0
    assert main(["log", "info", str(log), "--json", str(tmp_path / "info.json")]) == 0
    table = make_survey("river", ["depth_current"], 5, 300.0, tmp_path / "river")
    fit = tmp_path / "fit.json"
    assert main(["fit", str(table), "--target", "depth", "--quiet", "--json", str(fit)]) == 0
    report = tmp_path / "report.html"
    assert main(["report", str(table), "--quiet", "-o", str(report)]) == 0
    written = [
        log,
        tmp_path / "survey.csv",
        tmp_path / "survey.parquet",
        tmp_path / "info.json",
        fit,
        report,
    ]
    assert {p.name: oct(mode(p)) for p in written} == {p.name: oct(0o644) for p in written}
    # the workspace's own report and plots, too
    assert main(["report", str(table), "--quiet"]) == 0
    ws = Path(f"{table}.forcemap")
    assert mode(ws / "report.html") == 0o644
    assert all(mode(p) == 0o644 for p in ws.rglob("*.png"))
    assert all(mode(p) == 0o644 for p in ws.rglob("*.json"))
