"""The ws-protocol reference client (npm `@foxglove/ws-protocol`, run by node) against the live view.

    python bench/bench_ws_client.py            # needs node and npm; installs into bench/ws_client/

A synthetic survey's log (`/samples`, `/fix`) is replayed into `LiveService` (the real foxglove-sdk
server behind `host/live/front.py`, with the map process) while `bench/ws_client/client.mjs`
subscribes to everything, once offering the spec's `foxglove.websocket.v1` (what the reference client
and Lichtblick send) and once the sdk's `foxglove.sdk.v1`. It prints, per run, the subprotocol the
server agreed to and the messages per topic the client decoded. Not a test: the tests must not need
node (`tests/test_live_front.py` is the same check with a Python client).
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

from forcemap.host.cli.replay import _stream
from forcemap.host.live.front import SDK, SPEC
from forcemap.host.live.service import LiveService

ROOT = Path(__file__).resolve().parents[1]
HERE = ROOT / "bench" / "ws_client"
sys.path.insert(0, str(ROOT))
from bench.live_client import survey_log  # noqa: E402


def install() -> None:
    if not (HERE / "node_modules" / "@foxglove" / "ws-protocol").is_dir():
        subprocess.run(["npm", "install", "--no-audit", "--no-fund"], cwd=HERE, check=True)


def one_run(log: Path, protocol: str, *, sdk_port: bool = False) -> dict:
    """``sdk_port``: connect to the sdk's own port, past the front (as before the front)."""
    live = LiveService("127.0.0.1", 0, every_s=60.0)
    port = live.server.server.port if sdk_port else live.server.port
    node = subprocess.Popen(
        ["node", "client.mjs", f"ws://127.0.0.1:{port}", protocol, "600" if not sdk_port else "20"],
        cwd=HERE, stdout=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        # start streaming once the client has subscribed (the sdk's subscriptions are counted)
        deadline = threading.Event()
        while live.server.stats()["subscriptions"] < 2 and node.poll() is None and not sdk_port:
            deadline.wait(0.1)
        _stream(live, [log], speed=1e6)
        out, _ = node.communicate(timeout=700)
    finally:
        if node.poll() is None:
            node.kill()
        live.close(final_maps_s=60.0)
    result = json.loads(out.strip().splitlines()[-1])
    result["exit"] = node.returncode
    return result


def main() -> int:
    if shutil.which("node") is None or shutil.which("npm") is None:
        print("this bench needs node and npm", file=sys.stderr)
        return 2
    install()
    version = json.loads((HERE / "node_modules/@foxglove/ws-protocol/package.json").read_text())
    print(f"@foxglove/ws-protocol {version['version']}, node {_node_version()}")
    with tempfile.TemporaryDirectory() as tmp:
        log, n = survey_log(Path(tmp) / "log")
        print(f"replayed log: {n} samples and fixes")
        for protocol, past in ((SPEC, False), (SDK, False), (SPEC, True)):
            r = one_run(log, protocol, sdk_port=past)
            topics = {
                k: v for k, v in sorted(r["counts"].items()) if k.startswith(("/fix", "/map"))
            }
            print(
                f"{'the sdk alone, ' if past else ''}offered {protocol}: "
                f"agreed {r['agreed'] or '(refused)'}, exit {r['exit']}, "
                f"server {r['serverInfo']}, errors {r['errors']}, {topics}"
            )
    return 0


def _node_version() -> str:
    return subprocess.run(["node", "--version"], capture_output=True, text=True).stdout.strip()


if __name__ == "__main__":
    sys.exit(main())
