"""The live view's public port: accepts `foxglove.websocket.v1` as well as the sdk's `foxglove.sdk.v1`.

foxglove-sdk (0.30) answers HTTP 400 to a client that offers only `foxglove.websocket.v1`, the name
in the ws-protocol spec that Lichtblick, older Foxglove apps and the npm reference client
(`@foxglove/ws-protocol`) speak. Foxglove's stance is that the two names are one protocol today, so
this front does no more than translate the name: it reads a client's HTTP upgrade request, offers
`foxglove.sdk.v1` to the sdk's server (on 127.0.0.1, a port of its own) in its place, gives the
client back the name it asked for, and then copies bytes both ways untouched. WebSocket frames,
their masks and any compression are between the client and the sdk. A slow client still backs up
the sdk's socket (each direction waits for the other side to take its bytes), so the sdk's
per-client outbox and its drop warnings work as without the front.
"""

from __future__ import annotations

import asyncio
import contextlib
import threading
import time
from collections.abc import Callable

SDK = "foxglove.sdk.v1"
SPEC = "foxglove.websocket.v1"
HEADER = b"sec-websocket-protocol"
MAX_HEAD = 64 * 1024  # an upgrade request's headers; more is not a WebSocket client
BUFFER = 64 * 1024


def _offered(head: bytes) -> list[str]:
    """The subprotocols a request's ``Sec-WebSocket-Protocol`` headers offer, in order."""
    names: list[str] = []
    for line in head.split(b"\r\n")[1:]:
        name, sep, value = line.partition(b":")
        if sep and name.strip().lower() == HEADER:
            names += [v.strip().decode("latin-1") for v in value.split(b",") if v.strip()]
    return names


def _with_protocol(head: bytes, protocols: str | None) -> bytes:
    """``head`` with its ``Sec-WebSocket-Protocol`` headers replaced by one naming ``protocols``."""
    lines = head.split(b"\r\n")
    kept = [ln for ln in lines[1:] if ln.partition(b":")[0].strip().lower() != HEADER]
    if protocols is not None:
        kept.insert(0, b"Sec-WebSocket-Protocol: " + protocols.encode("latin-1"))
    return b"\r\n".join([lines[0], *kept])


def request_for_sdk(head: bytes) -> tuple[bytes, bool]:
    """The request to hand the sdk, and whether the client spoke the spec's name only.

    A client that offers `foxglove.sdk.v1` is passed as it is; one that offers `foxglove.websocket.v1`
    without it is offered to the sdk as `foxglove.sdk.v1`; anything else goes through untouched, and
    the sdk refuses it as it would without the front."""
    offered = _offered(head)
    if SDK in offered or SPEC not in offered:
        return head, False
    return _with_protocol(head, SDK), True


def response_for_client(head: bytes) -> bytes:
    """The sdk's answer with the spec's name where the sdk named its own."""
    if _offered(head) == [SDK]:
        return _with_protocol(head, SPEC)
    return head


async def _pipe(
    reader: asyncio.StreamReader,
    writer: asyncio.StreamWriter,
    moved: Callable[[int], None] | None = None,
) -> None:
    try:
        while data := await reader.read(BUFFER):
            if moved is not None:
                moved(len(data))
            writer.write(data)
            await writer.drain()  # a slow reader on the other side holds this side back
    except (ConnectionError, OSError):
        pass
    finally:
        with contextlib.suppress(Exception):
            writer.close()


class SubprotocolFront:
    """A TCP listener on ``host:port`` in front of the sdk's server on ``127.0.0.1:backend_port``.

    It runs its own asyncio loop on a daemon thread; ``port`` is the port it got (``port=0``: any)."""

    def __init__(self, host: str, port: int, backend_port: int):
        self.backend_port = backend_port
        self.spec_clients = 0  # connections that asked for foxglove.websocket.v1 only
        # the address the sdk sees (this front's end of the connection) -> the client's own
        self.peers: dict[str, str] = {}
        self._loop = asyncio.new_event_loop()
        self._server: asyncio.base_events.Server | None = None
        self._tasks: set[asyncio.Task] = set()
        self.last_moved = time.monotonic()  # the last bytes from the sdk towards a viewer
        # by viewer (its address): the bytes passed towards it, and how its connection ended
        self.sent: dict[str, int] = {}
        self.ended: dict[str, str] = {}
        started = threading.Event()
        failure: list[BaseException] = []

        def main() -> None:
            asyncio.set_event_loop(self._loop)
            try:
                self._server = self._loop.run_until_complete(
                    asyncio.start_server(self._client, host, port, limit=MAX_HEAD)
                )
            except BaseException as exc:  # noqa: BLE001 - handed to the constructor's caller
                failure.append(exc)
                started.set()
                return
            started.set()
            self._loop.run_forever()

        self._thread = threading.Thread(target=main, name="forcemap-live-front", daemon=True)
        self._thread.start()
        started.wait()
        if failure:
            self._thread.join()
            self._loop.close()
            raise failure[0]
        assert self._server is not None
        self.port = self._server.sockets[0].getsockname()[1]

    async def _client(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        task = asyncio.current_task()
        if task is not None:
            self._tasks.add(task)
        up_writer = None
        peer = writer.get_extra_info("peername")
        who = f"{peer[0]}:{peer[1]}" if peer else "?"  # the viewer's address
        try:
            head = await reader.readuntil(b"\r\n\r\n")
            head, spec = request_for_sdk(head)
            self.spec_clients += spec
            up_reader, up_writer = await asyncio.open_connection(
                "127.0.0.1", self.backend_port, limit=MAX_HEAD
            )
            seen = up_writer.get_extra_info("sockname")
            if seen and peer:
                self.peers[f"{seen[0]}:{seen[1]}"] = who
            up_writer.write(head)
            await up_writer.drain()
            answer = await up_reader.readuntil(b"\r\n\r\n")
            writer.write(response_for_client(answer) if spec else answer)
            await writer.drain()
            self.sent[who] = 0
            await asyncio.gather(
                _pipe(reader, up_writer), _pipe(up_reader, writer, lambda n: self._moved(who, n))
            )
            self.ended[who] = "closed"
        except (asyncio.IncompleteReadError, asyncio.LimitOverrunError, ConnectionError, OSError):
            pass  # not a WebSocket client, or it went away: nothing to serve
        except Exception as exc:  # noqa: BLE001 - one viewer's failure must not stop the front
            self.ended[who] = repr(exc)
        finally:
            for w in (writer, up_writer):
                if w is not None:
                    with contextlib.suppress(Exception):
                        w.close()
            if task is not None:
                self._tasks.discard(task)

    def _moved(self, who: str, n: int) -> None:
        self.last_moved = time.monotonic()
        self.sent[who] = self.sent.get(who, 0) + n

    def settle(self, quiet_s: float = 1.0, timeout_s: float = 10.0) -> None:
        """Wait until no bytes have gone towards a viewer for ``quiet_s`` (at most ``timeout_s``), so
        what the sdk still holds for a viewer that is behind reaches it before the connections drop.
        A stalled viewer moves nothing, so it does not hold this up."""
        end = time.monotonic() + timeout_s
        while time.monotonic() < end and time.monotonic() - self.last_moved < quiet_s:
            time.sleep(0.05)

    async def _close(self) -> None:
        if self._server is not None:
            self._server.close()
        for task in list(self._tasks):
            task.cancel()
        await asyncio.gather(*self._tasks, return_exceptions=True)

    def close(self) -> None:
        """Stop listening and drop every connection (the sdk's server is stopped by its owner)."""
        if self._loop.is_closed():
            return
        with contextlib.suppress(RuntimeError):
            asyncio.run_coroutine_threadsafe(self._close(), self._loop).result(10)
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(10)
        self._loop.close()
