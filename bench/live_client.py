"""A Foxglove WebSocket client for the tests: the `websockets` package speaking the sdk's protocol.

It subscribes to every channel the server advertises (also those advertised later) and keeps every
message as (topic, log_time, payload bytes); ``invalid`` checks each against its advertised JSON
schema. ``stall`` subscribes and then never reads again: a client whose socket fills up.

The client's event loop only receives: a frame is kept as it came and counted by topic, and the
decoding and the schema checks run when ``messages`` or ``invalid`` is read, in the reader's thread.
Three clients in one test process share one GIL; when each also checked every message in its loop,
they fell behind the daemon on a busy machine, their pongs queued behind megabytes of unread messages,
and websockets closed with "1011 keepalive ping timeout" while the server had answered every ping in
time (docs/LIVE.md, "A viewer that falls behind").
"""

from __future__ import annotations

import asyncio
import json
import struct
import threading
import time

import jsonschema
import websockets
from forcemap.host.log.mcap import McapLog
from forcemap.host.log.messages import SAMPLE_COLUMNS, Sample
from forcemap.host.log.record import LocationFix, Time

from bench.synth_survey import simulate

SUBPROTOCOL = "foxglove.sdk.v1"  # what foxglove-sdk 0.30 speaks
# the ws-protocol spec's name (Lichtblick, @foxglove/ws-protocol); host/live/front.py accepts it too
SPEC_SUBPROTOCOL = "foxglove.websocket.v1"
MESSAGE_DATA = 1
# (schema, payload) -> its first schema error or None: clients of one server get the same messages
_VERDICTS: dict[tuple[str, bytes], str | None] = {}
_VERDICTS_MAX = 500_000


def _verdict(schema: str, validator: jsonschema.protocols.Validator, payload: bytes) -> str | None:
    key = (schema, payload)
    if key not in _VERDICTS:
        if len(_VERDICTS) >= _VERDICTS_MAX:
            _VERDICTS.clear()
        error = next(iter(validator.iter_errors(json.loads(payload))), None)
        _VERDICTS[key] = None if error is None else error.message
    return _VERDICTS[key]


class LiveClient:
    def __init__(
        self, url: str, *, stall: bool = False, subprotocols: tuple[str, ...] = (SUBPROTOCOL,)
    ):
        self.url, self.stall, self.offered = url, stall, list(subprotocols)
        self.channels: dict[int, dict] = {}
        self.subs: dict[int, int] = {}  # subscription id -> channel id
        self.server_info: dict | None = None
        self.subprotocol: str | None = None
        self._frames: list[bytes] = []  # every binary frame, as received
        self._counts: dict[str, int] = {}  # topic -> messages received
        self._sub_topic: dict[int, str] = {}
        self._decoded: list[tuple[str, int, bytes]] = []
        self._invalid: list[str] = []
        self._checked = 0
        self._validators: dict[int, jsonschema.protocols.Validator] = {}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._ready = threading.Event()
        self.error: BaseException | None = None
        self.closed: str | None = None  # how the server ended the connection, when it did
        self.ops: dict[str, int] = {}  # the server's text messages, by op (advertise, status, ...)
        self.thread = threading.Thread(target=self._main, daemon=True)
        self.thread.start()

    def _main(self) -> None:
        try:
            asyncio.run(self._run())
        except BaseException as exc:  # noqa: BLE001 - reported by the test
            self.error = exc
            self._ready.set()

    async def _run(self) -> None:
        kw = {"max_size": None}
        if self.stall:  # the smallest buffers: the server sees a slow client at once; no pings,
            kw |= {"max_queue": 1, "ping_interval": None}  # whose timeout would close it after 40 s
        async with websockets.connect(self.url, subprotocols=self.offered, **kw) as ws:
            self.subprotocol = ws.subprotocol
            closer = asyncio.create_task(self._close_when_stopped(ws))
            async for raw in ws:
                if isinstance(raw, str):
                    await self._control(ws, json.loads(raw))
                    if self.stall and self.subs:
                        self._ready.set()
                        await closer  # never read again
                        return
                else:
                    assert raw[0] == MESSAGE_DATA, raw[:1]
                    self._frames.append(raw)
                    topic = self._sub_topic[int.from_bytes(raw[1:5], "little")]
                    self._counts[topic] = self._counts.get(topic, 0) + 1
            self.closed = f"code {ws.close_code} {ws.close_reason!r}"
            closer.cancel()

    async def _close_when_stopped(self, ws) -> None:
        while not self._stop.is_set():
            await asyncio.sleep(0.1)
        await ws.close()

    async def _control(self, ws, msg: dict) -> None:
        op = msg.get("op")
        self.ops[str(op)] = self.ops.get(str(op), 0) + 1
        if op == "serverInfo":
            self.server_info = msg
            self._ready.set()
        elif op == "advertise":
            new = []
            for ch in msg["channels"]:
                self.channels[ch["id"]] = ch
                assert ch["encoding"] == "json" and ch["schemaEncoding"] == "jsonschema", ch
                self._validators[ch["id"]] = jsonschema.Draft202012Validator(
                    json.loads(ch["schema"])
                )
                sub = len(self.subs) + 1
                self.subs[sub] = ch["id"]
                self._sub_topic[sub] = ch["topic"]
                new.append({"id": sub, "channelId": ch["id"]})
            await ws.send(json.dumps({"op": "subscribe", "subscriptions": new}))

    @property
    def messages(self) -> list[tuple[str, int, bytes]]:
        """(topic, log_time, payload) of every message so far, in the order received."""
        with self._lock:
            for raw in self._frames[len(self._decoded) : len(self._frames)]:
                sub, log_time = struct.unpack_from("<IQ", raw, 1)
                self._decoded.append((self._sub_topic[sub], log_time, bytes(raw[13:])))
            return self._decoded

    @property
    def invalid(self) -> list[str]:
        """Each message so far that its advertised schema rejects, as "topic: error"."""
        frames = self._frames[: len(self._frames)]
        with self._lock:
            for raw in frames[self._checked :]:
                channel = self.channels[self.subs[struct.unpack_from("<I", raw, 1)[0]]]
                error = _verdict(
                    channel["schema"], self._validators[channel["id"]], bytes(raw[13:])
                )
                if error is not None:
                    self._invalid.append(f"{channel['topic']}: {error}")
            self._checked = len(frames)
            return self._invalid

    def wait_ready(self, timeout: float = 30.0) -> None:
        assert self._ready.wait(timeout), "no serverInfo from the live server"
        if self.error is not None:
            raise self.error

    def wait_for(self, pred, timeout: float = 120.0, why=None) -> None:
        """Wait until ``pred(self)``; fail at once if the connection has ended, else after ``timeout``
        seconds, with what this client got and ``why()`` (the server's side, say) in the message."""
        deadline = time.monotonic() + timeout
        while not pred(self):
            if self.error is not None:
                failed = repr(self.error)
            elif self.closed is not None:
                failed = f"the server closed the connection ({self.closed})"
            elif time.monotonic() >= deadline:
                failed = "timed out"
            else:
                time.sleep(0.05)
                continue
            extra = "" if why is None else f"; {why()}"
            raise AssertionError(f"{failed}; topics {self.topics()}, ops {self.ops}{extra}")

    def topics(self) -> dict[str, int]:
        """Messages received so far, by topic."""
        return dict(self._counts)

    def close(self) -> None:
        self._stop.set()
        self.thread.join(10)


def survey_log(log_dir, duration_s: float = 400, seed: int = 4):
    """A synthetic survey's MCAP with ``/samples`` and ``/fix`` (what `replay --live` streams and maps):
    its path and the number of rows."""
    cols = simulate(duration_s=duration_s, seed=seed)
    log = McapLog(log_dir)
    for i in range(len(cols["t"])):
        t_ns = int(cols["t"][i] * 1e9)
        row = {k: float(cols[k][i]) for k in cols if k in SAMPLE_COLUMNS}
        log.write("/samples", t_ns, Sample(**row))
        fix = LocationFix(
            Time(t_ns // 10**9, t_ns % 10**9), "", float(cols["lat"][i]), float(cols["lon"][i]),
            0.0, [0.0] * 9, 0,
        )  # fmt: skip
        log.write("/fix", t_ns, fix)
    log.close()
    return log.path, len(cols["t"])
