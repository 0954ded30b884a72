"""The live view's command line: `run --live` options, the sdk as an optional extra, `live-layout`, `replay`."""

from __future__ import annotations

import argparse
import json
import subprocess
import sys

import pytest
from forcemap.host.cli import main
from forcemap.host.cli.live_options import start_live
from forcemap.host.cli.replay import _stream
from forcemap.host.errors import CliError
from forcemap.host.extras import install_hint
from forcemap.host.live.layout import build_layout, layout_json, schematic_png
from forcemap.host.live.server import parse_address
from forcemap.host.live.service import LiveService
from forcemap.host.log.mcap import McapLog
from forcemap.host.log.messages import SAMPLE_COLUMNS, Sample

from bench.live_client import LiveClient
from bench.synth_survey import simulate
from tests.test_daemon_support import ROOT
from tests.test_live import mcap_messages


def _py(code: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120
    )


def test_run_without_live_imports_nothing_of_it():
    res = _py(
        "import sys, argparse\n"
        "from forcemap.host.cli import build_parser\n"
        "import forcemap.host.cli.run as r\n"
        "args = build_parser('run').parse_args(['run', '--nmea', '/dev/null'])\n"
        "assert r.start_live(args, None, print) is None\n"
        "bad = [m for m in sys.modules if m.startswith(('foxglove', 'forcemap.host.live'))]\n"
        "print(bad)\n"
    )
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == "[]"


def test_live_without_the_sdk_is_one_line_and_exit_2(tmp_path):
    res = _py(
        "import sys; sys.modules['foxglove'] = None\n"  # as if foxglove-sdk were not installed
        "from forcemap.host.cli import main\n"
        f"sys.exit(main(['run', '--nmea', '/dev/null', '-o', {str(tmp_path)!r}, '--live']))\n"
    )
    assert res.returncode == 2
    assert res.stderr.strip().count("\n") == 0
    assert install_hint("live") in res.stderr  # as this forcemap was installed (a clone here)
    assert not list(tmp_path.glob("*.mcap"))


def test_addresses():
    assert parse_address(None) == ("127.0.0.1", 8765)
    assert parse_address("0.0.0.0:9000") == ("0.0.0.0", 9000)
    assert parse_address(":9001") == ("127.0.0.1", 9001)
    for bad in ("host:port", "1.2.3.4:70000"):
        with pytest.raises(CliError):
            parse_address(bad)


def test_binding_beyond_this_machine_warns(capsys):
    events = []
    args = argparse.Namespace(live="0.0.0.0:0", no_maps=True, map_every=60.0)
    service = start_live(args, None, lambda name, **kw: events.append((name, kw)))
    try:
        assert [e for e, _ in events] == ["live", "warning"]
        assert "anyone on that network can watch" in events[1][1]["detail"]
        assert "anyone on that network can watch" in capsys.readouterr().err
    finally:
        service.close()
    events.clear()
    service = start_live(
        argparse.Namespace(live="127.0.0.1:0", no_maps=True, map_every=60.0), None,
        lambda name, **kw: events.append((name, kw)),
    )  # fmt: skip
    service.close()
    assert [e for e, _ in events] == ["live"]


def test_live_layout_is_the_sdks_layout_and_is_written_once(tmp_path):
    assert json.loads(layout_json()) == build_layout()
    panels = json.dumps(build_layout())
    for panel in ('"Map"', '"Plot"', '"Table"', '"Log"', "/fix", "/health", "/alerts"):
        assert panel in panels
    out = tmp_path / "forcemap.json"
    assert main(["live-layout", "-o", str(out)]) == 0
    assert json.loads(out.read_text()) == build_layout()
    schematic_png(tmp_path / "l.png")  # the picture in docs/LIVE.md
    assert (tmp_path / "l.png").read_bytes()[:4] == b"\x89PNG"
    assert main(["live-layout", "-o", str(out)]) == 2  # exists: only with --force
    assert main(["live-layout", "-o", str(out), "--force"]) == 0


def test_replay_streams_the_log_and_grows_its_maps(tmp_path):
    cols = simulate(duration_s=400, seed=4)
    log = McapLog(tmp_path / "log")
    for i in range(len(cols["t"])):
        row = {k: float(cols[k][i]) for k in cols if k in SAMPLE_COLUMNS}
        log.write("/samples", int(cols["t"][i] * 1e9), Sample(**row))
    log.close()
    logged = mcap_messages(log.path)
    live = LiveService("127.0.0.1", 0, every_s=60.0)
    client = LiveClient(f"ws://127.0.0.1:{live.server.port}")
    try:
        client.wait_ready()
        # the server has the client's subscriptions before the first message goes out
        client.wait_for(lambda c: live.server.stats()["subscriptions"] >= len(c.channels) > 0, 30)
        assert _stream(live, [log.path], speed=1e6) == len(logged)
        client.wait_for(lambda c: c.topics().get("/samples", 0) == len(logged), 60)
    finally:
        live.close(final_maps_s=120.0)
        client.close()
    assert [m for m in client.messages if m[0] == "/samples"] == logged
    assert not client.invalid
    # the maps as they grew: one update per 60 s of the log's time (and the line ends)
    assert live.board.updates >= 400 // 60 - 1
    grids = live.board.latest()
    assert set(grids) == {"current", "wind", "depth"}
    assert grids["depth"].n_samples == len(logged)
    assert grids["current"].to_field().east.shape == grids["current"].shape


def test_replay_needs_live():
    assert main(["replay", "x.mcap"]) == 2
