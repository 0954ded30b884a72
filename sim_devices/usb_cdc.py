"""Emulated USB-CDC link on a pseudo-terminal, with the board's drop behaviour.

The emulator writes frames to the pty master; the host opens ``path`` (the slave, or a stable
symlink to it) with pyserial like a real ``/dev/ttyACM0``. When the host is not reading, the bytes
it has not read pile up on the slave side, up to the 256-byte CDC FIFO plus the host driver's
buffer (``host_buffer``). A frame that does not fit is cut there and ``write()`` returns None, as
a board's write does after its 500 ms timeout; while the FIFO is full ``writable()`` is False.

A UART (``host_buffer=None``) is never cut by the device: on a non-blocking pty that is full (the
host reads slower than the simulator writes) its write waits for room (poll, no spin) for up to
``patience_s``; only a reader that leaves the port full that long loses bytes, as a line nobody reads.

    with UsbCdc("/tmp/ports/bridge") as port:
        emu = EmulatedBridge(port.write, writable=port.writable)
"""

from __future__ import annotations

import fcntl
import os
import select
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
# host seconds a UART's reader may leave its pty full before the bytes that do not fit are lost. A
# Linux pty holds only 14-20 KiB (the line discipline's 4095 bytes and the flip buffer), which a
# simulator at x400 fills within one 50-ms pause of its reader. A port nobody reads costs this once
# (then it is ``stalled``): a simulator run with ports nobody opened waits that long once a port.
WRITE_PATIENCE_S = 0.5


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
        patience_s: float = WRITE_PATIENCE_S,
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
        self.patience_s = patience_s
        self.stalled = False  # left full for patience_s: not waited on again until it has room
        self.waits = 0  # UART writes that found the pty full and waited for the reader
        self._room = select.poll()
        self._room.register(self.master, select.POLLOUT)

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

    def writable_soon(self) -> bool:
        """``writable()``, giving a host that reads slower than the simulator writes the time to.

        A full FIFO is waited on (1-ms sleeps, no spin) for up to ``patience_s``; a host that leaves
        it full that long is not reading, and the port is ``stalled`` (not waited on again) until
        it has room. For a simulator that writes at x400 of real time: a 20-ms pause of its reader
        is 8 s of the board's time, which the firmware would otherwise take for a host gone.
        """
        if self.writable():
            self.stalled = False
            return True
        deadline = time.monotonic() + (0.0 if self.stalled else self.patience_s)
        while time.monotonic() < deadline:
            time.sleep(0.001)
            if self.writable():
                return True
        self.stalled = True
        return False

    def write(self, frame: bytes, settle: bool = True) -> int | None:
        """Write a frame; the bytes written, or None if some of it was lost.

        USB-CDC: if the frame does not fit the FIFO, write what fits and return None, like the board's
        write that gives up after its timeout and drops the rest: the host sees a truncated frame.
        ``settle=False``: the caller knows the host has read every byte before this write (lockstep),
        so the count of unread bytes is exact and the write need not wait for the kernel to move it.
        A UART: every byte, waiting for room while its reader reads (see the module's docstring).
        """
        if self.limit is None:
            n = self._send(frame)
            if n < len(frame):
                self.frames_dropped += 1
                return None
            self.frames_written += 1
            return n
        before = self.unread()
        room = self.limit - before
        if len(frame) > room:
            if room > 0:
                self._write(frame[:room], before, settle)
            self.frames_dropped += 1
            return None
        n = self._write(frame, before, settle)
        self.frames_written += 1
        return n

    def _send(self, data: bytes) -> int:
        """A UART's write: all of ``data``, polling for room while the pty is full; the bytes written.

        A short write or EAGAIN means the reader is behind, not gone: wait until the pty can take
        more, up to ``patience_s``. A port left full that long is ``stalled``: its writes then take
        what fits at once (the rest is lost) until one fits whole.
        """
        done, deadline = 0, None
        while True:
            try:
                done += os.write(self.master, data[done:])
            except BlockingIOError:
                pass
            if done == len(data) or self.stalled:
                break
            if deadline is None:
                deadline = time.monotonic() + self.patience_s
                self.waits += 1
            left = deadline - time.monotonic()
            if left <= 0 or not self._room.poll(left * 1000):
                break
        self.stalled = done < len(data)
        self.bytes_written += done
        return done

    def _write(self, data: bytes, before: int, settle: bool) -> int:
        n = os.write(self.master, data)
        self.bytes_written += n
        if not settle:
            return n
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
