"""The daemon's side of the live view: a bounded queue that never blocks acquisition and counts what it drops."""

from __future__ import annotations

import collections
import threading
from dataclasses import dataclass
from typing import Any

QUEUE_MAX = 4096


@dataclass(slots=True)
class Item:
    """One logged message on its way to the live server: the same bytes as in the MCAP."""

    topic: str
    log_time_ns: int
    data: bytes
    message: Any


class LiveTee:
    """``offer`` (the MCAP log's tee) appends to a bounded deque and returns at once; a full queue drops
    the new message and counts it by topic. ``take`` is the publisher thread's end."""

    def __init__(self, maxlen: int = QUEUE_MAX):
        self.maxlen = maxlen
        self._items: collections.deque[Item] = collections.deque()
        self._cond = threading.Condition()
        self.offered = 0
        self.drops: dict[str, int] = {}
        self.closed = False

    def offer(self, topic: str, log_time_ns: int, data: bytes, message: Any = None) -> None:
        """Never blocks for more than a lock, never raises."""
        try:
            with self._cond:
                self.offered += 1
                if self.closed or len(self._items) >= self.maxlen:
                    self.drops[topic] = self.drops.get(topic, 0) + 1
                    return
                self._items.append(Item(topic, log_time_ns, data, message))
                self._cond.notify()
        except Exception:  # noqa: BLE001 - the log's write must never fail for the live view
            pass

    def take(self, timeout: float) -> list[Item]:
        """Everything queued (waiting up to ``timeout`` for the first); [] when closed and empty."""
        with self._cond:
            if not self._items and not self.closed:
                self._cond.wait(timeout)
            out = list(self._items)
            self._items.clear()
            return out

    def close(self) -> None:
        with self._cond:
            self.closed = True
            self._cond.notify_all()

    def __len__(self) -> int:
        return len(self._items)
