"""Shared helpers for the daemon tests: real ptys, instrument traffic, a daemon subprocess, and a
probe that measures how long the machine kept a thread from running (the observed stall)."""

from __future__ import annotations

import functools
import json
import os
import subprocess
import sys
import threading
import time
import tty
from pathlib import Path

from forcemap.protocol import wire

ROOT = Path(__file__).resolve().parents[1]


def nmea_checksum(body: str) -> str:
    c = 0
    for ch in body.encode():
        c ^= ch
    return f"{c:02X}"


def nmea_line(body: str) -> bytes:
    return f"${body}*{nmea_checksum(body)}\r\n".encode()


def depth_sentence(i: int) -> bytes:
    return nmea_line(f"SDDPT,{2.0 + (i % 50) / 10:.1f},0.3")


def bridge_frame(seq: int, t_us: int, boot_id: int = 0x1234ABCD) -> bytes:
    chans = [(seq * (k + 1), t_us, 1000) for k in range(5)]
    return wire.encode(wire.SAMPLE, boot_id, seq, t_us, wire.pack_sample(2000, chans))


@functools.cache
def _mav():
    from pymavlink.dialects.v20 import ardupilotmega as mav

    return mav, mav.MAVLink(None, srcSystem=1, srcComponent=1)


def mavlink_packet(i: int) -> bytes:
    mav, m = _mav()
    msg = mav.MAVLink_global_position_int_message(
        i * 100, 473_977_420 + i, 85_455_940 + i, 500, 0, 100, 50, 0, 9000
    )
    return msg.pack(m)


class PtyPort:
    """A pty whose slave is reachable at ``path`` (a symlink), like the simulator's ports.

    The test writes to the master. ``pull()`` removes it as a cable pull does; ``plug()`` makes a
    new pty under the same path.
    """

    def __init__(self, path: Path):
        self.path = Path(path)
        self.master = -1
        self.slave = -1
        self.plug()

    def plug(self) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        tmp = self.path.with_suffix(".new")
        if tmp.exists() or tmp.is_symlink():
            tmp.unlink()
        os.symlink(os.ttyname(self.slave), tmp)
        os.replace(tmp, self.path)

    def pull(self) -> None:
        if self.path.is_symlink():
            self.path.unlink()
        for fd in (self.master, self.slave):
            if fd >= 0:
                os.close(fd)
        self.master = self.slave = -1

    def write(self, data: bytes) -> None:
        if self.master >= 0:
            os.write(self.master, data)

    def close(self) -> None:
        self.pull()


class DaemonProcess:
    """`forcemap run` as a subprocess; stderr (one JSON line per event) is collected as events."""

    def __init__(self, out: Path, ports: dict[str, str], *extra: str, quiet: bool = True):
        args = [sys.executable, "-m", "forcemap.host.cli", "run", "-o", str(out)]
        for name, port in ports.items():
            args += [f"--{name}", port]
        args += list(extra)
        if quiet:
            args.append("--quiet")
        self.proc = subprocess.Popen(
            args, cwd=ROOT, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True
        )
        self.events: list[dict] = []
        self.lines: list[str] = []
        self._cond = threading.Condition()
        self._thread = threading.Thread(target=self._collect, daemon=True)
        self._thread.start()

    def _collect(self) -> None:
        assert self.proc.stderr is not None
        for line in self.proc.stderr:
            with self._cond:
                self.lines.append(line)
                try:
                    self.events.append(json.loads(line))
                except ValueError:
                    pass
                self._cond.notify_all()

    def wait_for(self, pred, timeout: float = 60.0) -> dict:
        """The first event matching ``pred``, waiting for it."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while True:
                for e in self.events:
                    if pred(e):
                        return e
                left = deadline - time.monotonic()
                if left <= 0 or self.proc.poll() is not None and not self._thread.is_alive():
                    raise TimeoutError(f"no matching event; stderr:\n{''.join(self.lines)}")
                self._cond.wait(min(left, 0.1))

    def wait_connected(self, sources, timeout: float = 60.0) -> None:
        for s in sources:
            self.wait_for(
                lambda e, s=s: e.get("event") == "connected" and e.get("source") == s, timeout
            )

    def stop(self, sig: int, timeout: float = 20.0) -> int:
        self.proc.send_signal(sig)
        rc = self.proc.wait(timeout)
        self._thread.join(5)
        return rc


def unread_bytes(port: PtyPort) -> int:
    """Bytes written to the pty that its reader has not taken yet (the kernel's FIONREAD)."""
    import fcntl
    import struct as _struct
    import termios

    return _struct.unpack("i", fcntl.ioctl(port.slave, termios.FIONREAD, b"\0\0\0\0"))[0]


def wait_drained(ports, timeout: float = 30.0) -> None:
    """Wait until the daemon has read everything written to the ptys."""
    deadline = time.monotonic() + timeout
    for port in ports:
        while time.monotonic() < deadline:
            if unread_bytes(port) == 0:
                break
            time.sleep(0.02)
    time.sleep(0.3)


class StallProbe:
    """A thread that sleeps ``period_s`` over and over and records how late each wake-up was.

    The lateness is time in which the machine let no thread of this process run: the observed
    stall. Tests of timing promises (a reconnect within 2 s, at most 1 s lost to a kill) add the
    largest stall seen around the measured moment to the promised bound, so a busy machine cannot
    fail them, while a slow product still does: the stall is measured outside the product.
    """

    def __init__(self, period_s: float = 0.01):
        self.period_s = period_s
        self.sleeps: list[tuple[int, int]] = []  # (monotonic ns before, after) each sleep
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="stall-probe", daemon=True)

    def __enter__(self) -> StallProbe:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(5)

    def _run(self) -> None:
        while not self._stop.is_set():
            before = time.monotonic_ns()
            time.sleep(self.period_s)
            self.sleeps.append((before, time.monotonic_ns()))

    def max_stall(self, since_ns: int | None = None, until_ns: int | None = None) -> float:
        """The longest lateness (s) of a sleep overlapping [since_ns, until_ns] (monotonic ns)."""
        lo = -(2**63) if since_ns is None else since_ns
        hi = 2**63 if until_ns is None else until_ns
        late = [
            (after - before) / 1e9 - self.period_s
            for before, after in list(self.sleeps)
            if after >= lo and before <= hi
        ]
        return max(late, default=0.0)


def mcap_files(out: Path) -> list[Path]:
    return sorted(Path(out).glob("*.mcap"))


def last_status(out: Path) -> dict:
    """The last /daemon/status the daemon recorded (its final one after a clean stop)."""
    from forcemap.host.log.mcap import read_messages

    status = None
    for m in read_messages(mcap_files(out), "/daemon/status"):
        status = m.message
    assert status is not None, "no /daemon/status recorded"
    return status
