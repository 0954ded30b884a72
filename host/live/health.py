"""`/health` and its alerts, from what the daemon logs: its status snapshots, fixes and depths.

Times are the log's own (the daemon's arrival clock: the simulator's under `--clock sim:`), so a
replay at any speed and a test on a loaded machine raise the same alerts.
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from forcemap.host.log.live_messages import Health
from forcemap.host.log.record import FoxgloveLog

SILENT_S = 5.0
FIX_LOST_S = 5.0
NO_DEPTH_S = 5.0
DISK_LOW_BYTES = 1 << 30
DEPTH_RANGE_M = (0.3, 100.0)


@dataclass
class SourceHealth:
    connected: bool = False
    bytes: int = 0
    last_reading_ns: int | None = None
    first_seen_ns: int = 0
    outages: int = 0
    rate: float = 0.0


@dataclass
class HealthMonitor:
    """Feed it the logged messages (``observe``); ``update`` makes a `Health` and the alerts that changed."""

    disk_path: Path | None = None
    sources: dict[str, SourceHealth] = field(default_factory=dict)
    absent: list[str] = field(default_factory=list)
    last_fix_ns: int | None = None
    last_depth_ns: int | None = None
    last_depth: float | None = None
    active: dict[str, str] = field(default_factory=dict)  # alert key -> its text
    disk_free: int | None = None

    def observe(self, topic: str, t_ns: int, message: dict[str, Any]) -> None:
        if topic == "/fix":
            self.last_fix_ns = t_ns
        elif topic == "/depth" and message.get("depth") is not None:
            self.last_depth_ns, self.last_depth = t_ns, float(message["depth"])
        elif topic == "/daemon/status":
            self._status(t_ns, message)

    def _status(self, t_ns: int, snap: dict[str, Any]) -> None:
        self.absent = list(snap.get("absent") or [])
        for name, s in (snap.get("sources") or {}).items():
            h = self.sources.setdefault(name, SourceHealth(first_seen_ns=t_ns))
            if s.get("bytes", 0) > h.bytes:
                h.last_reading_ns = t_ns
            h.connected, h.bytes = bool(s.get("connected")), int(s.get("bytes", 0))
            h.outages, h.rate = int(s.get("disconnects", 0)), float(s.get("bytes_per_s", 0.0))

    def _conditions(self, now_ns: int) -> dict[str, tuple[str, str]]:
        """Alert key -> (level, text) of every condition that holds now."""
        out: dict[str, tuple[str, str]] = {}
        for name, h in self.sources.items():
            since = None if h.last_reading_ns is None else (now_ns - h.last_reading_ns) / 1e9
            waited = (now_ns - h.first_seen_ns) / 1e9
            if (since is None and waited > SILENT_S) or (since is not None and since > SILENT_S):
                what = "never read" if since is None else f"silent for {since:.0f} s"
                state = "connected" if h.connected else "disconnected"
                out[f"silent:{name}"] = ("WARNING", f"source {name} {what} ({state})")
        if self.last_fix_ns is not None and (now_ns - self.last_fix_ns) / 1e9 > FIX_LOST_S:
            out["fix"] = ("ERROR", f"fix lost: none for {(now_ns - self.last_fix_ns) / 1e9:.0f} s")
        if self.last_depth_ns is not None:
            lo, hi = DEPTH_RANGE_M
            quiet = (now_ns - self.last_depth_ns) / 1e9
            if quiet > NO_DEPTH_S:
                out["depth"] = ("WARNING", f"sounder out of range: no depth for {quiet:.0f} s")
            elif not lo <= (self.last_depth or 0.0) <= hi:
                out["depth"] = (
                    "WARNING",
                    f"sounder out of range: {self.last_depth:.2f} m (expected {lo:g}-{hi:g} m)",
                )
        if self.disk_free is not None and self.disk_free < DISK_LOW_BYTES:
            out["disk"] = ("ERROR", f"disk nearly full: {self.disk_free / 2**20:.0f} MiB left")
        return out

    def update(self, now_ns: int, live: dict[str, Any]) -> tuple[Health, list[FoxgloveLog]]:
        """The health now, and a log line for every alert raised or cleared since the last call."""
        if self.disk_path is not None:
            try:
                self.disk_free = shutil.disk_usage(self.disk_path).free
            except OSError:
                self.disk_free = None
        now = self._conditions(now_ns)
        logs = [
            FoxgloveLog.at(now_ns, level, text, "forcemap.health")
            for key, (level, text) in now.items()
            if key not in self.active
        ]
        logs += [
            FoxgloveLog.at(now_ns, "INFO", f"cleared: {text}", "forcemap.health")
            for key, text in self.active.items()
            if key not in now
        ]
        self.active = {k: text for k, (_, text) in now.items()}
        sources: dict[str, Any] = {}
        for name, h in self.sources.items():
            since = None if h.last_reading_ns is None else (now_ns - h.last_reading_ns) / 1e9
            silent = since is None or since > SILENT_S
            state = ("silent" if silent else "reading") if h.connected else "disconnected"
            sources[name] = {
                "state": state,
                "bytes_per_s": h.rate,
                "since_last_s": None if since is None else round(since, 1),
                "outages": h.outages,
            }
        for name in self.absent:
            sources[name] = {"state": "not given"}
        health = Health(now_ns / 1e9, sources, live, self.disk_free, sorted(self.active.values()))
        return health, logs
