"""bench/results.py: one command rewrites each benchmark's section of bench/RESULTS.md, and nothing else.

The mechanics are tested on a page of its own with tiny commands (seconds, no benchmark runs): a section's
text is replaced between its markers only, with the command, the commit and the CPU; the figures it
replaces go to the archive; the index follows; a failing command, an unknown name or a missing marker
leave the page as it was. Then the real page: every benchmark of the table has its section and the page
no other, the index is current, every command names a script that exists, and every section of the page
that docs, tests and code cite by its title ("bench/RESULTS.md, "The period's sd"") is still there, on
the page or in its archive.
"""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

from bench import results
from bench.results import BENCHES, Bench

ROOT = Path(__file__).resolve().parents[1]

PAGE = """# Results

Written by hand: kept.

<!-- bench-index -->
<!-- /bench-index -->

## A tiny table

Hand-written text before the markers.

<!-- bench:tiny -->
Recorded by hand at `abc1234` (2026-01-01): the old figure, the-old-figure-marker.
<!-- /bench:tiny -->

Hand-written text after the markers.

## Plain text

<!-- bench:texty -->
<!-- /bench:texty -->

## From a file

<!-- bench:fromfile -->
<!-- /bench:fromfile -->

## Fails

<!-- bench:fails -->
untouched
<!-- /bench:fails -->
"""

FAKE = (
    Bench("tiny", "python -c \"print('| a | b |'); print('|---|---|'); print('| 1 | 2 |')\"", 0.01,
          "a tiny table", markdown=True),
    Bench("texty", "python -c \"print('plain words')\"", 0.01, "plain text"),
    Bench("fromfile", "python -c \"open('{tmp}/out.txt', 'w').write('x\\ny\\nz')\"", 0.01,
          "the last two lines of a file", output="{tmp}/out.txt", tail=2),
    Bench("fails", "python -c \"import sys; sys.exit(3)\"", 0.01, "a command that fails"),
)  # fmt: skip


@pytest.fixture
def page(tmp_path):
    p = tmp_path / "RESULTS.md"
    p.write_text(PAGE)
    (tmp_path / "ARCHIVE.md").write_text("# Archive\n")
    return p


def run(page: Path, *argv: str) -> int:
    return results.main(list(argv), FAKE, page, ROOT, page.with_name("ARCHIVE.md"))


def outside(text: str) -> str:
    """The page with every generated part taken out."""
    text = re.sub(r"(<!-- bench:[\w-]+ -->).*?(<!-- /bench:)", r"\1\2", text, flags=re.S)
    return re.sub(r"(<!-- bench-index -->).*?(<!-- /bench-index -->)", r"\1\2", text, flags=re.S)


def test_a_run_rewrites_its_section_and_nothing_else(page):
    assert run(page, "tiny") == 0
    text = page.read_text()
    assert outside(text) == outside(PAGE)  # every hand-written byte kept
    i, j = results.section_span(text, "tiny")
    body = text[i:j]
    assert "| 1 | 2 |" in body and "the-old-figure-marker" not in body
    assert re.search(r"Measured at `[^`]+`, \d{4}-\d\d-\d\d \d\d:\d\d UTC", body)
    assert FAKE[0].command in body and "s of CPU" in body
    # the figures it replaced are in the archive, with the benchmark's name
    archive = page.with_name("ARCHIVE.md").read_text()
    assert "### `tiny`, replaced" in archive and "the old figure, the-old-figure-marker." in archive
    # the index names every benchmark, its section's anchor and when it was measured
    index = text[text.index("<!-- bench-index -->") : text.index("<!-- /bench-index -->")]
    assert "[`tiny`](#a-tiny-table)" in index and "[`fails`](#fails)" in index
    assert re.search(r"\| `[0-9a-f]{4,}[^`]*`, \d{4}-\d\d-\d\d \|", index.splitlines()[3])
    assert "| not yet |" in index  # texty, never run


def test_text_is_quoted_and_a_file_can_be_the_output(page):
    assert run(page, "texty", "fromfile") == 0
    text = page.read_text()
    i, j = results.section_span(text, "texty")
    assert "```text\nplain words\n```" in text[i:j]
    i, j = results.section_span(text, "fromfile")
    assert "y\nz" in text[i:j] and "x\n" not in text[i:j]


def test_a_failing_benchmark_leaves_its_section_and_says_so(page, capsys):
    assert run(page, "fails", "texty") == 1
    text = page.read_text()
    assert "untouched" in text and "plain words" in text  # the other ran
    assert "fails failed" in capsys.readouterr().err


def test_unknown_names_and_missing_markers_change_nothing(page, tmp_path):
    with pytest.raises(SystemExit) as exc:
        run(page, "nosuch")
    assert exc.value.code == 2
    broken = PAGE.replace("<!-- /bench:tiny -->\n", "")
    page.write_text(broken)
    with pytest.raises(SystemExit, match="exactly once"):
        run(page, "tiny")
    assert page.read_text() == broken


def test_list_and_index(page, capsys):
    assert run(page, "--list") == 0
    out = capsys.readouterr().out
    assert all(b.name in out for b in FAKE) and "benchmarks, about" in out
    assert run(page, "--index") == 0
    assert outside(page.read_text()) == outside(PAGE)
    assert "[`texty`](#plain-text)" in page.read_text()


def test_every_benchmark_has_its_section_and_the_page_no_other():
    text = results.RESULTS.read_text()
    assert sorted(results.sections_in(text)) == sorted(b.name for b in BENCHES)
    assert len({b.name for b in BENCHES}) == len(BENCHES)
    assert results.with_index(text, BENCHES) == text, "run `python -m bench.results --index`"
    for b in BENCHES:
        results.section_span(text, b.name)
        head = text[: text.index(f"<!-- bench:{b.name} -->")].rsplit("\n## ", 1)[1]
        assert f"`python -m bench.results {b.name}` runs `{b.command}`" in head, b.name
        script = next(
            a for a in shlex.split(b.command) if a.endswith((".py", ".sh")) or "bench." in a
        )
        path = ROOT / (script if "/" in script else script.replace(".", "/") + ".py")
        assert path.exists(), f"{b.name}: {path} does not exist"


def test_every_section_cited_by_title_is_still_there():
    """docs, tests, code and benchmarks cite "bench/RESULTS.md, "TITLE""; each title begins a heading of
    the page or of its archive."""
    headings = [
        h.lower()
        for f in ("RESULTS.md", "RESULTS_ARCHIVE.md")
        for h in re.findall(r"^#+ (.+)$", (ROOT / "bench" / f).read_text(), flags=re.M)
    ]
    cited = set()
    files = [*ROOT.glob("docs/*.md"), *ROOT.glob("tests/*.py"), *ROOT.glob("bench/*.py")]
    files += [*ROOT.glob("host/**/*.py"), ROOT / "README.md"]
    for f in files:
        if f == Path(__file__):
            continue
        # a title broken across lines (of a comment) joined; a blank line between is no citation
        text = re.sub(r"[ \t]*\n[ \t]*#?[ \t]*", " ", f.read_text())
        cited |= set(re.findall(r"RESULTS\.md,? (?:section )?\"([^\"]+)\"", text))
    assert len(cited) > 15
    missing = [c for c in cited if not any(h.startswith(c.lower()) for h in headings)]
    assert not missing, missing
