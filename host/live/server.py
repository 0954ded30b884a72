"""The Foxglove WebSocket server (the official foxglove-sdk): one JSON channel per topic, schema from the record.

Clients connect to `host/live/front.py`, which lets those speaking the ws-protocol spec's
`foxglove.websocket.v1` (Lichtblick, the npm reference client) in beside the sdk's `foxglove.sdk.v1`.

Each client's outbox is the sdk's (``message_backlog_size`` messages; the oldest is dropped when it is
full, and the sdk logs "outbox for client ... full"). Those warnings are counted per client here, so
`/health` shows who is too slow. The sdk is imported only when a server is started.
"""

from __future__ import annotations

import json
import logging
import re
import threading
from typing import Any

from forcemap.host.errors import CliError
from forcemap.host.extras import install_hint
from forcemap.host.live.front import SubprotocolFront
from forcemap.host.log.live_messages import LIVE_TOPIC_TYPES, MAP_TARGETS
from forcemap.host.log.mcap import schema_for
from forcemap.host.log.messages import TOPIC_TYPES

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8765
BACKLOG = 1024
# topics a new one of which (/mavlink/<MSG>, /raw/<source>) is advertised when first logged: a client
# subscribes on the advertisement, so it misses that first message
KNOWN_TOPICS = (
    *TOPIC_TYPES,
    *LIVE_TOPIC_TYPES,
    *(f"/map/{t}" for t in MAP_TARGETS),
    *(f"/map/layers/{t}" for t in (*MAP_TARGETS, "samples")),
)
PUBLIC_WARNING = (
    "live view on {host}:{port}: anyone on that network can watch the boat, its track and its "
    "maps (no password, no encryption); bind to 127.0.0.1 and use an SSH tunnel to keep it private"
)


def parse_address(text: str | None) -> tuple[str, int]:
    """``HOST:PORT``, ``HOST`` or ``:PORT`` (``None``: Foxglove's default, 127.0.0.1:8765)."""
    if not text:
        return DEFAULT_HOST, DEFAULT_PORT
    host, sep, port = text.rpartition(":")
    if not sep:
        host, port = text, str(DEFAULT_PORT)
    host = host.strip("[]") or DEFAULT_HOST
    try:
        number = int(port)
    except ValueError:
        number = -1
    if not 0 <= number <= 65535:
        raise CliError(f"--live {text}: give HOST:PORT, e.g. 127.0.0.1:8765 or 0.0.0.0:8765")
    return host, number


def is_private(host: str) -> bool:
    """Only the machine itself can connect."""
    return host in ("127.0.0.1", "localhost", "::1") or host.startswith("127.")


def require_sdk() -> Any:
    """The foxglove module, or the one-line install hint (exit 2)."""
    try:
        import foxglove
    except ImportError:
        raise CliError(f"the live view needs foxglove-sdk: {install_hint('live')}") from None
    return foxglove


class _DropCounter(logging.Handler):
    """Counts the sdk's "outbox for client ADDR full" warnings (and the drops they report) per client."""

    PATTERN = re.compile(r"outbox for client (\S+) full(?:.*?(\d+) dropped)?")

    def __init__(self, server: LiveServer):
        super().__init__(logging.INFO)
        self.server = server

    def emit(self, record: logging.LogRecord) -> None:
        m = self.PATTERN.search(record.getMessage())
        if m:
            self.server.note_drop(m.group(1), int(m.group(2) or 1))


class LiveServer:
    """Publishes bytes on JSON channels created on first use; knows its clients and their subscriptions."""

    def __init__(self, host: str = DEFAULT_HOST, port: int = DEFAULT_PORT, backlog: int = BACKLOG):
        foxglove = require_sdk()
        self._fg = foxglove
        self._lock = threading.Lock()
        self.clients: dict[int, dict[str, Any]] = {}
        self.client_drops: dict[str, int] = {}
        self.channels: dict[str, Any] = {}
        # topic -> (schema name, JSON schema) where a log says otherwise than this version's records
        self.schemas: dict[str, tuple[str, dict[str, Any]]] = {}
        handler = _DropCounter(self)
        sdk_log = logging.getLogger("foxglove")
        sdk_log.addHandler(handler)
        sdk_log.propagate = False
        sdk_log.setLevel(logging.INFO)
        foxglove.set_log_level("INFO")  # forwards the sdk's own log to `logging` (first call only)
        try:  # the sdk on a private port; the front takes the address asked for (both names)
            self.server = foxglove.start_server(
                name="forcemap",
                host="127.0.0.1",
                port=0,
                server_listener=self,
                message_backlog_size=backlog,
            )
        except Exception as exc:  # no port left on this machine
            raise CliError(f"cannot start the live view's server: {exc}") from None
        try:
            self.front = SubprotocolFront(host, port, self.server.port)
        except OSError as exc:  # the port is taken, the address is not this machine's
            self.server.stop()
            raise CliError(f"cannot start the live view on {host}:{port}: {exc}") from None
        self.host, self.port = host, self.front.port
        for topic in KNOWN_TOPICS:  # advertised from the start: a client sees their first message
            self.channel(topic)

    # ---- the sdk's ServerListener protocol
    def on_subscribe(self, client: Any, channel: Any) -> None:
        with self._lock:
            c = self.clients.setdefault(client.id, {"topics": set()})
            c["topics"].add(channel.topic)

    def on_unsubscribe(self, client: Any, channel: Any) -> None:
        with self._lock:
            c = self.clients.get(client.id)
            if c is not None:
                c["topics"].discard(channel.topic)
                if not c["topics"]:
                    del self.clients[client.id]

    def note_drop(self, client: str, n: int) -> None:
        client = self.front.peers.get(client, client)  # the sdk sees the front's address
        with self._lock:
            self.client_drops[client] = self.client_drops.get(client, 0) + n

    # ---- publishing
    def channel(self, topic: str, message: Any = None) -> Any:
        ch = self.channels.get(topic)
        if ch is None:
            name, schema = self.schemas.get(topic) or schema_for(topic, message)
            fg = self._fg
            ch = fg.Channel(
                topic,
                schema=fg.Schema(
                    name=name, encoding="jsonschema", data=json.dumps(schema).encode()
                ),
                message_encoding="json",
            )
            self.channels[topic] = ch
        return ch

    def publish(self, topic: str, log_time_ns: int, data: bytes, message: Any = None) -> None:
        self.channel(topic, message).log(data, log_time=int(log_time_ns))

    def stats(self) -> dict[str, Any]:
        with self._lock:
            return {
                "address": f"{self.host}:{self.port}",
                "clients": len(self.clients),
                "subscriptions": sum(len(c["topics"]) for c in self.clients.values()),
                "client_outbox_drops": dict(self.client_drops),
            }

    def stop(self) -> None:
        """Let the viewers take what is on its way to them (bounded), then close."""
        self.front.settle()
        self.front.close()
        self.server.stop()
