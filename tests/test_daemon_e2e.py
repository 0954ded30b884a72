"""End to end: `forcemap sim` (river, default faults, 50x) → `forcemap run` on its ptys → export.

Independent of machine speed: the simulator runs in lockstep with the daemon's readers (`--lockstep`, as
`forcemap demo` does): each chunk is stamped with its virtual send time before the next is written, so
counts and values do not depend on how busy the machine is. Paced to real time only, the daemon stamps
bytes when they arrive, and at 50x a 10-ms stall of the machine is half a second of virtual time: on a
loaded clean-clone run the current's p95 error against the truth rose from 0.12 to 0.32 m/s. The one
host-time bound (a reconnect within 2 s) grows by the longest stall a probe thread saw during the run;
tests/test_daemon_cable.py times a reconnect without lockstep.
"""

from __future__ import annotations

import csv
import json
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from forcemap.host.cli import main
from forcemap.host.cli.demo import LOCKSTEP_SOURCES
from forcemap.host.convert.export import COLUMNS
from forcemap.host.log.mcap import has_footer, read_messages
from forcemap.protocol import wire
from mcap.reader import make_reader

from tests.test_daemon_support import ROOT, DaemonProcess, StallProbe, mcap_files

SPEED = 50
DURATION = "10m"  # every default fault still happens: they are placed at fractions of the run
MAX_RECONNECT_S = 2.0


@pytest.mark.slow
def test_simulated_river_through_daemon_to_samples_table(tmp_path):
    ports, truth, out = tmp_path / "ports", tmp_path / "truth", tmp_path / "out"
    # the daemon first: it waits for the clock file and the ports, so nothing is missed at start
    daemon = DaemonProcess(
        out,
        {n: str(ports / n) for n in ("bridge", "depth", "mavlink")},
        "--clock",
        f"sim:{ports / 'clock'}",
    )
    with StallProbe() as probe:
        sim = subprocess.Popen(
            [sys.executable, "-m", "forcemap.host.cli", "sim", "--scenario", "river", "--faults", "default",
             "--speed", str(SPEED), "--duration", DURATION, "--ports", str(ports),
             "--lockstep", ",".join(LOCKSTEP_SOURCES), "-o", str(truth)],
            cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
        )  # fmt: skip
        try:
            assert sim.wait(300) == 0, sim.stderr.read()
            time.sleep(0.5)
            assert daemon.stop(signal.SIGTERM) == 0
        finally:
            for p in (sim, daemon.proc):
                if p.poll() is None:
                    p.kill()
    stall = probe.max_stall()

    [path] = mcap_files(out)
    assert has_footer(path)
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    topics = {c.topic for c in summary.channels.values()}
    assert {"/samples", "/fix", "/bridge/frame", "/nmea/sentence", "/diagnostics"} <= topics
    assert any(t.startswith("/mavlink/") for t in topics)

    # every cable pull the simulator made: reading again within 2 s (host time) of the port's
    # return, plus the longest stall seen in the run (virtual time runs SPEED times faster, so a
    # busy machine's scheduling shows up SPEED times larger in the log)
    effects = json.loads((truth / "effects.json").read_text())
    events = [(m.log_time_ns / 1e9, m.message) for m in read_messages(path, "/daemon/event")]
    plugs = [
        (effects["t0"] + f["t"], f["source"]) for f in effects["fault_log"] if f["action"] == "plug"
    ]
    assert plugs
    for t_back, source in plugs:
        up = min(
            t
            for t, e in events
            if e["event"] == "connected" and e.get("source") == source and t >= t_back - 1.0
        )
        virtual = max(0.0, up - t_back)
        print(
            f"{source}: connected {virtual:.2f} s (virtual) = {virtual / SPEED:.3f} s (host) after "
            f"replug; longest stall {stall:.3f} s"
        )
        assert virtual / SPEED <= MAX_RECONNECT_S + stall

    csv_path = tmp_path / "samples.csv"
    assert main(["export", str(path), "-o", str(csv_path)]) == 0
    rows = list(csv.DictReader(csv_path.open()))
    header = list(rows[0])
    assert [c for c in header if c in COLUMNS] == [c for c in COLUMNS if c in header]
    assert header[:3] == ["t", "lat", "lon"]
    for col in (
        "heading",
        "sog",
        "cog",
        "depth",
        "wind_speed",
        "wind_dir",
        "current_speed",
        "current_dir",
    ):
        assert col in header
    t = np.array([float(r["t"]) for r in rows])
    duration = effects["duration"]
    assert len(rows) > 0.5 * 4 * duration  # 4 Hz samples over most of the run
    assert np.all(np.diff(t) > 0)

    # the exported position follows the simulator's truth
    true = np.genfromtxt(truth / "samples.csv", delimiter=",", names=True)
    have = np.array([r["lat"] != "" for r in rows])
    lat = np.interp(t[have], true["t"], true["lat"])
    lon = np.interp(t[have], true["t"], true["lon"])
    got_lat = np.array([float(r["lat"]) for r in rows if r["lat"] != ""])
    got_lon = np.array([float(r["lon"]) for r in rows if r["lon"] != ""])
    err_m = np.hypot((got_lat - lat) * 111_320, (got_lon - lon) * 111_320 * np.cos(np.radians(lat)))
    assert np.median(err_m) < 10.0

    # true wind and current against the truth, within the bounds derived in docs/COMPENSATION.md
    def col(name):
        return np.array([float(r[name]) if r[name] != "" else np.nan for r in rows])

    def truth_at(name):
        return np.interp(t, true["t"], true[name])

    wind_err = np.hypot(
        col("wind_east") - truth_at("wind_east"), col("wind_north") - truth_at("wind_north")
    )
    wind_bound = 2 * np.sin(np.radians(13.1)) * col("app_wind_speed") + 0.3
    ok = np.isfinite(wind_err)
    assert ok.sum() > 0.5 * 4 * duration
    # per sample the bound holds except while a fault (GPS loss, a clock jump) is being healed
    assert np.mean(wind_err[ok] <= wind_bound[ok]) > 0.95
    cur_err = np.hypot(
        col("current_east") - truth_at("current_east"),
        col("current_north") - truth_at("current_north"),
    )
    ok = np.isfinite(cur_err)
    print(f"wind error median {np.median(wind_err[np.isfinite(wind_err)]):.2f} m/s; "
          f"current error median {np.median(cur_err[ok]):.3f}, p95 {np.percentile(cur_err[ok], 95):.3f} m/s")  # fmt: skip
    assert np.median(cur_err[ok]) < 0.06
    assert np.percentile(cur_err[ok], 95) < 0.3

    # every bridge pulse is accounted for: between any two received SAMPLEs of one boot, the
    # counts differ by exactly the pulses the simulator made, across lost frames and resets
    ledger = np.load(truth / "pulses.npz")
    boot_us = dict(zip(ledger["boot_id"].tolist(), ledger["boot_us"].tolist(), strict=True))
    pulses = [np.sort(ledger[f"ch{c}"]) for c in range(5)]
    samples = [
        m.message for m in read_messages(path, "/bridge/frame") if m.message["type"] == "SAMPLE"
    ]
    assert (
        len({s["boot_id"] for s in samples}) >= 3
    )  # the default faults reset and unplug the bridge
    checked = lost = 0
    for a, b in zip(samples, samples[1:], strict=False):
        if a["boot_id"] != b["boot_id"]:
            continue
        lost += (b["seq"] - a["seq"]) % 2**32 > 1
        t0, t1 = boot_us[a["boot_id"]] + a["t_us"], boot_us[a["boot_id"]] + b["t_us"]
        ca = [a["fields"]["anemo"], *a["fields"]["wheels"]]
        cb = [b["fields"]["anemo"], *b["fields"]["wheels"]]
        for c in range(5):
            made = np.searchsorted(pulses[c], t1) - np.searchsorted(pulses[c], t0)
            assert wire.count_delta(ca[c][0], cb[c][0]) == made
            checked += 1
    assert lost > 0 and checked > 5 * 0.5 * 4 * duration

    for fmt in ("parquet", "geojson", "kml"):
        assert main(["export", str(path), "-o", str(tmp_path / f"s.{fmt}")]) == 0
    track = json.loads((tmp_path / "s.geojson").read_text())["features"][0]
    assert len(track["geometry"]["coordinates"]) > 0.5 * duration
