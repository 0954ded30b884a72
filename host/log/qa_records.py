"""A quality finding as a log keeps it: one MCAP metadata record named ``qa.<category>.<check>[.<source>]``.

Every estimator that grades or calibrates a log (units, gains, offsets, lags, dead sources, checksum
variants, declination, bottom lost, an ADCP's bottom track ...) writes its finding in this one shape, so
that ``forcemap check``, ``log info``, ``fit`` and the report read them all from one place without knowing
who wrote them. The shape follows USGS QRev: a category, a verdict (green, yellow or red) against a stated
threshold, the measured value with its unit and uncertainty, the evidence, and the fix (applied or advised).
MCAP metadata values are strings, so numbers are written with ``repr``-exact text and read back as floats.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

PREFIX = "qa."
VERDICTS = ("green", "yellow", "red")
# the categories `check` reports, in its order; a finding of another category is shown under "other"
CATEGORIES = (
    "time",
    "position",
    "heading",
    "rate_of_turn",
    "speed_through_water",
    "wind",
    "depth",
    "water_level",
    "adcp",
    "other",
)


@dataclass(frozen=True)
class QaFinding:
    """One graded check of one log (and one source in it, where it is about a source)."""

    category: str  # one of CATEGORIES
    check: str  # short machine name: "gain", "misalignment", "latency", "dead", "unit", "declination", ...
    verdict: str  # green, yellow or red
    message: str  # one line a user reads: what was found, with its number
    source: str = ""  # the source it is about ("nmea IIVHW [port 0]"), or "" for the whole log
    value: float = math.nan  # the measured value in `unit`
    sd: float = math.nan  # its standard uncertainty, where estimated
    unit: str = ""  # SI, or "deg", "s", "%", "1" (a ratio)
    threshold: str = ""  # the rule graded against, with its source ("HDOP <= 2.5 (QRev)")
    evidence: str = ""  # what the number comes from ("least squares on 3,412 rows, 4 headings")
    fix: str = ""  # what was done or what to do ("applied: STW x 1.063"; "pin it in boat.toml [speed_log]")
    applied: bool = False  # the log's samples were corrected with this estimate
    extra: dict[str, str] = field(default_factory=dict)  # anything else worth keeping, as strings

    def __post_init__(self) -> None:
        if self.verdict not in VERDICTS:
            raise ValueError(f"verdict {self.verdict!r} is not one of {VERDICTS}")
        if self.category not in CATEGORIES:
            raise ValueError(f"category {self.category!r} is not one of {CATEGORIES}")

    @property
    def name(self) -> str:
        """The metadata record's name: ``qa.<category>.<check>[.<source>]``."""
        tail = f".{self.source}" if self.source else ""
        return f"{PREFIX}{self.category}.{self.check}{tail}"

    def to_metadata(self) -> dict[str, str]:
        """The finding as an MCAP metadata record's string map."""
        out: dict[str, str] = {}
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name == "extra":
                out.update({f"extra.{k}": str(x) for k, x in v.items()})
            elif isinstance(v, bool):
                out[f.name] = "true" if v else "false"
            elif isinstance(v, float):
                out[f.name] = "" if math.isnan(v) else repr(float(v))
            else:
                out[f.name] = str(v)
        return out

    @classmethod
    def from_metadata(cls, data: dict[str, str]) -> QaFinding:
        """Read a finding back from its metadata record (unknown keys are kept in ``extra``)."""
        known = {f.name for f in fields(cls)} - {"extra"}
        kw: dict[str, object] = {}
        extra: dict[str, str] = {}
        for k, v in data.items():
            if k.startswith("extra."):
                extra[k[len("extra.") :]] = v
            elif k in ("value", "sd"):
                kw[k] = float(v) if v else math.nan
            elif k == "applied":
                kw[k] = v == "true"
            elif k in known:
                kw[k] = v
            else:
                extra[k] = v
        return cls(**kw, extra=extra)  # type: ignore[arg-type]


def is_finding(name: str) -> bool:
    """Whether a metadata record's name is a quality finding's."""
    return name.startswith(PREFIX)


def worst(verdicts: list[str]) -> str:
    """The worst of some verdicts (green when there are none)."""
    return max(verdicts, key=VERDICTS.index, default="green")
