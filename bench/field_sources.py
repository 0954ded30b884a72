"""Source and latency figures for every real NMEA capture (issue 20), for bench_field_logs.py.

Each capture is imported through the real pipeline; per quantity: how many sources, which one was
used and why, each other one's disagreement (median, p95), lag and latency against the position
source; and the two figures the issue pins: speed from successive positions against SOG (p95), and
the yaw rate's p99.
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path
from typing import Any

import numpy as np
from forcemap.host.convert.importers import import_file

EARTH_R = 6_371_000.0


class FiguresSink:
    """Keeps the metadata and the samples' navigation columns, drops everything else."""

    def __init__(self) -> None:
        self.meta: dict[str, dict[str, str]] = {}
        self.rows: list[tuple[float, float | None, float | None, float | None, float | None]] = []

    def write(self, topic: str, log_time_ns: int, message: Any) -> None:
        if topic == "/samples":
            m = message
            self.rows.append((m.t, m.lat, m.lon, m.sog, m.yaw_rate))

    def metadata(self, name: str, data: dict[str, str]) -> None:
        self.meta[name] = dict(data)


def nav_figures(rows: list[tuple]) -> dict[str, float | None]:
    a = np.array([[np.nan if x is None else x for x in r] for r in rows], dtype=float)
    if len(a) < 3:
        return {"speed_vs_sog_p95": None, "yaw_rate_p99": None}
    t, lat, lon, sog, yaw = (a[:, i] for i in range(5))
    dt = np.diff(t)
    dx = np.diff(np.radians(lon)) * np.cos(np.radians(lat[:-1])) * EARTH_R
    dy = np.diff(np.radians(lat)) * EARTH_R
    ok = dt > 0.2
    d = np.abs(np.hypot(dx, dy)[ok] / dt[ok] - 0.5 * (sog[:-1] + sog[1:])[ok])
    d = d[np.isfinite(d)]
    y = np.abs(yaw[np.isfinite(yaw)])
    return {
        "speed_vs_sog_p95": float(np.percentile(d, 95)) if len(d) else None,
        "yaw_rate_p99": float(np.percentile(y, 99)) if len(y) else None,
    }


def capture_figures(path: Path) -> dict[str, Any]:
    sink = FiguresSink()
    t0 = time.perf_counter()
    import_file(path, sink, "nmea")
    out: dict[str, Any] = {"import_s": time.perf_counter() - t0, **nav_figures(sink.rows)}
    out["sources"] = {q: json.loads(v) for q, v in sink.meta.get("sources", {}).items()}
    return out


def _f(x: Any, fmt: str) -> str:
    return "-" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, fmt)


def report(real_nmea: Path) -> list[str]:
    """The lines bench_field_logs prints for every capture in ``real_nmea``."""
    lines = []
    for path in sorted(p for p in real_nmea.iterdir() if p.suffix in (".log", ".txt")):
        f = capture_figures(path)
        lines.append(
            f"\n{path.name}: import {f['import_s']:.1f} s; speed from positions vs SOG p95 "
            f"{_f(f['speed_vs_sog_p95'], '.2f')} m/s; yaw rate p99 {_f(f['yaw_rate_p99'], '.1f')} deg/s"
        )
        for q, d in f["sources"].items():
            lines.append(
                f"  {q:<10} used {d['chosen']} ({d['why']}), {len(d['sources'])} source(s)"
            )
            for name, r in d["sources"].items():
                if (
                    name == d["chosen"]
                    and r.get("latency_s") in (None, 0.0)
                    and not r.get("latency_note")
                ):
                    continue
                lines.append(
                    f"    {name:<30} {r['rate_hz']:5.2f} Hz share {100 * (r['share'] or 0):3.0f} %"
                    f" diff {_f(r.get('diff_median'), '+.2f')}/{_f(r.get('diff_p95'), '.2f')} {d['unit']}"
                    f" lag {_f(r.get('lag_s'), '+.2f')} s latency {_f(r.get('latency_s'), '+.2f')} s"
                    + (f" ({r['latency_note']})" if r.get("latency_note") else "")
                )
    return lines
