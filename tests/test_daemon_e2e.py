"""End to end: `forcemap sim` (river, default faults, 50x) → `forcemap run` on its ptys → export."""

from __future__ import annotations

import csv
import json
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from mcap.reader import make_reader

from host.cli import main
from host.export import COLUMNS
from host.mcap_log import has_footer, read_messages
from tests.test_daemon_support import ROOT, DaemonProcess, mcap_files

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
    sim = subprocess.Popen(
        [sys.executable, "-m", "host.cli", "sim", "--scenario", "river", "--faults", "default",
         "--speed", str(SPEED), "--duration", DURATION, "--ports", str(ports),
         "--truth", str(truth)],
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

    [path] = mcap_files(out)
    assert has_footer(path)
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    topics = {c.topic for c in summary.channels.values()}
    assert {"/samples", "/fix", "/bridge/frame", "/nmea/sentence", "/diagnostics"} <= topics
    assert any(t.startswith("/mavlink/") for t in topics)

    # every cable pull the simulator made: reading again within 2 s (host time) of the port's return
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
            f"{source}: connected {virtual:.2f} s (virtual) = {virtual / SPEED:.3f} s (host) after replug"
        )
        assert virtual / SPEED <= MAX_RECONNECT_S

    csv_path = tmp_path / "samples.csv"
    assert main(["export", str(path), "--format", "csv", "-o", str(csv_path)]) == 0
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

    for fmt in ("parquet", "geojson", "kml"):
        assert main(["export", str(path), "--format", fmt, "-o", str(tmp_path / f"s.{fmt}")]) == 0
    track = json.loads((tmp_path / "s.geojson").read_text())["features"][0]
    assert len(track["geometry"]["coordinates"]) > 0.5 * duration
