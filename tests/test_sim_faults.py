"""A fault schedule (corruption, a cable pull, a board reset, ...) shows in the byte streams at its time."""

from __future__ import annotations

import os
import threading
import time
from collections import defaultdict
from pathlib import Path

import numpy as np
import pynmea2
import serial
from forcemap.protocol import wire
from forcemap.sim_devices import faults as fl
from forcemap.sim_devices.engine import Simulation
from forcemap.sim_devices.ports import PortSet, run_live

Chunks = list[tuple[int, bytes]]
SCHEDULE = (
    "corrupt:source=bridge:at=30:for=20:rate=2e-3,"
    "pull:source=bridge:at=60:for=5,"
    "reset:at=120,"
    "gps_loss:at=150:for=10,"
    "nmea_garbage:at=170:for=20:rate=0.3,"
    "pull:source=depth:at=200:for=4,"
    "clock_jump:at=210:jump=2"
)


def run_offline(duration: float = 240.0) -> tuple[Simulation, dict[str, Chunks]]:
    streams: dict[str, Chunks] = defaultdict(list)
    sim = Simulation("river", "lawnmower", faults=SCHEDULE, seed=5)
    sim.run(duration, lambda s, t, d: streams[s].append((t, d)))
    return sim, streams


def rel(sim: Simulation, t_ns: int) -> float:
    return t_ns * 1e-9 - sim.scenario.t0


def test_every_fault_shows_at_its_time() -> None:
    sim, st = run_offline()
    # bridge: damaged frames only inside the corruption window, counted by the decoder's CRC/COBS checks
    dec = wire.StreamDecoder()
    bad_times, frames = [], []
    for t, d in st["bridge"]:
        before = dec.rejected()
        frames += [(rel(sim, t), f) for f in dec.feed(d)]
        if dec.rejected() > before:
            bad_times.append(rel(sim, t))
    assert len(bad_times) >= 5 and all(30.0 <= x < 50.5 for x in bad_times)
    # cable pull: no bridge bytes for 5 s, then the board boots again (power-on HELLO, new boot id)
    times = np.array([rel(sim, t) for t, _ in st["bridge"]])
    assert not np.any((times > 60.0) & (times < 65.0))
    hellos = [(t, f) for t, f in frames if f.msg_type == wire.HELLO]
    assert [round(t) for t, _ in hellos] == [0, 65, 120]
    assert [f.fields["reset_cause"] for _, f in hellos] == [1, 1, 3]  # power-on, power-on, watchdog
    assert len({f.boot_id for _, f in hellos}) == 3
    after_reset = [f for t, f in frames if t >= 120.0]
    assert (
        after_reset[0].msg_type == wire.HELLO
        and after_reset[0].seq == 0
        and after_reset[0].t_us < 1000
    )
    # GPS loss: fix_type drops below 2 for 10 s
    from pymavlink.dialects.v20 import ardupilotmega as mavlink2

    mav = mavlink2.MAVLink(None)
    msgs = [(rel(sim, t), m) for t, d in st["mavlink"] for m in (mav.parse_buffer(d) or [])]
    nofix = [t for t, m in msgs if m.get_type() == "GPS_RAW_INT" and m.fix_type < 2 and t > 10.0]
    assert nofix and min(nofix) >= 150.0 and max(nofix) <= 160.2
    # clock jump: time_boot_ms steps by 2 s between consecutive ATTITUDE messages at 210 s
    att = [(t, m.time_boot_ms) for t, m in msgs if m.get_type() == "ATTITUDE"]
    steps = [(t, b2 - b1) for (_, b1), (t, b2) in zip(att, att[1:], strict=False)]
    jumps = [t for t, s in steps if s > 1000]
    assert len(jumps) == 1 and 210.0 <= jumps[0] < 210.5
    # NMEA garbage only in its window; the depth pull leaves a 4 s hole
    buf = b"".join(d for _, d in st["depth"])
    ends = np.cumsum([len(d) for _, d in st["depth"]])
    tchunk = np.array([rel(sim, t) for t, _ in st["depth"]])
    bad_t, pos = [], 0
    for line in buf.split(b"\r\n")[:-1]:
        pos += len(line) + 2
        try:
            pynmea2.parse(line.decode("ascii", "replace"), check=True)
        except Exception:
            bad_t.append(tchunk[np.searchsorted(ends, pos - 1)])
    assert len(bad_t) >= 5 and all(170.0 <= x < 191.0 for x in bad_t)
    assert not np.any((tchunk > 200.2) & (tchunk < 204.0))
    # and the simulator logged each action when it happened
    acts = {(round(t), a) for t, a, _ in sim.fault_log}
    assert {
        (60, "unplug"),
        (65, "plug"),
        (120, "reset"),
        (150, "gps_off"),
        (210, "clock_jump"),
    } <= acts


def test_default_set_and_parsing() -> None:
    d = fl.parse("default")
    kinds = {f.kind for f in d}
    # the default set has every kind but the sources' (issue 20), which are the `sources` set, and
    # the two receivers of different fix quality and the instrument faults of issue 28 (with a known
    # truth for the estimators), which are in no set
    sources = {f.kind for f in fl.parse("sources")}
    quality = {"poor_gnss", "dgps_gnss"} | set(fl.CAL_KINDS)
    # the faults of real logs (issue 28), in no set either
    logs = {"no_variation", "checksum_variant", "position_jump", "bottom_lost", "beyond_range"}
    # the navigation faults of issue 29 (two receivers of three sentences, a late compass): no set
    nav = {"nav_receivers", "late_compass"}
    assert kinds | sources | quality | logs | nav == set(fl.KINDS)
    assert not kinds & (sources | quality | logs | nav)
    f = fl.parse_one("speed_log:gain=1.1:misalign=-3")
    assert (f.source, f.params) == ("nmea", {"gain": 1.1, "misalign": -3.0})
    f = fl.parse_one("pull:source=mavlink:at=12.5:for=3")
    assert (f.kind, f.source, f.start(100), f.end(100)) == ("pull", "mavlink", 12.5, 15.5)
    assert fl.parse("none") == [] and fl.parse(None) == []


def test_cable_pull_on_the_pty(tmp_path: Path) -> None:
    """The bridge's port disappears and comes back under the same path, with a freshly booted board."""
    ports = PortSet(tmp_path / "ports")
    path = ports.path("bridge")
    seen: list[tuple[bool, bytes]] = []
    done = threading.Event()

    def watcher() -> None:
        port: serial.Serial | None = serial.Serial(path, timeout=0.02)
        while not done.is_set():
            exists = os.path.exists(path)
            if port is None and exists:
                try:
                    port = serial.Serial(path, timeout=0.02)
                except (serial.SerialException, OSError):
                    port = None
            data = b""
            if port is not None:
                try:
                    data = port.read(4096)
                except (serial.SerialException, OSError):
                    port.close()
                    port = None
            seen.append((exists, data))
            time.sleep(0.002)
        if port is not None:
            port.close()

    th = threading.Thread(target=watcher, daemon=True)
    th.start()

    def factory(**kw: object) -> Simulation:
        return Simulation("lake", faults="pull:source=bridge:at=5:for=10", seed=1, **kw)  # type: ignore[arg-type]

    try:
        run_live(factory, ports, 25.0, speed=20.0)
        time.sleep(0.1)
    finally:
        done.set()
        th.join(5)
        ports.close()
    states = [e for e, _ in seen]
    gone = states.index(False)
    assert any(states[:gone]) and any(states[gone:])  # present, gone, back
    back = gone + states[gone:].index(True)
    frames_before = wire.StreamDecoder().feed(b"".join(d for _, d in seen[:gone]))
    frames_after = wire.StreamDecoder().feed(b"".join(d for _, d in seen[back:]))
    assert frames_before and frames_after
    assert {f.boot_id for f in frames_before}.isdisjoint({f.boot_id for f in frames_after})
    # the board re-booted at the re-plug (its HELLO may go out before the host re-opens): its
    # clock and sequence restarted
    assert frames_after[0].t_us < 10_000_000 and frames_after[0].seq < 60
    assert frames_after[0].t_us < frames_before[-1].t_us + 10_000_000
