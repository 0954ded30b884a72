"""A one-line progress indicator on stderr for long work."""

from __future__ import annotations

import sys
import time


class Progress:
    """Print `label: i/n (elapsed)` on one stderr line, overwriting it; silent when disabled."""

    def __init__(self, label: str, total: int, enabled: bool = True) -> None:
        self.label, self.total, self.enabled = label, total, enabled
        self.start = time.monotonic()
        self.done = 0

    def step(self, what: str = "") -> None:
        self.done += 1
        if self.enabled:
            elapsed = time.monotonic() - self.start
            msg = f"\r{self.label}: {self.done}/{self.total} {what[:40]:<40} {elapsed:5.1f} s"
            print(msg, end="", file=sys.stderr, flush=True)

    def close(self) -> None:
        if self.enabled:
            print(file=sys.stderr, flush=True)


def note(message: str, enabled: bool = True) -> None:
    """A single progress message on stderr."""
    if enabled:
        print(message, file=sys.stderr, flush=True)
