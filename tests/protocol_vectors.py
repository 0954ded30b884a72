"""Reads the golden vectors out of protocol/SPEC.md, so the document and the tests cannot disagree."""

from __future__ import annotations

import re
from pathlib import Path

SPEC = Path(__file__).resolve().parents[1] / "protocol" / "SPEC.md"


def golden_vectors() -> list[dict]:
    vectors = []
    for block in re.findall(r"```golden\n(.*?)```", SPEC.read_text(), re.S):
        v: dict = {}
        for line in block.strip().splitlines():
            key, _, value = line.partition(":")
            value = value.strip()
            if key in ("name", "payload", "wire"):
                v[key] = value
            else:
                v[key] = int(value, 0)
        vectors.append(v)
    return vectors
