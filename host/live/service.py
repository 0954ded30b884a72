"""The live view: the MCAP log's tee → one publisher thread → the Foxglove server, `/health`, the map process.

The daemon's thread only ever calls `LiveTee.offer` (bounded, never blocks). Everything else runs on
the publisher thread of this class, or in the map process.
"""

from __future__ import annotations

import json
import threading
from pathlib import Path
from typing import Any

from forcemap.host.live.health import HealthMonitor
from forcemap.host.live.mapproc import MapBoard, MapProcess
from forcemap.host.live.mission_layer import TOPIC as MISSION_TOPIC
from forcemap.host.live.mission_layer import MissionLayer
from forcemap.host.live.server import BACKLOG, DEFAULT_HOST, DEFAULT_PORT, LiveServer
from forcemap.host.live.tee import QUEUE_MAX, Item, LiveTee
from forcemap.host.log.mcap import encode_json
from forcemap.host.log.messages import as_json

WATCHED = ("/fix", "/depth", "/daemon/status", "/samples")


class LiveService:
    """Serve every logged topic live, with `/health`, `/alerts`, the growing maps and `/map/mission`."""

    def __init__(
        self,
        host: str = DEFAULT_HOST,
        port: int = DEFAULT_PORT,
        *,
        disk_path: str | Path | None = None,
        maps: bool = True,
        every_s: float = 60.0,
        refit_every_s: float = 300.0,
        backlog: int = BACKLOG,
        queue_max: int = QUEUE_MAX,
    ):
        self.server = LiveServer(host, port, backlog)
        self.tee = LiveTee(queue_max)
        self.health = HealthMonitor(Path(disk_path) if disk_path is not None else None)
        self.board = MapBoard()
        self.mission = MissionLayer()  # its plan comes from the replanner (run --replan)
        self.mapper = MapProcess(every_s, refit_every_s) if maps else None
        self.published: dict[str, int] = {}
        self.errors: dict[str, int] = {}
        self._last_t = 0
        self._finished = False
        self.thread = threading.Thread(target=self._run, name="forcemap-live", daemon=True)
        self.thread.start()

    @property
    def address(self) -> str:
        return f"{self.server.host}:{self.server.port}"

    def attach(self, log: Any) -> None:
        """Tee everything ``log`` (a `McapLog`) writes to the live view."""
        log.tee = self.tee.offer

    def _run(self) -> None:
        while True:
            items = self.tee.take(0.2)
            for item in items:
                self._guard("publish", self._item, item)
            if self.mapper is not None:
                self._guard("maps", self._maps, self.mapper.poll())
            if self._last_t and self.mission.due(self._last_t):  # a new plan, between fixes
                self._guard("mission", self._mission)
            if self.tee.closed and not items:
                if self.mission.due(
                    self._last_t + 10**18
                ):  # the log closed: the track's last metres
                    self._guard("mission", self._mission)
                return

    def _guard(self, what: str, fn: Any, *args: Any) -> None:
        """Nothing the live view does may end the thread (a bad message is counted)."""
        try:
            fn(*args)
        except Exception:  # noqa: BLE001
            self.errors[what] = self.errors.get(what, 0) + 1

    def publish(self, topic: str, t_ns: int, record: Any) -> None:
        """A live-only message (not in the MCAP)."""
        self._send(Item(topic, t_ns, encode_json(as_json(record)), record))

    def _send(self, item: Item) -> None:
        self.server.publish(item.topic, item.log_time_ns, item.data, item.message)
        self.published[item.topic] = self.published.get(item.topic, 0) + 1

    def _item(self, item: Item) -> None:
        self._send(item)
        self._last_t = max(self._last_t, item.log_time_ns)
        if item.topic not in WATCHED:
            return
        msg = as_json(item.message) if item.message is not None else json.loads(item.data)
        if item.topic == "/fix":
            self.mission.fix(msg["latitude"], msg["longitude"])
            if self.mission.due(item.log_time_ns):
                self._mission()
        self.health.observe(item.topic, item.log_time_ns, msg)
        if item.topic == "/samples" and self.mapper is not None:
            self.mapper.offer(msg)
        elif item.topic == "/daemon/status":
            health, alerts = self.health.update(item.log_time_ns, self.live_stats())
            self.publish("/health", item.log_time_ns, health)
            for log in alerts:
                self.publish("/alerts", item.log_time_ns, log)

    def _maps(self, results: list) -> None:
        for grids, messages in results:
            self.board.put(grids)
            t_ns = int(max(g.t_fit for g in grids) * 1e9)
            for topic, record in messages:
                self.publish(topic, t_ns, record)

    def _mission(self) -> None:
        self.publish(MISSION_TOPIC, self._last_t, self.mission.message())

    def live_stats(self) -> dict[str, Any]:
        """The live view's own counters, for `/health`."""
        out = self.server.stats()
        out["queue_drops"] = dict(self.tee.drops)
        out["queued"] = len(self.tee)
        out["errors"] = dict(self.errors)
        if self.mapper is not None:
            out["map_sample_drops"] = self.mapper.drops
            out["map_errors"] = self.mapper.errors[-3:]
            out["map_updates"] = self.board.updates
        return out

    def finish(self, final_maps_s: float = 10.0) -> None:
        """Publish what is queued, the track's last metres and the final maps (waiting at most
        ``final_maps_s`` for them: the map process runs at a low priority and may be behind). The server
        stays up, so a viewer ashore sees the survey's last state. Once only."""
        if self._finished:
            return
        self._finished = True
        self.tee.close()
        self.thread.join(timeout=30.0)
        if self.mapper is not None:
            self._guard("maps", self._maps, self.mapper.close(final_maps_s))

    def close(self, final_maps_s: float = 10.0) -> None:
        """`finish`, then stop the server."""
        self.finish(final_maps_s)
        self.server.stop()
