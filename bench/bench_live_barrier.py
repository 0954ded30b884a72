"""Can a client learn, in the stream, when its subscription took effect? (bench/RESULTS.md, "The suite's
last minute": the live test's failure.)

    python -m bench.bench_live_barrier [--messages 20000]

A foxglove-sdk server queues `--messages` messages for a subscribed client that has not read yet; the client
then asks for something the server answers in the stream (a subscription to an unknown channel, answered
by a `status`), and counts the data messages it reads before the answer. Fewer than were queued: the
answer overtakes the queue, so it cannot mark the point where a subscription took effect.
"""

from __future__ import annotations

import argparse
import asyncio
import json

import foxglove
import websockets


async def count_before_status(port: int, channel, n: int) -> int:
    """The data messages read before the status answer, after `n` were queued."""
    url = f"ws://127.0.0.1:{port}"
    async with websockets.connect(url, subprotocols=["foxglove.sdk.v1"], max_size=None) as ws:
        await ws.recv()  # serverInfo
        advertised = json.loads(await ws.recv())
        sub = {"id": 1, "channelId": advertised["channels"][0]["id"]}
        await ws.send(json.dumps({"op": "subscribe", "subscriptions": [sub]}))
        await asyncio.sleep(0.5)
        for i in range(n):
            channel.log(json.dumps({"i": i}).encode() + b" " * 200, log_time=i)
        unknown = {"id": 9, "channelId": 2**31 - 1}
        await ws.send(json.dumps({"op": "subscribe", "subscriptions": [unknown]}))
        seen = 0
        while not isinstance(await asyncio.wait_for(ws.recv(), 10), str):
            seen += 1
        return seen


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--messages", type=int, default=20000)
    a = p.parse_args()
    server = foxglove.start_server(
        name="barrier", host="127.0.0.1", port=0, message_backlog_size=10 * a.messages
    )
    schema = foxglove.Schema(name="a", encoding="jsonschema", data=b"{}")
    channel = foxglove.Channel("/a", schema=schema, message_encoding="json")
    try:
        seen = asyncio.run(count_before_status(server.port, channel, a.messages))
    finally:
        server.stop()
    print(f"the status answer came after {seen} of {a.messages} queued messages")


if __name__ == "__main__":
    main()
