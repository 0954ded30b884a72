"""docs/GUIDE.md runs: its ```sh blocks, in order, in one shell, in a fresh folder; what it quotes is there.

The guide is a tutorial on a real log the tests ship (tests/data/real/nmea/bundg_zeus_9.log). Its
```sh blocks are the commands a reader types; they run here as one bash session (a `cd` carries on to
the next block), in a temporary folder laid out like a clone's root, with the installed `forcemap`. A
```text block right after a ```sh block quotes that block's output: every line it quotes must be there,
in order, with every number in it free to change (a line's words are the guide's claim, its numbers the
day's measurement) and ` ... ` standing for a part left out (at a line's end, the rest of it); a line `...` alone skips lines. Blocks of
other kinds (the install, a JSON excerpt) are not run.

Then the properties the guide's text explains are asserted on the files the commands wrote: the maps,
the report, the plan, and the diagnoses' JSON with the fields the guide reads (a finding, a null, and a
candidate confounded with position with the survey that would separate it).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "GUIDE.md"
LOG = Path("tests/data/real/nmea/bundg_zeus_9.log")  # the guide's log, relative to a clone's root
SENTINEL = "@@@ forcemap guide block {} @@@"
NUMBER = r"[-+]?(?:\d[\d,]*(?:\.\d+)?|\.\d+)(?:e[-+]?\d+)?"


def blocks() -> list[tuple[str, str]]:
    """The page's fenced blocks in order: (info string, body)."""
    text = DOC.read_text(encoding="utf-8")
    return [
        (m.group(1).strip(), m.group(2))
        for m in re.finditer(r"^```([^\n]*)\n(.*?)^```", text, re.M | re.S)
    ]


def commands_and_quotes() -> list[tuple[str, list[str]]]:
    """Each ```sh block with the ```text blocks that follow it (its quoted output)."""
    out: list[tuple[str, list[str]]] = []
    for kind, body in blocks():
        if kind == "sh":
            out.append((body, []))
        elif kind == "text" and out:
            out[-1][1].append(body)
    return out


def line_pattern(line: str) -> re.Pattern:
    """A quoted line as a pattern: its words literal, its numbers any number, ` ... ` anything, runs of
    spaces any run of spaces (tables are aligned by the day's numbers)."""
    parts = []
    line = line.strip()
    line = line[: -len(" ...")] if line.endswith(" ...") else line  # a line cut at its end
    for i, chunk in enumerate(line.split(" ... ")):
        if i:
            parts.append(".*")
        pieces = re.split(f"({NUMBER})", chunk)
        for j, piece in enumerate(pieces):
            if j % 2:
                parts.append(NUMBER)
            else:
                parts.append(r"\s+".join(re.escape(w) for w in re.split(r"\s+", piece)))
    return re.compile("".join(parts))


def missing_quotes(quote: str, output: str) -> list[str]:
    """The quoted lines not found in the output, in order (each after the one before it)."""
    lines = output.splitlines()
    at, missing = 0, []
    for q in quote.splitlines():
        if not q.strip() or q.strip() == "...":
            continue
        pat = line_pattern(q)
        for k in range(at, len(lines)):
            if pat.search(lines[k]):
                at = k + 1
                break
        else:
            missing.append(q)
    return missing


def run_guide(folder: Path) -> list[str]:
    """Every ```sh block in one bash session in ``folder``; the output of each block."""
    steps = commands_and_quotes()
    (folder / LOG).parent.mkdir(parents=True)
    shutil.copy2(ROOT / LOG, folder / LOG)
    script = ["set -eo pipefail"]
    for i, (body, _) in enumerate(steps):
        script += [f"echo '{SENTINEL.format(i)}'", body]
    env = {
        **os.environ,
        "PATH": str(Path(sys.executable).parent) + os.pathsep + os.environ.get("PATH", ""),
        "PYTHONUNBUFFERED": "1",
        "MPLBACKEND": "Agg",
        "COLUMNS": "100",
    }
    res = subprocess.run(
        ["bash", "-c", "\n".join(script)],
        cwd=folder,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        timeout=900,
    )
    assert res.returncode == 0, res.stdout[-4000:]
    parts = re.split(r"^@@@ forcemap guide block (\d+) @@@\n", res.stdout, flags=re.M)
    outputs = [""] * len(steps)
    for i in range(1, len(parts), 2):
        outputs[int(parts[i])] = parts[i + 1]
    return outputs


def test_the_guide_walks_the_whole_story():
    """From the shipped log to a plan, every command the issue names, and the three shapes of a diagnosis."""
    code = "\n".join(body for body, _ in commands_and_quotes())
    for command in ("import", "check", "export", "fit", "diagnose", "grid", "report", "plan"):
        assert re.search(rf"^forcemap {command} ", code, re.M), command
    assert str(LOG) in code and (ROOT / LOG).exists()
    text = DOC.read_text(encoding="utf-8")
    for heading in (
        "## Reading a diagnosis",
        "### A finding",
        "### A null",
        "### Cannot tell: do this",
    ):
        assert heading in text
    assert "[gis]" in text  # grid needs the extra, and the guide says so
    # every quoted block quotes something, with a pattern that compiles and matches itself
    for _, quotes in commands_and_quotes():
        for quote in quotes:
            assert not missing_quotes(quote, quote), quote


def test_a_quoted_line_keeps_its_words_and_frees_its_numbers():
    out = "  yellow: speed log gain 0.688 ± 0.097 (reads 45.4 % high)\nrank  covariate   cv_rmse\n"
    assert not missing_quotes("yellow: speed log gain 0.7 ± 0.1 (reads 12 % high)", out)
    assert not missing_quotes("rank covariate cv_rmse", out)
    assert not missing_quotes("yellow: speed log ... high)", out)
    assert not missing_quotes("yellow: speed log gain ...", out)
    assert missing_quotes("yellow: compass gain 0.688", out)
    assert missing_quotes(
        "rank covariate cv_rmse\nyellow: speed log gain 1 ± 1", out
    )  # order counts


@pytest.mark.slow
def test_every_command_of_the_guide_runs_and_says_what_the_guide_quotes(tmp_path):
    outputs = run_guide(tmp_path)
    for (body, quotes), output in zip(commands_and_quotes(), outputs, strict=True):
        for quote in quotes:
            missing = missing_quotes(quote, output)
            assert not missing, (
                f"$ {body.strip()}\nnot in its output:\n"
                + "\n".join(missing)
                + ("\n--- output ---\n" + output[-3000:])
            )
    work = tmp_path / "guide"
    # the files the guide says each command writes
    for name in (
        "zeus.mcap",
        "zeus.csv",
        "zeus.csv.forcemap/history.json",
        "zeus.csv.forcemap/diagnosis-wind_speed.json",
        "maps/current_speed.tif",
        "maps/wind_speed.tif",
        "maps/depth.tif",
        "maps/maps.nc",
        "maps/depth-contours.geojson",
        "zeus.html",
        "planned.waypoints",
        "planned.toml",
        "planned.json",
    ):
        assert (work / name).is_file(), name
    assert "data:image/png;base64," in (work / "zeus.html").read_text()

    # a null: the current's diagnosis finds nothing, in one round, and says which candidate came closest
    current = json.loads((work / "current.json").read_text())
    assert current["missing_effect_found"] is False and len(current["rounds"]) == 1
    assert current["rounds"][0]["added"] is None
    # a finding, then "cannot tell": the wind's first round names a term with its gain, the second
    # round's best candidate is confounded with position and the advice names the survey to run
    wind = json.loads((work / "wind.json").read_text())
    first, second = wind["rounds"][0], wind["rounds"][1]
    assert wind["missing_effect_found"] is True and first["missing_effect_found"] is True
    best = wind["candidates"][0]
    assert best["identifiable"] is True and best["improvement"] >= 0.10
    assert first["added"] == f"gp({best['covariate']}, matern32)"
    assert first["cv_rmse_after"] < wind["baseline"]["cv_rmse"]
    assert max(best["null_gains"]) < best["improvement"]
    assert second["missing_effect_found"] is False and second["added"] is None
    confounded = second["candidates"][0]
    assert confounded["identifiable"] is False and "position" in confounded["confounded_with"]
    assert "one pass" in second["advice"] and "repeat the line later" in second["advice"]
    assert wind["advice"] is None  # the top level is the first round's, which found something
    # the plan keeps the intended lines beside the waypoints it writes
    planned = json.loads((work / "planned.json").read_text())
    assert len(planned["lines"]) == 2 and len(planned["plan"]["original"]["lines"]) == 2
