"""`forcemap log info`'s sources section: every source of each quantity in a log, and how it compares.

Reads the ``/source/reading`` topic (every reading of every source, used or not) and the ``sources``
metadata (why the chosen one was used), and compares each source with the chosen one by
forcemap.host.fuse.source_stats: rate, share of the time, median and p95 difference, the lag that
best aligns them, and the latency against the position source.
"""

from __future__ import annotations

import json
from typing import Any

from forcemap.host.fuse.source_stats import Track, analyse


class SourceCollector:
    """Gathers ``/source/reading`` messages and the ``sources`` metadata of one log."""

    def __init__(self) -> None:
        self.readings: dict[str, dict[str, tuple[list[float], list[list], list[int]]]] = {}
        self.why: dict[str, str] = {}
        self.chosen: dict[str, str] = {}
        self.fix: dict[str, dict[str, str]] = {}  # position: each source's fix quality
        self._result: dict[str, Any] | None = None

    def add(self, log_time_ns: int, data: bytes) -> None:
        """One ``/source/reading`` message as logged."""
        try:
            m = json.loads(data)
            q, src, value, used = m["quantity"], m["source"], m["value"], bool(m["used"])
        except (ValueError, KeyError, TypeError):
            return
        t, v, u = self.readings.setdefault(q, {}).setdefault(src, ([], [], [0]))
        t.append(log_time_ns * 1e-9)
        v.append(value if isinstance(value, list) else [value])
        u[0] += used
        self._result = None

    def metadata(self, data: dict[str, str]) -> None:
        """The ``sources`` metadata record: the chosen source and why, per quantity."""
        for q, text in data.items():
            try:
                d = json.loads(text)
            except ValueError:
                continue
            self.why[q] = str(d.get("why", ""))
            self.chosen[q] = str(d.get("chosen", ""))
            if isinstance(d.get("fix"), dict):
                self.fix[q] = {str(k): str(v) for k, v in d["fix"].items()}

    def result(self) -> dict[str, Any]:
        """Per quantity, its sources compared with the chosen one (source_stats.analyse)."""
        if self._result is None:
            tracks = {
                q: {n: Track(n, t, v, u[0]) for n, (t, v, u) in srcs.items()}
                for q, srcs in self.readings.items()
            }
            chosen = {q: c for q, c in self.chosen.items() if c in tracks.get(q, {})}
            self._result = analyse(tracks, chosen, self.why)
            for q, fixes in self.fix.items():
                for name, row in self._result.get(q, {}).get("sources", {}).items():
                    if fixes.get(name):
                        row["fix"] = fixes[name]
        return self._result

    def lines(self) -> list[str]:
        """The text section (empty without ``/source/reading``)."""
        return format_sources(self.result())


def _num(x: Any, fmt: str, unit: str = "") -> str:
    return "?" if x is None else f"{x:{fmt}}{unit}"


def format_sources(result: dict[str, Any]) -> list[str]:
    """Lines for `log info`: per quantity, the source used (and why), then every other one."""
    if not result:
        return []
    out = ["", "  sources per quantity (* = used; vs the used one: median and p95 difference,"]
    out.append("  the lag that best aligns them; latency against the position source):")
    for q, d in result.items():
        why = f" ({d['why']})" if d.get("why") else ""
        out.append(f"    {q}: {d['chosen']}{why}")
        unit = d.get("unit", "")
        for name, r in sorted(d["sources"].items(), key=lambda kv: kv[0] != d["chosen"]):
            mark = "*" if name == d["chosen"] else " "
            line = (
                f"      {mark} {name:<34} {r['rate_hz']:6.2f} Hz  share {100 * (r['share'] or 0):3.0f}%"
                f"  used {r['used']}/{r['readings']}"
            )
            if "diff_median" in r:
                line += (
                    f"  diff {_num(r['diff_median'], '+.2f')} / p95 {_num(r['diff_p95'], '.2f')} {unit}"
                    f"  lag {_num(r.get('lag_s'), '+.2f', ' s')}"
                )
            if r.get("latency_s") is not None and not (q == "position" and mark == "*"):
                line += f"  latency {r['latency_s']:+.2f} s"
            if r.get("fix"):
                line += f"  fix {r['fix']}"
            if r.get("latency_note"):
                line += f"  latency: {r['latency_note']}"
            out.append(line)
    return out
