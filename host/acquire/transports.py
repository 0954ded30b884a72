"""The byte streams a reader opens: serial ports and anything pyserial opens (`socket://` for TCP), UDP
sockets; each opened by an opener the reader calls again after a disconnect."""

from __future__ import annotations

import os
import socket
import time
from typing import Protocol

import serial

READ_TIMEOUT_S = 0.2
MAX_READ = 65536
# how often an idle serial reader checks that its path still names the device it opened
PATH_CHECK_S = 0.5


class Transport(Protocol):
    """An open byte stream: ``read`` returns b"" after a short timeout and raises on disconnect."""

    def read(self) -> bytes: ...

    def close(self) -> None: ...


class Disconnected(Exception):
    """The transport is gone; ``reason`` is a short machine-readable word."""

    def __init__(self, reason: str, detail: str = ""):
        super().__init__(f"{reason}: {detail}" if detail else reason)
        self.reason = reason
        self.detail = detail


class SerialTransport:
    """Anything ``serial.serial_for_url`` opens: a device path, ``socket://``, ``loop://``, ..."""

    def __init__(self, url: str, baudrate: int = 115200):
        self.url = url
        self._is_path = "://" not in url
        # exclusive (flock) on a device, so a second daemon or mpremote cannot share the port
        extra = {"exclusive": True} if self._is_path else {}
        self._ser = serial.serial_for_url(url, baudrate=baudrate, timeout=READ_TIMEOUT_S, **extra)
        self._device = self._identity() if self._is_path else None
        self._checked = time.monotonic()

    def _identity(self) -> tuple[int, int] | None:
        try:
            st = os.stat(self.url)
        except OSError:
            return None
        return (st.st_rdev, st.st_ino)

    def read(self) -> bytes:
        data = self._ser.read(1)
        if data:
            waiting = self._ser.in_waiting
            if waiting:
                data += self._ser.read(min(waiting, MAX_READ))
            return data
        # Idle: a pulled cable may have left us holding a dead device whose path is gone or
        # now names a new one (a pty re-created under the same symlink).
        if self._is_path and time.monotonic() - self._checked >= PATH_CHECK_S:
            self._checked = time.monotonic()
            now = self._identity()
            if now is None:
                raise Disconnected("port_removed", self.url)
            if now != self._device:
                raise Disconnected("port_replaced", self.url)
        return b""

    def write(self, data: bytes) -> None:
        self._ser.write(data)

    def close(self) -> None:
        try:
            self._ser.close()
        except Exception:
            pass


class UdpTransport:
    """A UDP socket bound to HOST:PORT (pymavlink's ``udp:``/``udpin:``)."""

    def __init__(self, host: str, port: int):
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self._sock.bind((host, port))
        self._sock.settimeout(READ_TIMEOUT_S)
        self._peer: tuple | None = None  # who sent the last datagram: where replies go

    def read(self) -> bytes:
        try:
            data, self._peer = self._sock.recvfrom(MAX_READ)
            return data
        except TimeoutError:
            return b""

    def write(self, data: bytes) -> None:
        if self._peer is None:
            raise OSError("nothing heard yet on this UDP port: no one to send to")
        self._sock.sendto(data, self._peer)

    def close(self) -> None:
        self._sock.close()


class SerialOpener:
    """Opens a SerialTransport; for a device path it can also tell when the path (re)appears."""

    def __init__(self, url: str, baudrate: int = 115200):
        self.url = url
        self.baudrate = baudrate
        self.path = None if "://" in url else url

    def __call__(self) -> Transport:
        return SerialTransport(self.url, self.baudrate)

    def present(self) -> bool:
        """False only when the device path is known to be missing."""
        return self.path is None or os.path.exists(self.path)


def parse_udp(spec: str) -> tuple[str, int]:
    """``udp:[HOST:]PORT`` or ``udpin:[HOST:]PORT`` to the (host, port) to listen on.

    A missing host listens on every interface, as instrument multiplexers broadcast (NMEA on 10110).
    """
    scheme, _, rest = spec.partition(":")
    host, _, port = rest.rpartition(":")
    if scheme not in ("udp", "udpin") or not port.isdigit() or not 0 < int(port) < 65536:
        raise ValueError(
            f"bad UDP source {spec!r}: expected udp:PORT or udp:HOST:PORT with a port from 1 to 65535"
        )
    return host or "0.0.0.0", int(port)


class UdpOpener:
    """Opens a UdpTransport listening on (host, port)."""

    def __init__(self, host: str, port: int):
        self.host = host
        self.port = port

    def __call__(self) -> Transport:
        return UdpTransport(self.host, self.port)
