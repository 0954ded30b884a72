"""Emulated USB-CDC link on a pseudo-terminal, with the board's drop behaviour.

The emulator writes frames to the pty master; the host opens ``path`` (the slave, or a stable
symlink to it) with pyserial like a real ``/dev/ttyACM0``. When the host is not reading, the bytes
it has not read pile up on the slave side, up to the 256-byte CDC FIFO plus the host driver's
buffer (``host_buffer``). A frame that does not fit is cut there and ``write()`` returns None, as
a board's write does after its 500 ms timeout; while the FIFO is full ``writable()`` is False.

    with UsbCdc("/tmp/ports/bridge") as port:
        emu = EmulatedBridge(port.write, writable=port.writable)
"""

from __future__ import annotations

import fcntl
import os
import struct
import termios
import time
import tty

CDC_FIFO = 256
# FIONREAD on a Linux pty never reports more than 4095 unread bytes, so a limit above that could
# never be reached and a host that stopped reading would look like one that reads.
PTY_COUNT_MAX = 4095
HOST_BUFFER = PTY_COUNT_MAX - CDC_FIFO - 300
_SETTLE_S = 0.001


class UsbCdc:
    """A pty pair standing in for the board's USB-CDC port.

    ``link``: optional symlink made to the slave's path. ``host_buffer``: bytes the host's driver
    holds before the device side backs up (the Linux tty buffer is about 4 KiB, of which FIONREAD
    reports at most 4095 bytes; 0 makes a host that stops reading cost frames at once). Our own slave fd stays open so the pty never hangs up.
    """

    def __init__(
        self,
        link: str | None = None,
        *,
        fifo: int = CDC_FIFO,
        host_buffer: int | None = HOST_BUFFER,
    ):
        self.master, self.slave = os.openpty()
        # a fresh pty is cooked: echo and newline mangling would corrupt binary frames
        tty.setraw(self.slave)
        tty.setraw(self.master)
        self.slave_path = os.ttyname(self.slave)
        # None: a plain serial line (a UART), whose writes the device never cuts short
        self.limit = None if host_buffer is None else min(fifo + host_buffer, PTY_COUNT_MAX - 1)
        self.link = link
        if link:
            if os.path.islink(link):
                os.unlink(link)
            d = os.path.dirname(link)
            if d:
                os.makedirs(d, exist_ok=True)
            os.symlink(self.slave_path, link)
        self.bytes_written = 0
        self.frames_written = 0
        self.frames_dropped = 0

    @property
    def path(self) -> str:
        """What the host opens: the symlink if one was made, else the slave's path."""
        return self.link or self.slave_path

    def unread(self) -> int:
        """Bytes written but not yet read by the host."""
        buf = fcntl.ioctl(self.slave, termios.FIONREAD, b"\0\0\0\0")
        return struct.unpack("i", buf)[0]

    def writable(self) -> bool:
        """True while there is room in the FIFO (like POLLOUT on the board's USB-CDC stream)."""
        return self.limit is None or self.unread() < self.limit

    def write(self, frame: bytes) -> int | None:
        """Write a frame. If it does not fit, write what fits and return None, like the board's
        write that gives up after its timeout and drops the rest: the host sees a truncated frame.
        """
        before = self.unread()
        room = len(frame) if self.limit is None else self.limit - before
        if len(frame) > room:
            if room > 0:
                self._write(frame[:room], before)
            self.frames_dropped += 1
            return None
        n = self._write(frame, before)
        self.frames_written += 1
        return n

    def _write(self, data: bytes, before: int) -> int:
        n = os.write(self.master, data)
        self.bytes_written += n
        # The kernel moves pty bytes to the slave side from a worker thread: until it has run,
        # FIONREAD undercounts and a host that stopped reading would look like one that reads.
        # Yield until the count moves (our bytes landed, or the host read), for at most 1 ms.
        deadline = time.monotonic() + _SETTLE_S
        while self.unread() == before and time.monotonic() < deadline:
            os.sched_yield()
        return n

    def close(self) -> None:
        for fd in (self.master, self.slave):
            try:
                os.close(fd)
            except OSError:
                pass
        if self.link and os.path.islink(self.link):
            os.unlink(self.link)

    def __enter__(self) -> UsbCdc:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
