"""Progress of long work on stderr: one line rewritten in place on a terminal, one line per step elsewhere."""

from __future__ import annotations

import sys
import time


def _is_terminal() -> bool:
    isatty = getattr(sys.stderr, "isatty", None)
    return bool(isatty and isatty())


class Progress:
    """`label: i/n what (elapsed)` on stderr; silent when disabled.

    On a terminal the line is overwritten (``\\r``); when stderr is a file, a pipe or journald
    (``terminal=False``, the default there) every step is a line of its own, so a log holds no
    endless line."""

    def __init__(
        self, label: str, total: int, enabled: bool = True, terminal: bool | None = None
    ) -> None:
        self.label, self.total, self.enabled = label, total, enabled
        self.terminal = _is_terminal() if terminal is None else terminal
        self.start = time.monotonic()
        self.done = 0

    def step(self, what: str = "") -> None:
        self.done += 1
        if not self.enabled:
            return
        elapsed = time.monotonic() - self.start
        if self.terminal:
            msg = f"\r{self.label}: {self.done}/{self.total} {what[:40]:<40} {elapsed:5.1f} s"
            print(msg, end="", file=sys.stderr, flush=True)
        else:
            line = f"{self.label}: {self.done}/{self.total} {what[:60]}".rstrip()
            print(f"{line} ({elapsed:.1f} s)", file=sys.stderr, flush=True)

    def close(self) -> None:
        if self.enabled and self.terminal:
            print(file=sys.stderr, flush=True)


def note(message: str, enabled: bool = True) -> None:
    """A single progress message on stderr."""
    if enabled:
        print(message, file=sys.stderr, flush=True)
