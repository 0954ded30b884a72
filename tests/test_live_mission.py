"""`/map/mission` on the live Map panel: the intended lines, the plan the autopilot holds, the flown track."""

from __future__ import annotations

import json

import numpy as np
from forcemap.host.live.mission_layer import TOPIC, MissionLayer
from forcemap.host.live.service import LiveService
from forcemap.host.log.mcap import McapLog
from forcemap.host.log.messages import LocationFix, Time
from forcemap.host.vessel.geodesy import LocalFrame

from bench.live_client import LiveClient
from tests.test_live import mcap_messages

LAT0, LON0 = 47.0, 8.0
M_LAT = 1 / LocalFrame(LAT0, LON0).m_per_deg_lat  # degrees of latitude per metre (WGS-84, vessel)
LINES = np.array([[[LAT0, LON0], [LAT0 + 200 * M_LAT, LON0]],
                  [[LAT0 + 200 * M_LAT, LON0 + 0.0003], [LAT0, LON0 + 0.0003]]])  # fmt: skip
PLAN = np.array([[LAT0, LON0], [LAT0 + 200 * M_LAT, LON0], [LAT0 + 200 * M_LAT, LON0 + 0.0003],
                 [LAT0, LON0 + 0.0003]])  # fmt: skip


def _features(doc: dict) -> dict[str, list]:
    return {f["properties"]["name"]: f["geometry"]["coordinates"] for f in doc["features"]}


def test_the_layer_is_lon_lat_decimated_and_follows_the_plan():
    layer = MissionLayer(step_m=3.0, every_s=5.0)
    layer.fix(LAT0 - 10 * M_LAT, LON0)
    assert not layer.due(0)  # no mission yet (the track is kept for when there is one)
    layer.set_plan(LINES, PLAN)
    assert layer.due(0) and not layer.due(1)  # a new plan goes out at once, then nothing changed
    for k in range(1000):  # 100 m north in 10 cm steps: one point kept per 3 m
        layer.fix(LAT0 + k * 0.1 * M_LAT, LON0)
    layer.fix(float("nan"), LON0)
    assert 31 <= len(layer.track) <= 36
    assert not layer.due(4 * 10**9) and layer.due(5 * 10**9)  # the track: every 5 s of log time
    f = _features(layer.geojson())
    assert set(f) == {"intended line 1", "intended line 2", "plan: the original", "flown track"}
    assert f["intended line 2"][0] == [round(LON0 + 0.0003, 7), round(LAT0 + 200 * M_LAT, 7)]
    assert f["plan: the original"] == [[round(b, 7), round(a, 7)] for a, b in PLAN]
    moved = PLAN.copy()
    moved[2:, 1] -= 0.0001  # an accepted replan moves the second line's ends upstream
    layer.set_plan(LINES, moved)
    assert layer.due(5 * 10**9 + 1)  # at once, though the track went out a moment ago
    f = _features(layer.geojson())
    assert f["plan: replan 1"][2] == [round(LON0 + 0.0002, 7), round(LAT0 + 200 * M_LAT, 7)]


def _last_track_len(client) -> int:
    shown = [p for t, _, p in list(client.messages) if t == TOPIC]
    if not shown:
        return 0
    return len(_features(json.loads(json.loads(shown[-1])["geojson"])).get("flown track", []))


def test_the_live_server_shows_the_mission_and_the_log_does_not_have_it(tmp_path):
    live = LiveService("127.0.0.1", 0, maps=False)
    client = LiveClient(f"ws://127.0.0.1:{live.server.port}")
    log = McapLog(tmp_path)
    try:
        client.wait_ready()
        client.wait_for(lambda c: live.server.stats()["subscriptions"] >= len(c.channels) > 0, 30)
        live.attach(log)
        live.mission.set_plan(LINES, PLAN)
        t0 = 1_763_000_000 * 10**9
        for k in range(120):  # two minutes at 1 m/s, one fix a second
            t = t0 + k * 10**9
            fix = LocationFix(Time(t // 10**9, 0), "gps", LAT0 + k * M_LAT, LON0, 0.0, [0.0] * 9, 0)
            log.write("/fix", t, fix)
        log.close()
        live.finish()  # the survey's last view goes out, the server stays up: wait for it, not for a time
        client.wait_for(lambda c: c.topics().get("/fix", 0) == 120 and _last_track_len(c) == 40, 60)
    finally:
        live.close()
        client.close()
    shown = [json.loads(json.loads(p)["geojson"]) for t, _, p in client.messages if t == TOPIC]
    assert not client.invalid
    # the plan at once, then the track every 5 s of log time, and the last metres at the end
    assert 120 // 5 <= len(shown) <= 120 // 5 + 3
    last = _features(shown[-1])
    # 117 m in 3 m steps (a point each 3 fixes) and the first
    assert len(last["flown track"]) == 40
    assert last["flown track"][-1] == [LON0, round(LAT0 + 117 * M_LAT, 7)]
    assert TOPIC not in {t for t, _, _ in mcap_messages(log.path)}  # a view, not a record
