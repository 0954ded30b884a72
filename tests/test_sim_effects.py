"""Instrument effects show in the bytes the instruments send, and only when switched on."""

from __future__ import annotations

import math
from collections import defaultdict

import numpy as np
import pytest
from forcemap.protocol import wire
from forcemap.sim_devices.engine import Simulation
from forcemap.sim_devices.instruments import InstrumentConfig, along_axis
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

DURATION = 240.0


def run(effects: list[str]) -> tuple[Simulation, dict[str, list[tuple[int, bytes]]]]:
    streams: dict[str, list[tuple[int, bytes]]] = defaultdict(list)
    sim = Simulation("river", "lawnmower", effects=effects, seed=2)
    sim.run(DURATION, lambda s, t, d: streams[s].append((t, d)))
    return sim, streams


@pytest.fixture(scope="module")
def base() -> tuple[Simulation, dict[str, list[tuple[int, bytes]]]]:
    return run([])


def wheel_rates(
    sim: Simulation, streams: dict[str, list[tuple[int, bytes]]]
) -> tuple[np.ndarray, np.ndarray]:
    """(sim time, pulses/s per channel) from consecutive SAMPLE frames, 5 s apart."""
    dec = wire.StreamDecoder()
    fr = [f for _, d in streams["bridge"] for f in dec.feed(d) if f.msg_type == wire.SAMPLE]
    t, r = [], []
    for a, b in zip(fr[::20], fr[20::20], strict=False):
        dt = (b.t_us - a.t_us) * 1e-6
        chans = [a.fields["anemo"], *a.fields["wheels"]], [b.fields["anemo"], *b.fields["wheels"]]
        r.append([wire.count_delta(x[0], y[0]) / dt for x, y in zip(*chans, strict=True)])
        t.append(0.5 * (a.t_us + b.t_us) * 1e-6)
    return np.array(t), np.array(r)


def attitude(
    sim: Simulation, streams: dict[str, list[tuple[int, bytes]]]
) -> list[tuple[float, object]]:
    mav = mavlink2.MAVLink(None)
    return [
        (t * 1e-9 - sim.scenario.t0, m)
        for t, d in streams["mavlink"]
        for m in (mav.parse_buffer(d) or [])
        if m.get_type() == "ATTITUDE"
    ]


def test_wheel_misalignment(base) -> None:  # type: ignore[no-untyped-def]
    sim, st = run(["wheel_misalignment:wheel=1:angle_deg=20"])
    _, r_on = wheel_rates(sim, st)
    _, r_off = wheel_rates(*base)
    # the same boat motion (the effect is in the instrument only) ...
    assert np.allclose(sim.track["x"], base[0].track["x"])
    # ... read through a wheel turned 20 deg: wheel 1 changes, the others do not
    assert np.allclose(r_on[:, 2:], r_off[:, 2:], rtol=0.01, atol=0.5)
    ratio = np.median(r_on[:, 1] / np.maximum(r_off[:, 1], 1e-9))
    assert abs(ratio - 1.0) > 0.1
    # and it matches the cosine response of the rotated axis
    tr = sim.track
    expect = np.median(
        np.abs([along_axis(u, v, 0.0, 65.0, (0, 0)) for u, v in zip(tr["u"], tr["v"], strict=True)])
    )
    nominal = np.median(tr["wheel1_speed"])
    assert ratio == pytest.approx(expect / nominal, rel=0.15)


def test_anemometer_upwash(base) -> None:  # type: ignore[no-untyped-def]
    sim, st = run(["anemometer_upwash"])
    _, r_on = wheel_rates(sim, st)
    _, r_off = wheel_rates(*base)
    stw = np.median(np.hypot(sim.track["u"], sim.track["v"]))
    assert np.median(r_on[:, 0] / r_off[:, 0]) == pytest.approx(1.0 + 0.08 * stw, rel=0.05)


def test_compass_deviation(base) -> None:  # type: ignore[no-untyped-def]
    sim, st = run(["compass_deviation"])
    tr = sim.track
    att = attitude(sim, st)
    t = np.array([a for a, _ in att])
    yaw = np.degrees([m.yaw for _, m in att])
    hd = np.interp(t, tr["t"], np.unwrap(tr["heading"], period=360.0))
    err = (yaw - hd + 180.0) % 360.0 - 180.0
    expect = 10.0 * np.sin(np.radians(hd + 30.0))
    assert np.median(np.abs(err - expect)) < 1.0 and np.abs(err).max() > 7.0
    base_att = attitude(*base)
    t0 = np.array([a for a, _ in base_att])
    e0 = (
        np.degrees([m.yaw for _, m in base_att])
        - np.interp(t0, tr["t"], np.unwrap(tr["heading"], period=360.0))
        + 180
    ) % 360 - 180
    assert np.abs(e0).max() < 3.0


def test_clock_offset(base) -> None:  # type: ignore[no-untyped-def]
    sim, st = run(["clock_offset"])
    _, sb = base
    # the autopilot's bytes are the same, 1.5 s later relative to the bridge's
    assert b"".join(d for _, d in st["mavlink"]) == b"".join(d for _, d in sb["mavlink"])
    assert b"".join(d for _, d in st["bridge"]) == b"".join(d for _, d in sb["bridge"])
    lag = np.array([a[0] - b[0] for a, b in zip(st["mavlink"], sb["mavlink"], strict=True)])
    assert np.all(lag == 1_500_000_000)
    import json

    assert math.isclose(sim.meta()["instruments"]["mavlink_latency_s"], 1.5)
    json.dumps(sim.meta())


def test_hidden_effect_is_recorded() -> None:
    sim = Simulation("lake", effects=["gusts:peak_factor=1.5", "compass_deviation"])
    sim.run(5.0, lambda *a: None)
    meta = sim.meta()
    assert [(e["name"], e["kind"]) for e in meta["effects"]] == [
        ("gusts", "world"),
        ("compass_deviation", "instrument"),
    ]
    assert meta["effects"][0]["params"]["peak_factor"] == 1.5
    assert InstrumentConfig().wheel_angles_deg == (45.0, 135.0, -135.0, -45.0)
