"""How long the navigation smoother takes on a 90-minute log (issue 29): `python bench/bench_navigation.py`.

A synthetic 90-minute survey at 3 m/s with a turn every 2 minutes, read as the smoother reads a log:
a coarse receiver (RMC, GGA and GLL each at 1 Hz: 3 readings/s, and its SOG/COG), a precise one
(the same every 4 s), two compasses at 2 Hz (one 5 s late), a rate-of-turn sensor at 2 Hz and a
speed log at 1 Hz; one row per second. The figures: the smoother's wall and CPU time, and the same
as a ratio to the baseline in the same process, `source_stats.analyse` of the same sources (what
`log info` has computed since issue 20: every source against the chosen one, and its latency).
"""

from __future__ import annotations

import math
import time

import numpy as np
from forcemap.host.convert.nav_readings import SourceData
from forcemap.host.convert.navigation import Navigation
from forcemap.host.fuse import source_stats
from forcemap.host.vessel.geodesy import LocalFrame

DURATION_S = 5400.0
SPEED = 3.0


def truth(t: np.ndarray) -> tuple[np.ndarray, ...]:
    """x, y (m), heading (deg), yaw rate (deg/s), v_east, v_north: turns of 90 deg every 120 s."""
    phase = (t % 120.0) / 120.0
    rate = np.where(phase < 0.1, 90.0 / 12.0, 0.0)  # deg/s during the first 12 s of each leg
    heading = np.cumsum(rate) * (t[1] - t[0])
    ve, vn = SPEED * np.sin(np.radians(heading)), SPEED * np.cos(np.radians(heading))
    x, y = np.cumsum(ve) * (t[1] - t[0]), np.cumsum(vn) * (t[1] - t[0])
    return x, y, heading % 360.0, rate, ve, vn


def readings(rng: np.random.Generator) -> dict[str, dict[str, SourceData]]:
    fine = np.arange(0.0, DURATION_S, 0.05)
    x, y, h, r, ve, vn = truth(fine)
    frame = LocalFrame(46.2, 6.2)
    t0 = 1.7e9

    def at(ts: np.ndarray, a: np.ndarray) -> np.ndarray:
        return np.interp(ts, fine, a)

    out: dict[str, dict[str, SourceData]] = {
        "position": {},
        "heading": {},
        "yaw_rate": {},
        "stw": {},
    }
    for name, period, err, fixes in (("coarse", 1.0, 1.0, 3), ("precise", 4.0, 0.1, 4)):
        src = SourceData(
            f"nmea G{name[0].upper()}* [hhmmss.ss 5dp]", fixes=[fixes] * 10, hdops=[1.0]
        )
        for k in range(3):  # RMC, GGA, GLL at 0, 0.3, 0.6 s
            ts = np.arange(0.3 * k, DURATION_S, period)
            lat, lon = frame.to_latlon(
                at(ts, x) + rng.normal(0, err, len(ts)), at(ts, y) + rng.normal(0, err, len(ts))
            )
            sog = np.hypot(at(ts, ve), at(ts, vn)) if k == 0 else np.full(len(ts), np.nan)
            cog = np.degrees(np.arctan2(at(ts, ve), at(ts, vn))) % 360 if k == 0 else sog
            src.t += list(t0 + ts)
            src.v += [list(v) for v in zip(lat, lon, sog, cog, strict=True)]
        out["position"][src.name] = src
    for name, late, sd in (("nmea HEHDT", 5.0, 0.5), ("nmea HCHDG", 0.0, 1.0)):
        ts = np.arange(0.1, DURATION_S, 0.5)
        hv = (
            at(ts - late, np.degrees(np.unwrap(np.radians(h)))) + rng.normal(0, sd, len(ts))
        ) % 360
        out["heading"][name] = SourceData(name, list(t0 + ts), [[v] for v in hv], used=1)
    ts = np.arange(0.2, DURATION_S, 0.5)
    out["yaw_rate"]["nmea TIROT"] = SourceData(
        "nmea TIROT", list(t0 + ts), [[v] for v in at(ts, r) + rng.normal(0, 0.05, len(ts))]
    )
    ts = np.arange(0.4, DURATION_S, 1.0)
    out["stw"]["nmea VWVHW"] = SourceData("nmea VWVHW", list(t0 + ts), [[SPEED]] * len(ts), used=1)
    return out


def baseline(data: dict[str, dict[str, SourceData]]) -> None:
    tracks = {
        q: {n: source_stats.Track(n, *s.arrays()) for n, s in srcs.items()}
        for q, srcs in data.items()
    }
    chosen = {q: next(iter(srcs)) for q, srcs in data.items()}
    source_stats.analyse(tracks, chosen)


def timed(fn) -> tuple[float, float]:
    w, c = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - w, time.process_time() - c


def main() -> None:
    data = readings(np.random.default_rng(1))
    n = sum(len(s.t) for srcs in data.values() for s in srcs.values())
    rows = 1.7e9 + np.arange(0.0, DURATION_S, 1.0)
    nav = Navigation()
    base = timed(lambda: baseline(data))
    fit = timed(lambda: nav.fit(data, rows))
    late = next(f for f in nav.fits_ if f.source == "nmea HEHDT")
    print(f"{n} readings, {len(rows)} rows, {DURATION_S / 60:.0f} min")
    print(f"baseline source_stats.analyse: {base[0]:.2f} s wall, {base[1]:.2f} s CPU")
    print(
        f"Navigation.fit: {fit[0]:.2f} s wall, {fit[1]:.2f} s CPU ({fit[1] / base[1]:.2f}x the baseline's CPU)"
    )
    print(f"late compass measured {late.latency:+.2f} s (truth +5.00)")
    st = nav.state(rows)
    frame = LocalFrame(46.2, 6.2)
    x, y = frame.to_local(st["lat"], st["lon"])
    tx, ty, *_ = truth(np.arange(0.0, DURATION_S, 0.05))
    fine = np.arange(0.0, DURATION_S, 0.05)
    err = np.hypot(x - np.interp(rows - 1.7e9, fine, tx), y - np.interp(rows - 1.7e9, fine, ty))
    print(f"position error p95 {np.percentile(err, 95):.2f} m; rows {math.floor(len(rows))}")


if __name__ == "__main__":
    main()
