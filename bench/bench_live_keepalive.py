"""Who leaves a viewer's ping unanswered on a busy machine: the live server, or the viewer itself?

    python bench/bench_live_keepalive.py                        # the machine as it is
    python bench/bench_live_keepalive.py --burn 5 --boost 19    # the failure of issue 38, on demand

The scene of tests/test_live.py::test_live_clients_see_what_the_mcap_holds (its daemon with `--live`,
its simulated river at x40, its clients: two from the start, one that stalls, one that joins after
40 samples), with two kinds of witness:

- the test's clients (`bench.live_client.LiveClient`, three in this process, one GIL), each also
  sending a ping every second and noting its round trip and the bytes waiting unread in its own
  socket when the ping left;
- a lean client in a process of its own (no decoding, no schema checks), pinging every 0.5 s: what
  the server answers to a viewer that keeps up.

``--burn N`` starts N processes spinning Python; ``--boost K`` renices the daemon's and simulator's
threads to -K, so the producers run at their pace while the readers compete with the spinners for
what is left: the idle CI machine of issue 38, where the simulator ran at its full x40. Figures:
messages, the client thread's CPU, ping round trips (max, median), the unread bytes behind the worst,
and any error (websockets' "1011 keepalive ping timeout" closes a client whose pong waits > 20 s).
"""

from __future__ import annotations

import argparse
import asyncio
import fcntl
import json
import multiprocessing as mp
import os
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import termios
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.live_client import SUBPROTOCOL, LiveClient  # noqa: E402

LEAN = """
import asyncio, json, sys, time, websockets
async def main(url):
    rtts, n = [], 0
    async with websockets.connect(url, subprotocols=[@SUBPROTOCOL@], max_size=None, ping_interval=None) as ws:
        async def pinger():
            while True:
                t0 = time.monotonic()
                await (await ws.ping())
                rtts.append(time.monotonic() - t0)
                await asyncio.sleep(0.5)
        task = None
        try:
            async for raw in ws:
                if isinstance(raw, str):
                    msg = json.loads(raw)
                    if msg.get("op") == "advertise":
                        subs = [{"id": c["id"], "channelId": c["id"]} for c in msg["channels"]]
                        await ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
                    task = task or asyncio.create_task(pinger())
                else:
                    n += 1
        except websockets.ConnectionClosed:
            pass
    print(json.dumps({"messages": n, "pings": len(rtts), "rtt_max_s": max(rtts, default=None),
                      "rtt_median_s": sorted(rtts)[len(rtts) // 2] if rtts else None}))
asyncio.run(main(sys.argv[1]))
""".replace("@SUBPROTOCOL@", repr(SUBPROTOCOL))


def _burn(stop) -> None:
    x = 0
    while not stop.is_set():
        for i in range(100_000):
            x += i * i


def _unread(ws) -> int:
    sock = ws.transport.get_extra_info("socket")
    return struct.unpack("i", fcntl.ioctl(sock.fileno(), termios.FIONREAD, struct.pack("i", 0)))[0]


class Witness(LiveClient):
    """The test's client, also pinging every second: (round trip or None, unread bytes at the ping)."""

    def __init__(self, url: str, name: str):
        self.name, self.pings, self._pinging = name, [], False
        super().__init__(url)

    async def _pinger(self, ws) -> None:
        while not self._stop.is_set():
            t0, unread = time.monotonic(), _unread(ws)
            try:
                await asyncio.wait_for(await ws.ping(), 60)
            except Exception:  # noqa: BLE001 - the connection closed: the error is the client's
                return
            self.pings.append((time.monotonic() - t0, unread))
            await asyncio.sleep(1.0)

    async def _control(self, ws, msg: dict) -> None:
        if not self._pinging:
            self._pinging = True
            asyncio.get_running_loop().create_task(self._pinger(ws))
        await super()._control(ws, msg)

    def _main(self) -> None:
        try:
            super()._main()
        finally:
            self.thread_cpu = time.thread_time()

    def figures(self) -> dict:
        rtts = sorted(p[0] for p in self.pings)
        worst = max(self.pings, default=(None, None))
        return {
            "messages": len(self.messages),
            "thread_cpu_s": round(getattr(self, "thread_cpu", float("nan")), 2),
            "pings": len(rtts),
            "rtt_max_s": round(rtts[-1], 3) if rtts else None,
            "rtt_median_s": round(rtts[len(rtts) // 2], 4) if rtts else None,
            "unread_bytes_at_worst": worst[1],
            "error": None if self.error is None else str(self.error)[:80],
        }


def _boost(pids: list[int], nice: int, until) -> None:
    while not until():
        for pid in pids:
            for task in os.listdir(f"/proc/{pid}/task") if os.path.isdir(f"/proc/{pid}/task") else []:
                try:
                    os.setpriority(os.PRIO_PROCESS, int(task), nice)
                except OSError:
                    pass
        time.sleep(0.5)


def run(burn: int, boost: int) -> dict:
    from tests import test_live

    tmp = Path(tempfile.mkdtemp(prefix="bench_keepalive_"))
    stop = mp.Event()
    burners = [mp.Process(target=_burn, args=(stop,)) for _ in range(burn)]
    for b in burners:
        b.start()
    ports, _, daemon, url = test_live._start(tmp)
    first, second = Witness(url, "first"), Witness(url, "second")
    stalled = LiveClient(url, stall=True)
    lean = subprocess.Popen([sys.executable, "-c", LEAN, url], stdout=subprocess.PIPE, text=True)
    clients = [first, second, stalled]
    for c in clients:
        c.wait_ready()
    t0 = time.monotonic()
    sim = test_live._sim(tmp, ports)
    if boost:
        threading.Thread(
            target=_boost, args=([sim.pid, daemon.proc.pid], -boost, lambda: sim.poll() is not None),
            daemon=True,
        ).start()  # fmt: skip
    failure = None
    try:
        first.wait_for(lambda c: c.topics().get("/samples", 0) >= 40, 300)
        late = Witness(url, "late")
        clients.append(late)
        late.wait_ready()
        sim.wait(900)
        first.wait_for(lambda c: c.topics().get("/map/current", 0) >= 3, 600)
        daemon.stop(signal.SIGTERM, timeout=60)
    except AssertionError as exc:
        failure = str(exc)[:120]
    finally:
        for c in clients:
            c.close()
        for p in (sim, daemon.proc):
            if p.poll() is None:
                p.kill()
        stop.set()
        for b in burners:
            b.join()
    out = {"burn": burn, "boost": boost, "wall_s": round(time.monotonic() - t0, 1)}
    out["test_would_fail"] = failure
    for c in clients:
        if isinstance(c, Witness):
            out[c.name] = c.figures()
    out["lean, own process"] = json.loads(lean.communicate(timeout=60)[0] or "{}")
    shutil.rmtree(tmp, ignore_errors=True)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--burn", type=int, default=0, help="processes spinning a core each")
    ap.add_argument("--boost", type=int, default=0, help="renice the daemon and simulator to -K")
    args = ap.parse_args()
    print(json.dumps(run(args.burn, args.boost), indent=1))


if __name__ == "__main__":
    main()
