"""The links of the pages written by audience (the guide, the methods, the reference, the results) lead
somewhere: every relative link names a file of the repository and, with a `#fragment`, a heading of it
(GitHub's anchors: lower case, punctuation dropped, spaces to hyphens, `-1`, `-2` for repeats)."""

from __future__ import annotations

import re
from functools import cache
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [
    "README.md",
    "docs/GUIDE.md",
    "docs/METHODS.md",
    "docs/WORKBENCH.md",
    "docs/PAPER.md",
    "bench/RESULTS.md",
]
LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")


@cache
def anchors(page: Path) -> set[str]:
    text = re.sub(r"^```.*?^```", "", page.read_text(encoding="utf-8"), flags=re.M | re.S)
    seen: dict[str, int] = {}
    out = set()
    for heading in re.findall(r"^#{1,6} (.+?)\s*#*$", text, flags=re.M):
        slug = re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")
        n = seen.get(slug, 0)
        seen[slug] = n + 1
        out.add(slug if n == 0 else f"{slug}-{n}")
    return out


@pytest.mark.parametrize("page", PAGES)
def test_every_relative_link_leads_somewhere(page):
    src = ROOT / page
    bad = []
    for target in LINK.findall(src.read_text(encoding="utf-8")):
        if re.match(r"[a-z]+:", target):
            continue  # http:, https:, mailto:
        path, _, fragment = target.partition("#")
        dest = (src.parent / path).resolve() if path else src
        rel = dest.relative_to(ROOT).as_posix() if dest.is_relative_to(ROOT) else str(dest)
        if not dest.exists():
            bad.append(f"{target}: no {rel}")
            continue
        if fragment and dest.suffix == ".md" and fragment not in anchors(dest):
            bad.append(f"{target}: no heading #{fragment} in {rel}")
    assert not bad, f"{page}:\n" + "\n".join(bad)
