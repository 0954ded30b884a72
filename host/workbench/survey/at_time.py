"""`--at TIME`: when a map or a plan is for, in one clear form: ISO 8601 with its zone, UNIX seconds, or now."""

from __future__ import annotations

import math
import re
import time
from datetime import UTC, datetime

from forcemap.host.workbench.errors import WorkbenchError

FORMS = (
    "ISO 8601 with its zone (2026-06-02T14:00Z, 2026-06-02T14:00+02:00), a date YYYY-MM-DD (its 00:00 "
    "UTC), UNIX time, or now"
)
_DATE = re.compile(r"^\d{4}-\d{2}-\d{2}$")
# before 1970 or after 2200 is a typo, not a survey
EARLIEST, LATEST = 0.0, 7_258_118_400.0


def parse_at(text: str | float | int, option: str = "--at") -> float:
    """UNIX seconds of `text`: `now`, a number of UNIX seconds, an ISO 8601 time with its zone (Z, +hh:mm),
    or a date alone (its 00:00 UTC). A time of day without a zone is refused: which tide it means depends
    on it."""
    if isinstance(text, int | float):
        value = float(text)
    else:
        raw = str(text).strip()
        value = _parse(raw, option)
    if not (math.isfinite(value) and EARLIEST <= value <= LATEST):
        raise WorkbenchError(f"{option} {text}: not a time between 1970 and 2200; give {FORMS}")
    return value


def _parse(raw: str, option: str) -> float:
    if raw.lower() == "now":
        return time.time()
    try:
        return float(raw)
    except ValueError:
        pass
    if _DATE.match(raw):
        return datetime.fromisoformat(raw).replace(tzinfo=UTC).timestamp()
    iso = raw[:-1] + "+00:00" if raw.endswith(("Z", "z")) else raw
    try:
        when = datetime.fromisoformat(iso)
    except ValueError:
        raise WorkbenchError(f"{option} {raw}: cannot read this time; give {FORMS}") from None
    if when.tzinfo is None:
        raise WorkbenchError(
            f"{option} {raw}: give its time zone ({raw}Z for UTC, or {raw}+02:00): a time without one "
            "is ambiguous, and the tide it asks for is not"
        )
    return when.timestamp()
