"""What was rejected of a survey's soundings, why, and where: one ``qa.depth.rejected`` finding.

Every sounding the import judged carries its reason in the samples' ``bottom_lost`` column
(forcemap.host.fuse.sounding_reasons: 0 held, 1 the bottom lost, 2 spike, 3 false bottom, 4 second
echo); a table no import marked is judged now. The finding gives the share rejected for each reason,
where the rejected lie (per minute of the survey, and the minutes where most are), and is graded on
the share rejected: green under REJECTED_YELLOW, red over REJECTED_RED (QRev's share of invalid
ensembles, as the bottom lost's). Its ``extra`` carries the counts per minute (``per_minute``: JSON,
minute -> soundings and each reason's count), which `check --json` and the report give in full.
"""

from __future__ import annotations

import json
from collections.abc import Mapping

import numpy as np
from forcemap.host.fuse.sounding_reasons import NAMES, REASONS
from forcemap.host.log.qa_records import QaFinding

REJECTED_YELLOW = 0.05
REJECTED_RED = 0.25
TOP_MINUTES = 3  # the minutes named in the message, most rejected first


def per_minute(t: np.ndarray, codes: np.ndarray) -> dict[int, dict[str, int]]:
    """Per minute of the survey (from its first row): its soundings and each reason's count."""
    have = codes >= 0
    if not have.any():
        return {}
    minute = np.floor((t - t[0]) / 60.0).astype(int)
    out: dict[int, dict[str, int]] = {}
    for m in np.unique(minute[have]):
        here = have & (minute == m)
        row = {"soundings": int(here.sum()), NAMES[0]: int((codes[here] == 0).sum())}
        row |= {NAMES[k]: int((codes[here] == k).sum()) for k in REASONS}
        out[int(m)] = row
    return out


def _worst_minutes(table: dict[int, dict[str, int]]) -> list[str]:
    """The minutes with the largest share rejected, as runs of minutes: '31-36 min (82 %)'."""
    share = {m: 1.0 - row[NAMES[0]] / row["soundings"] for m, row in table.items()}
    bad = sorted(m for m, s in share.items() if s > 0.5)
    runs: list[list[int]] = []
    for m in bad:
        if runs and m == runs[-1][1] + 1:
            runs[-1][1] = m
        else:
            runs.append([m, m])
    runs.sort(key=lambda r: -sum(table[m]["soundings"] for m in range(r[0], r[1] + 1)))
    out = []
    for a, b in runs[:TOP_MINUTES]:
        n = sum(table[m]["soundings"] for m in range(a, b + 1))
        held = sum(table[m][NAMES[0]] for m in range(a, b + 1))
        out.append(f"{a}-{b + 1} min ({100 * (1 - held / n):.0f} % rejected)")
    return out


def rejected_finding(
    c: Mapping[str, np.ndarray], source: str, estimated: bool = False
) -> QaFinding | None:
    """The share of soundings rejected for each reason, and where (``c``: the table's columns, its
    ``bottom_lost`` the reasons; ``estimated``: judged now, not marked in the file)."""
    depth, t = np.asarray(c["depth"], float), np.asarray(c["t"], float)
    have = np.isfinite(depth)
    if have.sum() < 10 or "bottom_lost" not in c:
        return None
    codes = np.where(have, np.nan_to_num(np.asarray(c["bottom_lost"], float)), -1).astype(int)
    n = int(have.sum())
    counts = {k: int((codes == k).sum()) for k in REASONS}
    share = sum(counts.values()) / n
    table = per_minute(t, codes)
    parts = [f"{REASONS[k]} {100 * v / n:.1f} %" for k, v in counts.items()]
    msg = f"rejected {100 * share:.1f} % of {n} soundings: " + ", ".join(parts)
    worst = _worst_minutes(table)
    if worst:
        msg += "; most where " + ", ".join(worst) + " into the survey"
    verdict = "green" if share < REJECTED_YELLOW else ("yellow" if share <= REJECTED_RED else "red")
    minutes = "; ".join(
        f"{m}: {row['soundings'] - row[NAMES[0]]}/{row['soundings']}"
        for m, row in table.items()
        if row["soundings"] > row[NAMES[0]]
    )
    return QaFinding(
        "depth", "rejected", verdict, msg, source, 100 * share, unit="%",
        threshold=f"under {100 * REJECTED_YELLOW:g} % of the soundings rejected: green; up to "
        f"{100 * REJECTED_RED:g} %: yellow; more: red",
        evidence="rejected/soundings per minute where any was: " + (minutes or "none"),
        fix=("judged now, not marked in the file: import the raw log to mark the rows"
             if estimated else "every row stays; bottom_lost gives its sounding's reason (0 held) "
             "and depth maps leave out the rejected"),
        extra={"shares": json.dumps({NAMES[k]: v / n for k, v in counts.items()}),
               "per_minute": json.dumps(table), "soundings": str(n)},
    )  # fmt: skip
