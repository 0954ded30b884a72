"""NMEA 0183 checksum variants: a talker that computes its checksum the wrong way, the same way every time.

The standard checksum is the XOR of every character between ``$`` (or ``!``) and ``*``. Some
instrument buses compute it over part of the sentence only (the Irene logs of 2013: over the address
``IIHDG`` alone, so every HDG carries ``*4B`` whatever its heading). A line whose checksum fails is
tested against each VARIANT; a variant is *systematic* when it explains at least MIN_LINES lines and
at least MIN_SHARE of the failures (damaged lines match one variant by chance once in 256). Strict
parsing (the default) rejects these lines and reports the variant; ``--nmea-checksum lenient``
accepts them, counted, and trades away the checksum's protection of the fields it leaves out.
"""

from __future__ import annotations

from collections.abc import Callable

from forcemap.host.log.qa_records import QaFinding

MODES = ("strict", "lenient")
MIN_LINES = 10
MIN_SHARE = 0.1


def xor(text: str) -> int:
    """XOR of the characters of ``text`` (ASCII)."""
    x = 0
    for b in text.encode("ascii", "replace"):
        x ^= b
    return x


def _address(body: str) -> str:
    comma = body.find(",")
    return body if comma < 0 else body[:comma]


def _without_last_field(body: str) -> str:
    comma = body.rfind(",")
    return body if comma < 0 else body[:comma]


# name -> (what it covers, said in words; the characters it is computed over, from the body
# between the start character and "*")
VARIANTS: dict[str, tuple[str, Callable[[str], str]]] = {
    "address": ("over the address only", _address),
    "without_last_field": ("over the sentence without its last field", _without_last_field),
    "with_start": ("including the start character $", lambda body: "$" + body),
}


def variant_of(body: str, want: int) -> str:
    """The variant whose checksum of ``body`` (between ``$`` and ``*``) is ``want``, or ''."""
    for name, (_, part) in VARIANTS.items():
        if xor(part(body)) == want:
            return name
    return ""


def systematic(variants: dict[str, int], bad_checksums: int) -> list[tuple[str, int]]:
    """The variants (name, lines) that are systematic among ``bad_checksums`` failed lines (rejected
    or accepted leniently), most lines first."""
    total = bad_checksums
    out = [(v, n) for v, n in variants.items() if n >= MIN_LINES and n >= MIN_SHARE * max(total, 1)]
    return sorted(out, key=lambda vn: -vn[1])


def describe(name: str) -> str:
    """A variant's name in words ("over the address only")."""
    return VARIANTS[name][0] if name in VARIANTS else name


def finding(
    variants: dict[str, int], by_address: dict[str, int], bad: int, lines: int, mode: str
) -> QaFinding | None:
    """``qa.other.nmea_checksum``: the systematic variant, its count and what became of its lines
    (``bad``: lines whose checksum failed, lenient ones included; ``by_address``: "variant ADDR")."""
    found = systematic(variants, bad)
    if not found:
        return None
    name, n = found[0]
    top = sorted(((k.split(" ", 1)[1], c) for k, c in by_address.items() if k.startswith(name + " ")),
                 key=lambda kc: -kc[1])  # fmt: skip
    who = ", ".join(f"{a} {c}" for a, c in top[:4]) + (", ..." if len(top) > 4 else "")
    lenient = mode == "lenient"
    fate = (
        "accepted (--nmea-checksum lenient)"
        if lenient
        else ("rejected; --nmea-checksum lenient accepts them")
    )
    return QaFinding(
        "other",
        "nmea_checksum",
        "yellow" if lenient else "red",
        f"checksums: {n} of {lines} lines have theirs computed {describe(name)} ({who}), a "
        f"systematic variant: {fate}",
        value=float(n),
        unit="lines",
        threshold=f"a variant is systematic when it explains >= {MIN_LINES} lines and >= "
        f"{MIN_SHARE:.0%} of the failed checksums (one damaged line in 256 matches by chance)",
        evidence=f"{bad} lines failed the standard checksum (XOR between $ and *)",
        fix="applied: accepted, the checksum no longer guards what it leaves out"
        if lenient
        else "import again with --nmea-checksum lenient (run: the same option)",
        applied=lenient,
        extra={"variant": name, "mode": mode, "addresses": who},
    )
