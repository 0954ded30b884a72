"""The river for 10 simulated minutes: every byte stream decodes and agrees with the logged truth."""

from __future__ import annotations

import math
import threading
import time
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np
import pynmea2
import pytest
import serial
from forcemap.host.acquire.arrival_clock import SimClock
from forcemap.protocol import wire
from forcemap.sim_devices.bridge_emu import vane_voltage
from forcemap.sim_devices.engine import Simulation
from forcemap.sim_devices.instruments import InstrumentConfig, wheel_response
from forcemap.sim_devices.ports import SOURCES, PortSet, run_live
from forcemap.sim_devices.truth import COLUMNS
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

DURATION = 600.0
Chunks = list[tuple[int, bytes]]


# ---- decoding helpers (shared by the offline and the pty tests) ---------------------------------
def decode_bridge(chunks: Chunks) -> tuple[list[tuple[int, wire.Frame]], wire.StreamDecoder]:
    dec = wire.StreamDecoder()
    out = []
    for t, d in chunks:
        out += [(t, f) for f in dec.feed(d)]
    return out, dec


def parse_nmea(chunks: Chunks) -> tuple[list[tuple[int, pynmea2.NMEASentence]], list[str]]:
    good, bad, buf = [], [], b""
    for t, d in chunks:
        buf += d
        *lines, buf = buf.split(b"\r\n")
        for raw in lines:
            line = raw.decode("ascii", "replace")
            try:
                good.append((t, pynmea2.parse(line, check=True)))
            except (pynmea2.ParseError, pynmea2.ChecksumError, ValueError, AttributeError):
                bad.append(line)
    return good, bad


def decode_mavlink(chunks: Chunks) -> list[tuple[int, object]]:
    mav = mavlink2.MAVLink(None)
    mav.robust_parsing = True
    out = []
    for t, d in chunks:
        out += [(t, m) for m in (mav.parse_buffer(d) or [])]
    return out


def read_truth(path: Path) -> dict[str, np.ndarray]:
    arr = np.genfromtxt(path / "samples.csv", delimiter=",", names=True)
    assert tuple(arr.dtype.names) == COLUMNS
    return {c: arr[c] for c in COLUMNS}


def circ_diff(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.abs((np.asarray(a) - np.asarray(b) + 180.0) % 360.0 - 180.0)


def check_streams(
    streams: dict[str, Chunks], truth: dict[str, np.ndarray], ppm: float, duration: float
) -> None:
    """Everything the issue asks of the byte streams, against the truth table."""
    t0 = truth["t"][0] - 0.1
    cfg = InstrumentConfig()

    # -- bridge: frames decode, SAMPLE at 4 Hz, pulse counts give back the truth
    frames, dec = decode_bridge(streams["bridge"])
    assert dec.rejected() == 0
    samples = [f for _, f in frames if f.msg_type == wire.SAMPLE]
    assert abs(len(samples) - 4 * duration) <= 0.02 * 4 * duration
    assert len({f.boot_id for _, f in frames}) == 1
    t_us = np.array([f.t_us for f in samples], dtype=float)
    sim_t = t_us / (1e6 * (1.0 + ppm * 1e-6))
    win = 20  # 5 s windows
    grid_t = truth["t"] - t0
    wheel_err, anemo_err = [], []
    for j in range(0, len(samples) - win, win):
        a, b = samples[j], samples[j + win]
        dt_dev = (b.t_us - a.t_us) * 1e-6
        sel = (grid_t > sim_t[j]) & (grid_t <= sim_t[j + win])
        for i in range(4):
            meas = (
                wire.count_delta(a.fields["wheels"][i][0], b.fields["wheels"][i][0])
                / cfg.wheel_pulses_per_m[i]
                / dt_dev
            )
            expect = np.mean(
                [
                    wheel_response(s, cfg.wheel_stall, cfg.wheel_s0)
                    for s in truth[f"wheel{i + 1}_speed"][sel]
                ]
            )
            if expect > 0.5:
                wheel_err.append(abs(meas - expect) / expect)
        meas = (
            wire.count_delta(a.fields["anemo"][0], b.fields["anemo"][0])
            / cfg.anemo_hz_per_mps
            / dt_dev
        )
        expect = float(np.mean(truth["app_wind_speed"][sel]))
        anemo_err.append(abs(meas - expect) / expect)
    # wheel noise is 2 % (correlated over 2 s), averaged over 5 s windows
    assert np.median(wheel_err) < 0.025 and np.percentile(wheel_err, 95) < 0.07
    # the firmware's lockout removes the reed bounce: counts are closures
    assert np.median(anemo_err) < 0.02 and np.percentile(anemo_err, 95) < 0.05
    # vane: nearest of the 16 divider voltages gives the apparent wind angle (+- 11.25 deg and the vane's hunting)
    table = np.array([vane_voltage(22.5 * k) / 3.3 * 65535 for k in range(16)])
    dirs = np.array([22.5 * np.argmin(np.abs(table - f.fields["vane_raw"])) for f in samples])
    true_ang = np.interp(sim_t, grid_t, np.unwrap(truth["app_wind_angle"], period=360.0))
    vane_err = circ_diff(dirs, true_ang)
    assert np.median(vane_err) < 12.0 and np.percentile(vane_err, 90) < 25.0

    # -- depth: every sentence parses with a valid checksum, talker SD, paced at 4800 baud
    good, bad = parse_nmea(streams["depth"])
    assert not bad
    kinds = Counter(s.sentence_type for _, s in good)
    assert all(abs(kinds[k] - duration) <= 2 for k in ("DPT", "DBT", "MTW"))
    assert {s.talker for _, s in good} == {"SD"}
    ts = np.array([t for t, _ in streams["depth"]], dtype=np.int64)
    lens = np.array([len(d) for _, d in streams["depth"]])
    assert np.all(np.diff(ts) >= (lens[1:] * 1e9 / 480.0).astype(np.int64) - 2)
    dpt = [(t, float(s.depth) + float(s.offset)) for t, s in good if s.sentence_type == "DPT"]
    dt_ = np.array([t for t, _ in dpt]) * 1e-9 - truth["t"][0] + 0.1
    err = np.abs(np.array([d for _, d in dpt]) - np.interp(dt_, grid_t, truth["depth"]))
    assert np.median(err) < 0.05 and err.max() < 0.4

    # -- autopilot: MAVLink 2 from system 1, ArduPilot rates, and positions and headings that match
    msgs = decode_mavlink(streams["mavlink"])
    types = Counter(m.get_type() for _, m in msgs)
    cur = [m.seq for _, m in msgs if m.get_type() == "MISSION_CURRENT"]
    for name, hz in (
        ("HEARTBEAT", 1),
        ("SYSTEM_TIME", 1),
        ("GPS_RAW_INT", 5),
        ("GLOBAL_POSITION_INT", 5),
        ("ATTITUDE", 10),
        ("VFR_HUD", 4),
        ("MISSION_CURRENT", 1),
        ("NAV_CONTROLLER_OUTPUT", 1),
    ):
        # Rover also sends MISSION_CURRENT at once when the item changes
        extra = sum(a != b for a, b in zip(cur[:-1], cur[1:], strict=True))
        extra = extra if name == "MISSION_CURRENT" else 0
        assert abs(types[name] - hz * duration - extra) <= 0.01 * hz * duration + 2, name
    assert set(types) == {
        "HEARTBEAT",
        "SYSTEM_TIME",
        "GPS_RAW_INT",
        "GLOBAL_POSITION_INT",
        "ATTITUDE",
        "VFR_HUD",
        "MISSION_CURRENT",
        "NAV_CONTROLLER_OUTPUT",
    }
    assert {(m.get_srcSystem(), m.get_srcComponent()) for _, m in msgs} == {(1, 1)}
    st = [(t, m) for t, m in msgs if m.get_type() == "SYSTEM_TIME"]
    assert st[0][1].time_unix_usec == 0 and st[-1][1].time_unix_usec > 0
    for t, m in st:
        if m.time_unix_usec:
            assert abs(m.time_unix_usec * 1e3 - t) < 0.3e9
    lat0 = truth["lat"][0]
    m_lat = 111_000.0
    m_lon = m_lat * math.cos(math.radians(lat0))
    gpi = [(t, m) for t, m in msgs if m.get_type() == "GLOBAL_POSITION_INT" and m.lat != 0]
    tt = np.array([t * 1e-9 - t0 for t, _ in gpi])
    de = (np.array([m.lon for _, m in gpi]) * 1e-7 - np.interp(tt, grid_t, truth["lon"])) * m_lon
    dn = (np.array([m.lat for _, m in gpi]) * 1e-7 - np.interp(tt, grid_t, truth["lat"])) * m_lat
    dist = np.hypot(de, dn)
    assert np.median(dist) < 1.5 and dist.max() < 5.0
    att = [(t, m) for t, m in msgs if m.get_type() == "ATTITUDE"]
    tt = np.array([t * 1e-9 - t0 for t, _ in att])
    yaw = np.degrees([m.yaw for _, m in att]) % 360.0
    hd = np.interp(tt, grid_t, np.unwrap(truth["heading"], period=360.0))
    assert np.median(circ_diff(yaw, hd)) < 1.5
    hud = [m for _, m in msgs if m.get_type() == "VFR_HUD"]
    assert all(0 <= m.throttle <= 100 for m in hud) and max(m.throttle for m in hud) > 50
    # the guidance as Rover reports it: the cross-track error and the waypoint ahead
    nco = [m for _, m in msgs if m.get_type() == "NAV_CONTROLLER_OUTPUT"]
    assert max(abs(m.xtrack_error) for m in nco) > 1.0 and all(m.wp_dist < 1000 for m in nco)
    cur = [m.seq for _, m in msgs if m.get_type() == "MISSION_CURRENT"]
    assert cur[0] >= 1 and len(set(cur)) >= 2
    boots = [m.time_boot_ms for _, m in att]
    assert all(b2 > b1 for b1, b2 in zip(boots, boots[1:], strict=False))


# ---- offline: the core with a sink --------------------------------------------------------------
@pytest.fixture(scope="module")
def river(tmp_path_factory: pytest.TempPathFactory) -> tuple[Simulation, dict[str, Chunks], Path]:
    truth_dir = tmp_path_factory.mktemp("truth")
    streams: dict[str, Chunks] = defaultdict(list)
    last = [0]

    def sink(source: str, t_ns: int, data: bytes) -> None:
        assert t_ns >= last[0]  # one time-ordered stream of calls
        last[0] = t_ns
        streams[source].append((t_ns, data))

    sim = Simulation("river", "lawnmower", effects=["depth_current"], seed=3, truth_dir=truth_dir)
    sim.run(DURATION, sink)
    return sim, streams, truth_dir


def test_offline_river_streams_match_truth(
    river: tuple[Simulation, dict[str, Chunks], Path],
) -> None:
    sim, streams, truth_dir = river
    check_streams(streams, read_truth(truth_dir), sim.ppm, DURATION)


def test_truth_files(river: tuple[Simulation, dict[str, Chunks], Path]) -> None:
    import json

    sim, _, truth_dir = river
    meta = json.loads((truth_dir / "effects.json").read_text())
    assert meta["scenario"] == "river" and meta["seed"] == 3
    assert [e["name"] for e in meta["effects"]] == ["depth_current"]
    assert meta["t0"] == pytest.approx(1780322400.0)
    f = np.load(truth_dir / "fields.npz")
    nt, ny, nx = f["current_east"].shape
    assert f["depth"].shape == (ny, nx) == (len(f["y"]), len(f["x"])) and len(f["t"]) == nt
    assert 0.5 <= f["depth"].min() and f["depth"].max() <= 6.0
    sp = np.hypot(f["current_east"], f["current_north"])
    assert sp.max() == pytest.approx(2.5, abs=0.05)
    tr = read_truth(truth_dir)
    assert np.allclose(np.diff(tr["t"]), 0.1, atol=1e-3)
    assert len(tr["t"]) == pytest.approx(DURATION * 10, abs=2)


def test_same_seed_same_bytes() -> None:
    def collect(seed: int) -> bytes:
        out: list[bytes] = []
        Simulation("lake", seed=seed, faults="default").run(
            30.0, lambda s, t, d: out.append(s.encode() + d)
        )
        return b"".join(out)

    assert collect(1) == collect(1)
    assert collect(1) != collect(2)


# ---- live: ptys opened with pyserial, accelerated -----------------------------------------------
def test_ports_river_10_minutes(tmp_path: Path) -> None:
    ports = PortSet(tmp_path / "ports")
    opened = {s: serial.Serial(ports.path(s), timeout=0.05) for s in SOURCES}
    streams: dict[str, Chunks] = defaultdict(list)
    stop = threading.Event()
    done = threading.Event()
    clock: list[SimClock] = []

    def reader() -> None:
        # one thread polling all three, so the simulator keeps the interpreter most of the time
        while True:
            finished = done.is_set()
            for source, port in opened.items():
                n = port.in_waiting
                if n:
                    data = port.read(n)
                    streams[source].append((clock[0].now_ns() if clock else 0, data))
            if finished:
                break
            time.sleep(0.005)

    threads = [threading.Thread(target=reader, daemon=True)]
    for th in threads:
        th.start()
    truth_dir = tmp_path / "truth"

    def factory(**kw: object) -> Simulation:
        sim = Simulation(
            "river", "lawnmower", effects=["depth_current"], seed=3, truth_dir=truth_dir, **kw
        )  # type: ignore[arg-type]
        clock.append(SimClock(ports.clock_path))
        return sim

    try:
        sim = run_live(factory, ports, DURATION, speed=400.0, stop=stop)
        time.sleep(0.2)
    finally:
        done.set()
        for th in threads:
            th.join(5)
        for p in opened.values():
            p.close()
        ports.close()
    # the ports carried exactly the bytes the core produced
    for s in SOURCES:
        assert sum(len(d) for _, d in streams[s]) == sim.stats[s] == ports.bytes_written[s]
    # the same bytes as the offline core, in the same order; arrivals on the virtual clock (the
    # daemon's --clock sim:DIR/clock) follow the core's send times
    ref: dict[str, Chunks] = defaultdict(list)
    Simulation("river", "lawnmower", effects=["depth_current"], seed=3).run(
        DURATION, lambda s, t, d: ref[s].append((t, d))
    )
    for s in SOURCES:
        assert b"".join(d for _, d in streams[s]) == b"".join(d for _, d in ref[s])
        if not ref[s]:
            continue  # the NMEA bus's port is silent without its faults (issue 20)
        sent_end = np.cumsum([len(d) for _, d in ref[s]])
        got_end = np.cumsum([len(d) for _, d in streams[s]])
        sent_t = np.array([t for t, _ in ref[s]], dtype=np.int64)
        lag = (
            np.array([t for t, _ in streams[s]], dtype=np.int64)
            - sent_t[np.searchsorted(sent_end, got_end)]
        ) * 1e-9
        # never before it was sent (the clock file is re-anchored if the simulator falls behind)
        assert lag.min() > -1.0, s
    check_streams(ref, read_truth(truth_dir), sim.ppm, DURATION)


def test_a_machine_that_falls_behind_holds_the_clock_back(tmp_path: Path) -> None:
    """After the simulator stalls, the clock file comes back to the bytes: stalls never add up.

    Independent of machine speed: the bound is one stall as it really happened in this run (the
    longest host time between two of the simulator's catch-up checks, measured around its
    ``advance`` calls, which a busy machine only lengthens), not a stall plus a guessed allowance.
    """
    from forcemap.host.acquire.arrival_clock import SimClock

    speed, lag_wall, stall_wall, reread_s = 100.0, 0.05, 0.3, 0.02
    ports = PortSet(tmp_path / "ports")
    calls: list[tuple[float, float]] = []  # host monotonic s at entry and exit of each advance
    stalled: list[float] = []  # host seconds each stall really took

    class Stalling(Simulation):
        def advance(self, t: float) -> None:
            entry = time.monotonic()
            before = self.t
            super().advance(t)
            if int(self.t // 20) > int(before // 20):  # every 20 s of virtual time
                s0 = time.monotonic()
                time.sleep(stall_wall)  # the machine is busy elsewhere: 30 s of virtual time
                stalled.append(time.monotonic() - s0)
            calls.append((entry, time.monotonic()))

    sims: list[Simulation] = []

    def factory(**kw: object) -> Simulation:
        sims.append(Stalling("river", "lawnmower", seed=1, **kw))  # type: ignore[arg-type]
        now = time.monotonic()
        calls.append((now, now))  # run_live anchors the clock after this: the first "check"
        return sims[-1]

    ahead: list[float] = []
    done = threading.Event()

    def watch() -> None:
        clock = SimClock(ports.clock_path, wait_s=10.0, reread_s=reread_s)
        while not done.is_set():
            if sims and hasattr(sims[0], "t"):  # started
                t_sim = sims[0].t
                now = clock.now_ns()
                if sims[0].t == t_sim:  # the simulator did not move while the clock was read
                    ahead.append((now - (sims[0].t0_ns + t_sim * 1e9)) * 1e-9)
            time.sleep(0.002)

    th = threading.Thread(target=watch, daemon=True)
    th.start()
    try:
        run_live(factory, ports, 300.0, speed=speed, max_lag_wall_s=lag_wall)
    finally:
        done.set()
        th.join(5)
        ports.close()
    # run_live checks the lag after each advance, so two checks are never further apart than
    # from the exit of one advance to the entry of the one after next
    gap = max(calls[k + 1][0] - calls[k - 1][1] for k in range(1, len(calls) - 1))
    # the lead: the allowed lag, one gap between checks, and the watcher's clock-file re-read
    bound = max(0.5, lag_wall * speed) + (gap + reread_s) * speed
    print(
        f"lead at most {max(ahead):.1f} s (bound {bound:.1f} s, longest gap {gap:.3f} s); "
        f"{len(stalled)} stalls adding up to {sum(stalled) * speed:.0f} s"
    )
    assert len(stalled) >= 10 and ports.reanchors >= 10
    assert sum(stalled) * speed > 4 * bound  # what the lead would be if stalls added up
    assert max(ahead) < bound
