"""A truncated MCAP is read up to its last complete chunk, and `export`, `fit` and `season` say so in one
line: how many samples were read, and that `forcemap log recover` exists (issue 33). The log is cut to
its first half, as a user's killed or half-copied file is."""

from __future__ import annotations

import csv

import pytest
from forcemap.host.cli import main

from bench.live_client import survey_log


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    d = tmp_path_factory.mktemp("truncated")
    path, n = survey_log(d / "log", duration_s=1200, seed=3)
    data = path.read_bytes()
    cut = d / "cut.mcap"
    cut.write_bytes(data[: len(data) // 2])
    return path, cut, n


def _notes(err: str) -> list[str]:
    return [line for line in err.splitlines() if line.startswith("note:") and "truncated" in line]


def test_export_of_a_truncated_log_says_how_much_it_read(logs, tmp_path, capsys):
    full, cut, n = logs
    assert main(["export", str(full), "-o", str(tmp_path / "full.csv")]) == 0
    assert _notes(capsys.readouterr().err) == []  # a complete log: no word
    out = tmp_path / "cut.csv"
    assert main(["export", str(cut), "-o", str(out)]) == 0
    err = capsys.readouterr().err
    [note] = _notes(err)
    rows = list(csv.DictReader(out.open()))
    assert 0 < len(rows) < n  # the first half, not all of it and not nothing
    assert f"read {len(rows):,} samples" in note
    assert f"forcemap log recover {cut}" in note
    # the span it names is the rows' own: minutes between the first and last sample written
    minutes = (float(rows[-1]["t"]) - float(rows[0]["t"])) / 60
    assert f"({minutes:.1f} min of survey" in note
    # and a track export of the same file says the same
    assert main(["export", str(cut), "-o", str(tmp_path / "cut.geojson")]) == 0
    assert _notes(capsys.readouterr().err) == [note]


@pytest.mark.slow
def test_fit_and_season_on_a_truncated_log_say_so(logs, tmp_path, capsys):
    _, cut, _ = logs
    local = tmp_path / "cut.mcap"
    local.write_bytes(cut.read_bytes())
    assert main(["fit", str(local), "--target", "depth", "--no-plots", "--quiet"]) == 0
    [note] = _notes(capsys.readouterr().err)
    assert "samples" in note and "forcemap log recover" in note
    assert main(["season", str(local), "-o", str(tmp_path / "season"), "--no-cv", "--quiet"]) == 0
    [again] = _notes(capsys.readouterr().err)
    assert again == note
