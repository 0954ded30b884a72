"""A Foxglove WebSocket client for the tests: the `websockets` package speaking the sdk's protocol.

It subscribes to every channel the server advertises (also those advertised later), decodes each
message against its advertised JSON schema, and keeps (topic, log_time, payload bytes). ``stall``
subscribes and then never reads again: a client whose socket fills up.
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


class LiveClient:
    def __init__(
        self, url: str, *, stall: bool = False, subprotocols: tuple[str, ...] = (SUBPROTOCOL,)
    ):
        self.url, self.stall, self.offered = url, stall, list(subprotocols)
        self.channels: dict[int, dict] = {}
        self.subs: dict[int, int] = {}  # subscription id -> channel id
        self.messages: list[tuple[str, int, bytes]] = []
        self.invalid: list[str] = []
        self.server_info: dict | None = None
        self.subprotocol: str | None = None
        self._validators: dict[int, jsonschema.protocols.Validator] = {}
        self._stop = threading.Event()
        self._ready = threading.Event()
        self.error: BaseException | None = None
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
        if self.stall:  # the smallest buffers: the server sees a slow client at once
            kw |= {"max_queue": 1}
        async with websockets.connect(self.url, subprotocols=self.offered, **kw) as ws:
            self.subprotocol = ws.subprotocol
            while not self._stop.is_set():
                try:
                    raw = await asyncio.wait_for(ws.recv(), 0.2)
                except TimeoutError:
                    continue
                if isinstance(raw, str):
                    await self._control(ws, json.loads(raw))
                    if self.stall and self.subs:
                        self._ready.set()
                        while not self._stop.is_set():
                            await asyncio.sleep(0.1)  # never read again
                        return
                else:
                    self._data(raw)

    async def _control(self, ws, msg: dict) -> None:
        op = msg.get("op")
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
                new.append({"id": sub, "channelId": ch["id"]})
            await ws.send(json.dumps({"op": "subscribe", "subscriptions": new}))

    def _data(self, raw: bytes) -> None:
        assert raw[0] == MESSAGE_DATA, raw[:1]
        sub, log_time = struct.unpack_from("<IQ", raw, 1)
        payload = bytes(raw[13:])
        channel = self.channels[self.subs[sub]]
        errors = list(self._validators[channel["id"]].iter_errors(json.loads(payload)))
        if errors:
            self.invalid.append(f"{channel['topic']}: {errors[0].message}")
        self.messages.append((channel["topic"], log_time, payload))

    def wait_ready(self, timeout: float = 30.0) -> None:
        assert self._ready.wait(timeout), "no serverInfo from the live server"
        if self.error is not None:
            raise self.error

    def wait_for(self, pred, timeout: float = 120.0) -> None:
        deadline = time.monotonic() + timeout
        while not pred(self):
            assert time.monotonic() < deadline, f"timed out; topics {self.topics()}"
            assert self.error is None, self.error
            time.sleep(0.05)

    def topics(self) -> dict[str, int]:
        out: dict[str, int] = {}
        for topic, _, _ in list(self.messages):
            out[topic] = out.get(topic, 0) + 1
        return out

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
