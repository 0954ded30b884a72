"""Clock mapping: lower-envelope offset+drift fits, new epochs on reset/reboot/jump, GPS UTC."""

from __future__ import annotations

import random

import pytest
from forcemap.host.fuse.timesync import ClockFit, SourceClock, UtcFix, WallClock


def points(n, rate_hz, offset, drift, seed=0, start=100.0, max_latency=0.03):
    """(device_s, host_s) with host = device*(1+drift) + offset + latency >= 0."""
    rng = random.Random(seed)
    out = []
    for i in range(n):
        dev = start + i / rate_hz
        lat = min(rng.expovariate(1 / 0.004), max_latency)
        out.append((dev, dev * (1 + drift) + offset + lat))
    return out


def test_offset_and_drift_recovered_under_latency():
    fit = ClockFit()
    pts = points(4 * 600, 4.0, offset=1_750_000_000.0, drift=50e-6)
    for d, h in pts:
        fit.add(d, h)
    for d in (pts[len(pts) // 2][0], pts[-1][0]):
        true = d * (1 + 50e-6) + 1_750_000_000.0
        assert fit.to_host(d) == pytest.approx(true, abs=2e-3)
    assert fit.drift == pytest.approx(50e-6, abs=5e-6)


def test_the_line_stays_under_the_points():
    fit = ClockFit()
    pts = points(4 * 300, 4.0, offset=10.0, drift=-20e-6, seed=2)
    for d, h in pts:
        fit.add(d, h)
    # latency >= 0: no recent point lies more than a fraction of a millisecond under the mapping
    assert min(h - fit.to_host(d) for d, h in pts[-400:]) > -1e-3


def test_short_fit_is_offset_only():
    fit = ClockFit()
    for d, h in points(20, 4.0, offset=5.0, drift=100e-6, seed=1):
        fit.add(d, h)
    assert fit.drift == 0.0
    assert fit.offset == pytest.approx(5.0 + 100e-6 * 102, abs=3e-3)


def test_new_epoch_on_boot_id_change_and_reboot():
    clk = SourceClock("bridge")
    _, m = clk.observe(10.0, 1000.0, key=1)
    assert m is not None and m.epoch == "1#1"
    clk.observe(11.0, 1001.0, key=1)
    t, m = clk.observe(0.5, 1002.0, key=2)  # board reset: new boot id, device time restarts
    assert m.epoch == "2#2" and t == pytest.approx(1002.0) and clk.resets == 1
    mav = SourceClock("mavlink")
    mav.observe(500.0, 2000.0)
    mav.observe(501.0, 2001.0)
    t, m = mav.observe(3.0, 2002.0)  # time_boot_ms jumped back: the autopilot rebooted
    assert mav.epochs == 2 and t == pytest.approx(2002.0)
    mav.observe(3.7, 2002.5)  # small jitter backwards is not a reboot
    assert mav.epochs == 2


def test_clock_jumps_start_an_epoch_outliers_do_not():
    clk = SourceClock("bridge", jump_points=5)
    for i in range(40):
        clk.observe(i * 0.25, 100 + i * 0.25, key=7)
    # a stalled host: a few points arrive seconds late, then all is well again
    for i in range(40, 44):
        clk.observe(i * 0.25, 103 + i * 0.25, key=7)
    t, _ = clk.observe(11.0, 111.0, key=7)
    assert clk.epochs == 1 and t == pytest.approx(111.0)
    # the device clock jumps 10 s ahead and stays there: a new epoch after 5 points
    for i in range(4):
        t, _ = clk.observe(21.25 + i * 0.25, 111.25 + i * 0.25, key=7)
        assert clk.epochs == 1 and t == pytest.approx(121.25 + i * 0.25)  # still the old line
    t, _ = clk.observe(22.25, 112.25, key=7)
    assert clk.epochs == 2 and t == pytest.approx(112.25)


def test_a_young_fit_comes_down_to_low_points():
    clk = SourceClock("bridge")
    clk.observe(0.0, 102.0, key=1)  # the first read came 2 s late
    t, _ = clk.observe(0.25, 100.25, key=1)
    assert clk.epochs == 1 and t == pytest.approx(100.25)


def test_utc_correction_is_a_robust_median():
    u = UtcFix()
    assert u.to_utc(100.0) == 100.0
    for i in range(20):
        u.observe(1000.0 + i + 0.25, 1000.0 + i)
    u.observe(2000.0, 1020.0)  # one outlier
    assert u.correction == pytest.approx(0.25)
    for i in range(3):  # the host clock was stepped by an hour: start again
        u.observe(1021.25 + i, 1021.0 + i - 3600.0)
    assert u.correction == pytest.approx(3600.25)


def test_wall_clock():
    w = WallClock()
    assert w.to_wall(5.0) == 5.0
    w.observe(5.0, 1000.0)
    assert w.to_wall(6.0) == 1001.0


def test_mapping_message():
    clk = SourceClock("mavlink")
    for d, h in points(100, 10.0, offset=3.0, drift=0.0):
        clk.observe(d, h)
    msg = clk.mapping().as_message()
    assert set(msg) == {
        "source",
        "epoch",
        "offset_s",
        "drift_ppm",
        "ref_device_s",
        "points",
        "span_s",
    }
    assert msg["points"] == 100 and msg["source"] == "mavlink"


def test_mappings_are_reported_sparingly():
    clk = SourceClock("bridge")
    reported = [
        m
        for d, h in points(4 * 1200, 4.0, offset=7.0, drift=30e-6, seed=4)
        if (m := clk.observe(d, h, key=1)[1]) is not None
    ]
    assert 20 <= len(reported) <= 150  # a 20-minute fit: settling, then about once a minute
    assert reported[-1].drift * 1e6 == pytest.approx(30.0, abs=5.0)


def test_a_stalled_reader_is_latency_not_a_jump():
    clk = SourceClock("mavlink")
    for i in range(3000):  # 5 minutes at 10 Hz, read on time
        clk.observe(i * 0.1, 1000.0 + i * 0.1)
    # the reader stalls: 300 messages (30 s) arrive up to 4 s late, the backlog building and draining
    worst = 0.0
    for i in range(3000, 3300):
        late = 4.0 * (1 - abs(i - 3150) / 150)
        t, _ = clk.observe(i * 0.1, 1000.0 + i * 0.1 + late)
        worst = max(worst, abs(t - (1000.0 + i * 0.1)))
    assert clk.epochs == 1
    assert worst < 0.05  # the bins whose minimum is late tilt the drift a little; nothing more


def test_a_device_clock_late_for_minutes_starts_an_epoch():
    clk = SourceClock("mavlink", late_s=60.0)
    for i in range(400):
        clk.observe(i * 0.1, 1000.0 + i * 0.1)
    # from here the host sees every message 5 s later than the line says, for good
    for i in range(400, 400 + 590):
        clk.observe(i * 0.1, 1005.0 + i * 0.1)
    assert clk.epochs == 1
    for i in range(990, 1020):
        t, _ = clk.observe(i * 0.1, 1005.0 + i * 0.1)
    assert clk.epochs == 2 and t == pytest.approx(1005.0 + 1019 * 0.1, abs=1e-6)
