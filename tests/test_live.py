"""`forcemap run --live` on a simulated river: real foxglove-sdk server, real WebSocket clients.

Two clients from the start, one that connects mid-survey, one that stalls. Each message a client
decodes must be valid against its advertised schema and be byte for byte a message of the MCAP of
the same run (same topic, same log time). The daemon stamps with the simulator's clock, "mid-survey" is
"after the first client saw 40 samples", and the stalled client's cost is counted in messages, not
seconds. One thing depends on the pace (SPEED): a channel advertised on first use is received from
when the client reads its advertisement.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys

import numpy as np
import pytest
from forcemap.host.log.mcap import FileScan, iter_records, read_messages
from forcemap.protocol import wire
from mcap.records import Message

from bench.live_client import SUBPROTOCOL, LiveClient
from tests.test_daemon_support import ROOT, DaemonProcess, mcap_files

# The simulator's pace against real time. A channel advertised when its topic is first logged (the
# MAVLink messages, the raw bytes) is subscribed to when a client reads the advertisement, behind what
# it has not yet read: at x40 the MAVLink stream lasts 12 s of wall time, and a loaded clean run's
# client once read its advertisement after the last HEARTBEAT (475 logged, none received). At x20 a
# client may fall 24 s behind and still get them.
SPEED = 20
DURATION = "8m"


def mcap_messages(path) -> list[tuple[str, int, bytes]]:
    scan = FileScan(path)
    out = []
    for rec in iter_records(path, scan):
        if isinstance(rec, Message):
            out.append((scan.channels[rec.channel_id].topic, rec.log_time, bytes(rec.data)))
    return out


def _start(tmp_path):
    ports, out = tmp_path / "ports", tmp_path / "out"
    daemon = DaemonProcess(
        out,
        {n: str(ports / n) for n in ("bridge", "depth", "mavlink")},
        "--clock", f"sim:{ports / 'clock'}", "--live", "127.0.0.1:0", "--map-every", "60s",
    )  # fmt: skip
    url = daemon.wait_for(lambda e: e.get("event") == "live")["connect"]
    return ports, out, daemon, url


def _sim(tmp_path, ports):
    return subprocess.Popen(
        [sys.executable, "-m", "forcemap.host.cli", "sim", "--scenario", "river", "--faults", "default",
         "--speed", str(SPEED), "--duration", DURATION, "--ports", str(ports),
         "-o", str(tmp_path / "truth")],
        cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip


@pytest.mark.slow
def test_live_clients_see_what_the_mcap_holds(tmp_path):
    ports, out, daemon, url = _start(tmp_path)
    clients, sim = [], None
    try:
        first, second = LiveClient(url), LiveClient(url)
        stalled = LiveClient(url, stall=True)
        clients = [first, second, stalled]
        for c in clients:
            c.wait_ready()
        sim = _sim(tmp_path, ports)
        first.wait_for(lambda c: c.topics().get("/samples", 0) >= 40, 300)
        late = LiveClient(url)
        clients.append(late)
        late.wait_ready()
        assert sim.wait(600) == 0, sim.stderr.read()
        # the map process runs at a low priority: on a busy machine it may still be catching up
        first.wait_for(lambda c: c.topics().get("/map/current", 0) >= 3, 600)
        assert daemon.stop(signal.SIGTERM, timeout=60) == 0
    finally:
        for c in clients:
            c.close()
        for p in (sim, daemon.proc):
            if p is not None and p.poll() is None:
                p.kill()
    [path] = mcap_files(out)
    logged = mcap_messages(path)
    in_mcap = set(logged)
    per_topic: dict[str, int] = {}
    for topic, _, _ in logged:
        per_topic[topic] = per_topic.get(topic, 0) + 1
    assert first.subprotocol == SUBPROTOCOL
    for c in (first, second, late):
        assert not c.invalid, c.invalid[:5]
        mcap_topics = [m for m in c.messages if m[0] in per_topic]
        # every logged topic's message a client got is the MCAP's, byte for byte
        assert set(mcap_topics) <= in_mcap
        live_only = {t for t, _, _ in c.messages} - set(per_topic)
        assert {"/health", "/map/current", "/map/wind", "/map/depth", "/map/info",
                "/map/layers/current", "/map/layers/samples"} <= live_only, live_only  # fmt: skip
    for c in (first, second):
        for topic in per_topic:
            logged_here = [m for m in logged if m[0] == topic]
            got = [m for m in c.messages if m[0] == topic]
            if topic.startswith("/mavlink/") or topic.startswith("/raw/"):
                # advertised when first logged: the client has it from its subscription on, whole
                # (a topic logged once, such as a corrupted packet's, may come before it)
                assert got == logged_here[len(logged_here) - len(got) :], topic
                assert got or len(logged_here) < 10, (topic, c.topics())
            else:  # advertised from the start: all of it
                assert got == logged_here, (topic, len(got), len(logged_here))
    # the late client got the rest of the survey, not its start
    late_samples = late.topics()["/samples"]
    assert 0 < late_samples < per_topic["/samples"]
    # the stalled client cost nothing: the others got everything (above), and the daemon counted
    health = [json.loads(p) for t, _, p in first.messages if t == "/health"]
    assert health[-1]["live"]["clients"] >= 3
    assert set(health[-1]["sources"]) >= {"bridge", "depth", "mavlink"}
    # the growing maps: updated more than once, each with its samples count
    infos = [json.loads(p) for t, _, p in first.messages if t == "/map/info"]
    current = [i for i in infos if i["target"] == "current"]
    assert len(current) >= 3 and current[-1]["n_samples"] > current[0]["n_samples"]
    _pulses_accounted(path, tmp_path / "truth")


def _pulses_accounted(path, truth) -> None:
    """As in test_daemon_e2e: between two SAMPLEs of one boot the counts differ by exactly the pulses
    the simulator made, across lost frames and resets, with the clients attached."""
    ledger = np.load(truth / "pulses.npz")
    boot_us = dict(zip(ledger["boot_id"].tolist(), ledger["boot_us"].tolist(), strict=True))
    pulses = [np.sort(ledger[f"ch{c}"]) for c in range(5)]
    samples = [
        m.message for m in read_messages(path, "/bridge/frame") if m.message["type"] == "SAMPLE"
    ]
    checked = 0
    for a, b in zip(samples, samples[1:], strict=False):
        if a["boot_id"] != b["boot_id"]:
            continue
        t0, t1 = boot_us[a["boot_id"]] + a["t_us"], boot_us[a["boot_id"]] + b["t_us"]
        ca = [a["fields"]["anemo"], *a["fields"]["wheels"]]
        cb = [b["fields"]["anemo"], *b["fields"]["wheels"]]
        for c in range(5):
            made = np.searchsorted(pulses[c], t1) - np.searchsorted(pulses[c], t0)
            assert wire.count_delta(ca[c][0], cb[c][0]) == made
            checked += 1
    assert checked > 5 * 1000
