"""The live view for every client: `foxglove.websocket.v1` (the ws-protocol spec, Lichtblick) as well as
the sdk's `foxglove.sdk.v1`, through `host/live/front.py` to the real foxglove-sdk server.

A client offering only the spec's name gets the track (`/fix`) and the growing maps (`/map/*`) of a
replayed survey, decoded and valid against their advertised schemas; nothing here times the machine
(the log is offered as fast as the publisher takes it, the maps follow the log's own time).
"""

from __future__ import annotations

import asyncio

import pytest
import websockets
from forcemap.host.cli.replay import _stream
from forcemap.host.live.front import SDK, SPEC, request_for_sdk, response_for_client
from forcemap.host.live.service import LiveService

from bench.live_client import SPEC_SUBPROTOCOL, SUBPROTOCOL, LiveClient, survey_log

UPGRADE = (
    b"GET / HTTP/1.1\r\nHost: 127.0.0.1:8765\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
    b"Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n"
)


def test_only_the_name_is_translated():
    spec = UPGRADE + b"sec-websocket-protocol: foxglove.websocket.v1\r\n\r\n"
    head, translated = request_for_sdk(spec)
    assert translated and b"\r\nSec-WebSocket-Protocol: foxglove.sdk.v1\r\n" in head
    assert set(head.split(b"\r\n")) - set(spec.split(b"\r\n")) == {
        b"Sec-WebSocket-Protocol: foxglove.sdk.v1"
    }
    assert b"foxglove.websocket.v1" not in head and head.count(b"Sec-WebSocket-Key") == 1
    # a client offering both, or only the sdk's name, or another name: untouched
    for offer in (b"foxglove.websocket.v1, foxglove.sdk.v1", b"foxglove.sdk.v1", b"chat"):
        other = UPGRADE + b"Sec-WebSocket-Protocol: " + offer + b"\r\n\r\n"
        assert request_for_sdk(other) == (other, False)
    answer = (
        b"HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
        b"Sec-WebSocket-Accept: s3pPLMBiTxaQ9kYGzzhZRbK+xOo=\r\nSec-WebSocket-Protocol: foxglove.sdk.v1\r\n\r\n"
    )
    back = response_for_client(answer)
    assert b"Sec-WebSocket-Protocol: foxglove.websocket.v1" in back
    assert (
        back.replace(b"foxglove.websocket.v1", b"foxglove.sdk.v1").split(b"\r\n")[0]
        == (answer.split(b"\r\n")[0])
    )
    assert b"s3pPLMBiTxaQ9kYGzzhZRbK+xOo=" in back  # the handshake's proof is the sdk's own


@pytest.mark.slow
def test_a_client_speaking_only_the_spec_name_gets_the_track_and_the_maps(tmp_path):
    path, n = survey_log(tmp_path / "log")
    live = LiveService("127.0.0.1", 0, every_s=60.0)
    url = f"ws://127.0.0.1:{live.server.port}"
    spec = LiveClient(url, subprotocols=(SPEC_SUBPROTOCOL,))
    sdk = LiveClient(url)
    try:
        for c in (spec, sdk):
            c.wait_ready()
            c.wait_for(lambda c: live.server.stats()["subscriptions"] >= 2 * len(c.channels), 60)
        _stream(live, [path], speed=1e6)
        # bounds that hold on a loaded 2-core machine: the map process runs at a low priority and may
        # still be catching up; a wait that fails says what the server and the sdk's client saw
        def why() -> str:
            front = live.server.front
            return (
                f"server {live.server.stats()}; the sdk's client {sdk.topics()}; the front sent "
                f"{front.sent}, ended {front.ended}"
            )

        spec.wait_for(lambda c: c.topics().get("/fix", 0) == n, 600, why)
        spec.wait_for(lambda c: c.topics().get("/map/current", 0) >= 3, 600, why)
    finally:
        live.close(final_maps_s=120.0)
        spec.close()
        sdk.close()
    assert spec.subprotocol == SPEC_SUBPROTOCOL and sdk.subprotocol == SUBPROTOCOL
    assert live.server.front.spec_clients == 1
    assert not spec.invalid, spec.invalid[:5]
    got = spec.topics()
    for topic in ("/map/current", "/map/wind", "/map/depth", "/map/info", "/map/layers/depth"):
        assert got.get(topic, 0) >= 1, (topic, got)
    # the same bytes as the sdk's own client got, for every logged message
    fixes = [m for m in spec.messages if m[0] == "/fix"]
    assert fixes == [m for m in sdk.messages if m[0] == "/fix"]
    lats = [m for m in fixes if b'"latitude"' in m[2]]
    assert len(lats) == n


def test_a_name_neither_speaks_is_still_refused():
    live = LiveService("127.0.0.1", 0, maps=False)

    async def connect(protocols):
        async with websockets.connect(
            f"ws://127.0.0.1:{live.server.port}", subprotocols=protocols
        ) as ws:
            return ws.subprotocol

    try:
        assert asyncio.run(connect([SPEC])) == SPEC
        assert asyncio.run(connect([SDK])) == SDK
        with pytest.raises(websockets.exceptions.InvalidStatus) as refused:
            asyncio.run(connect(["chat"]))
        assert refused.value.response.status_code == 400
    finally:
        live.close()
