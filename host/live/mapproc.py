"""The live maps in their own process, at a lower priority, so acquisition never waits for a refit.

`MapProcess.offer(sample)` never blocks (a full queue drops the sample and counts it). Results come
back as `MapGrid`s with their Foxglove messages; `MapBoard` keeps the latest grid of every target for
readers in the daemon's process (the live server, and online planning).
"""

from __future__ import annotations

import multiprocessing as mp
import os
import queue
import threading
import time
from typing import Any

from forcemap.host.live.growing import MapGrid

NICE = 10
IN_MAX = 20_000  # 5 h of samples at 1 Hz: the map process is behind only while it refits
OUT_MAX = 64


def _serve(
    inbox: Any, outbox: Any, every_s: float, refit_every_s: float, nice: int, parent: int
) -> None:
    """The map process: add samples, update when due, send the grids and their layers back."""
    from forcemap.host.live.layers import map_messages
    from forcemap.host.live.maps import LiveMaps

    try:
        os.nice(nice)
    except OSError:
        pass
    maps = LiveMaps(every_s=every_s, refit_every_s=refit_every_s)
    while True:
        try:
            item = inbox.get(timeout=0.5)
        except queue.Empty:
            if os.getppid() != parent:  # the daemon was killed (kill -9): no one to map for
                return
            continue
        batch = [item]
        while True:  # everything queued: one update for a backlog, not one per sample
            try:
                batch.append(inbox.get_nowait())
            except queue.Empty:
                break
        final = False
        for kind, payload in batch:
            # one sample at a time: the updates fall where the samples' time says, however they
            # arrive (a replay at x100, a backlog after a long refit)
            if kind == "sample":
                maps.add(payload)
            elif kind == "stop":
                final = True
            try:
                grids = maps.step(force="final" if final else "")
                if grids:
                    outbox.put(("maps", grids, map_messages(grids, maps)))
            except Exception as exc:  # noqa: BLE001 - a bad update costs that update, not the maps
                outbox.put(("error", f"{type(exc).__name__}: {exc}"))
        if final:
            outbox.put(("stopped", maps.refits, maps.updates))
            return


class MapBoard:
    """The latest live map of every target, for any reader in this process (thread-safe)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._grids: dict[str, MapGrid] = {}
        self.updates = 0

    def put(self, grids: list[MapGrid]) -> None:
        with self._lock:
            for g in grids:
                self._grids[g.target] = g
            self.updates += 1

    def latest(self) -> dict[str, MapGrid]:
        """Target ("current", "wind", "depth") -> its newest `MapGrid` (with sd, age, samples count)."""
        with self._lock:
            return dict(self._grids)


class MapProcess:
    """Starts the map process; ``offer`` samples, ``poll`` results, ``close`` for the final maps."""

    def __init__(self, every_s: float = 60.0, refit_every_s: float = 300.0, nice: int = NICE):
        ctx = mp.get_context("spawn")  # no fork of a process with reader threads and a server
        self.inbox = ctx.Queue(IN_MAX)
        self.outbox = ctx.Queue(OUT_MAX)
        # at exit, samples the map process will never read are dropped, not flushed (which would
        # hang the daemon's exit on a full pipe)
        self.inbox.cancel_join_thread()
        self.proc = ctx.Process(
            target=_serve,
            args=(self.inbox, self.outbox, every_s, refit_every_s, nice, os.getpid()),
            name="forcemap-live-map",
            daemon=True,
        )
        self.proc.start()
        self.drops = 0
        self.offered = 0
        self.stats: tuple[int, int] | None = None
        self.errors: list[str] = []

    def offer(self, sample: dict[str, Any]) -> None:
        self.offered += 1
        try:
            self.inbox.put_nowait(("sample", sample))
        except queue.Full:
            self.drops += 1

    def poll(self, timeout: float = 0.0) -> list[tuple[list[MapGrid], list]]:
        """Results that have arrived: (grids, [(topic, record), ...]) per update."""
        out = []
        try:
            while True:
                item = self.outbox.get(timeout=timeout) if timeout else self.outbox.get_nowait()
                timeout = 0.0
                if item[0] == "maps":
                    out.append((item[1], item[2]))
                elif item[0] == "error":
                    self.errors.append(item[1])
                elif item[0] == "stopped":
                    self.stats = (item[1], item[2])
        except queue.Empty:
            pass
        return out

    def close(self, timeout: float = 60.0) -> list[tuple[list[MapGrid], list]]:
        """Ask for the final maps (a last hyperparameter refit) and wait for them."""
        out: list = []
        if self.proc.is_alive():
            try:
                self.inbox.put(("stop", None), timeout=5.0)
            except queue.Full:
                pass
            deadline = time.monotonic() + timeout
            while self.stats is None and self.proc.is_alive() and time.monotonic() < deadline:
                out += self.poll(timeout=0.2)
            out += self.poll()
        self.proc.join(timeout=2.0)
        if self.proc.is_alive():
            self.proc.terminate()
            self.proc.join(timeout=5.0)
        return out
