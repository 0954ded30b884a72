"""A simulated moving-boat ADCP: the river's true current profile along the boat's track, written as
TRDI PD0 ensembles (a Workhorse 1200 kHz in ship coordinates, WinRiver II's GGA blocks) that
``forcemap import`` reads back through dolfyn.

The profile is a 1/6 power law under the simulated surface current: ``u(z) = U_s (z / D)^(1/6)`` at
height ``z`` above the bed in water ``D`` deep, so the true depth average is ``6/7 U_s``. The ADCP
measures the water relative to itself in ship coordinates (x starboard, y forward) with seeded noise;
the bottom track is the bed's velocity relative to the boat. Its compass reads the true heading plus
``compass_error_deg`` (so the correction that undoes it is minus that), its clock runs
``clock_error_s`` off GPS UTC, and bottom track is lost in seeded runs (``bt_loss``), where the
ensemble carries TRDI's no-data values. A GGA fix rides in every ``gps_every``-th ensemble.

    truth = read_truth("out/truth/samples.csv")
    pd0, per_ensemble = SimAdcp(AdcpSetup(compass_error_deg=6.0, bt_loss=0.1)).record(truth)
"""

from __future__ import annotations

import csv
import math
import struct
from dataclasses import dataclass, fields
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

POWER = 1.0 / 6.0
NO_DATA = -32768
FIRMWARE = (51, 40)  # a Workhorse, as dolfyn names firmware 51
SHIP_WITH_TILTS = 0x10 | 0x04  # EX: ship coordinates, tilts used


@dataclass
class AdcpSetup:
    """The instrument and what goes wrong with it."""

    period_s: float = 1.0
    cell_size: float = 0.25
    blank: float = 0.25
    n_cells: int = 40
    draft: float = 0.2
    beam_angle: float = 20.0
    noise: float = 0.03  # m/s per cell and component
    bt_noise: float = 0.005
    compass_error_deg: float = 0.0
    clock_error_s: float = -2.5  # the instrument's clock minus UTC
    bt_loss: float = 0.0  # share of ensembles without bottom track, lost in runs
    gps_every: int = 5
    gps_noise_m: float = 0.2
    hdop: float = 0.9
    seed: int = 0

    @property
    def bin1(self) -> float:
        return self.blank + self.cell_size


def read_truth(path: str | Path) -> dict[str, np.ndarray]:
    """The simulator's truth table (samples.csv, docs/CONVENTIONS.md) by column."""
    with open(path) as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def _fixed(s: AdcpSetup) -> bytes:
    head = bytes([FIRMWARE[0], FIRMWARE[1], 0x0C, 0x41, 0, 0, 4, s.n_cells])
    body = struct.pack(
        "<HHHBBBBH3BBhhBBHHBBBBH",
        1,  # pings per ensemble
        round(s.cell_size * 100),
        round(s.blank * 100),
        1,  # profiling mode
        64,  # correlation threshold
        1,
        0,
        2000,  # error velocity max, mm/s
        0,
        round(s.period_s),
        0,
        SHIP_WITH_TILTS,
        0,  # heading alignment
        0,  # magnetic variation
        0x7D,
        0x7D,
        round(s.bin1 * 100),
        round(s.cell_size * 100),
        1,
        5,
        50,
        0,
        round(s.cell_size * 100),
    )
    tail = bytes(8) + struct.pack("<H", 0) + struct.pack("<BBIB", 255, 0, 1, round(s.beam_angle))
    return b"\x00\x00" + head + body + tail


def _variable(s: AdcpSetup, number: int, t_inst: float, heading: float, temp: float) -> bytes:
    d = datetime.fromtimestamp(t_inst, UTC)
    hund = min(99, round(d.microsecond / 1e4))
    rtc = bytes([d.year % 100, d.month, d.day, d.hour, d.minute, d.second, hund])
    out = struct.pack("<H", 0x0080) + struct.pack("<H", number & 0xFFFF) + rtc
    out += struct.pack(
        "<BHHHHhhhh", number >> 16, 0, 1500, round(s.draft * 10), round(heading % 360 * 100), 0, 0,
        0, round(temp * 100),
    )  # fmt: skip
    out += bytes([0, 0, 0, 0, 0, 0]) + bytes(8)  # pre-ping wait, std devs, ADC
    out += struct.pack("<I", 0) + bytes(2) + struct.pack("<II", 0, 0) + bytes(1)
    out += bytes([d.year // 100]) + bytes([d.year % 100, d.month, d.day, d.hour, d.minute])
    out += bytes([d.second, hund])
    return out


def _velocity(vel: np.ndarray) -> bytes:
    """(m, 4) m/s, NaN as no data."""
    mm = np.where(np.isfinite(vel), np.round(vel * 1000), NO_DATA).astype("<i2")
    return struct.pack("<H", 0x0100) + mm.tobytes()


def _bottom(ranges: np.ndarray | None, vel: np.ndarray | None) -> bytes:
    out = struct.pack("<H", 0x0600) + bytes(14)
    if ranges is None or vel is None:
        out += struct.pack("<4H", 0, 0, 0, 0) + struct.pack("<4h", *([NO_DATA] * 4))
        out += bytes(12)
    else:
        cm = np.round(ranges * 100).astype(int)
        out += struct.pack("<4H", *(c & 0xFFFF for c in cm))
        out += struct.pack("<4h", *np.round(vel * 1000).astype(int))
        out += bytes([200] * 4) + bytes([100] * 4) + bytes([100] * 4)
    out += bytes(26) + bytes(7)
    out += bytes([0, 0, 0, 0]) if ranges is None else bytes(int(c) >> 16 for c in cm)
    return out + bytes(4)


def _gga(t_utc: float, lat: float, lon: float, hdop: float) -> bytes:
    d = datetime.fromtimestamp(t_utc, UTC)
    tod = f"{d.hour:02d}{d.minute:02d}{d.second:02d}.{min(99, round(d.microsecond / 1e4)):02d}"
    body = struct.pack("<d", 0.0) + b"$GPGGA," + tod.encode() + b","
    body += struct.pack("<d", abs(lat)) + (b"N" if lat >= 0 else b"S")
    body += struct.pack("<d", abs(lon)) + (b"E" if lon >= 0 else b"W")
    body += struct.pack("<BBff", 2, 12, hdop, 10.0) + b"m" + struct.pack("<f", 0.0) + b"m"
    body += struct.pack("<fH", 1.0, 0)
    return struct.pack("<HHH", 0x2022, 104, len(body) + 2) + body


def ensemble(blocks: list[bytes]) -> bytes:
    """A PD0 ensemble: header, the blocks at their offsets, reserved word and checksum."""
    n = len(blocks)
    offsets, pos = [], 6 + 2 * n
    for b in blocks:
        offsets.append(pos)
        pos += len(b)
    nbytes = pos + 2  # the reserved word; the checksum follows and is not counted
    data = b"\x7f\x7f" + struct.pack("<HBB", nbytes, 0, n) + struct.pack(f"<{n}H", *offsets)
    data += b"".join(blocks) + b"\x00\x00"
    return data + struct.pack("<H", sum(data) & 0xFFFF)


def _bt_lost(n: int, share: float, rng: np.random.Generator) -> np.ndarray:
    """Seeded runs of 2 to 8 ensembles without bottom track, ``share`` of them in all."""
    lost = np.zeros(n, bool)
    while lost.mean() < share:
        start = int(rng.integers(0, n))
        lost[start : start + int(rng.integers(2, 9))] = True
    return lost


class SimAdcp:
    """The simulated ADCP: ``record`` a truth track into PD0 bytes and the per-ensemble truth."""

    def __init__(self, setup: AdcpSetup | None = None) -> None:
        self.s = setup or AdcpSetup()

    def record(self, truth: dict[str, np.ndarray]) -> tuple[bytes, dict[str, np.ndarray]]:
        """PD0 bytes, and per ensemble: UTC ``t``, true depth-averaged and near-surface current."""
        s = self.s
        rng = np.random.default_rng([s.seed, 32])
        t = np.arange(truth["t"][0], truth["t"][-1], s.period_s)
        at = {k: np.interp(t, truth["t"], truth[k]) for k in truth if k not in ("heading",)}
        hd = np.radians(truth["heading"])
        at["heading"] = (
            np.degrees(
                np.arctan2(
                    np.interp(t, truth["t"], np.sin(hd)), np.interp(t, truth["t"], np.cos(hd))
                )
            )
            % 360.0
        )
        lost = _bt_lost(t.size, s.bt_loss, rng) if s.bt_loss > 0 else np.zeros(t.size, bool)
        fixed = _fixed(s)
        cells = s.bin1 + np.arange(s.n_cells) * s.cell_size
        out = bytearray()
        truth_out = {
            "t": t,
            "davg_e": at["current_east"] * 6 / 7,
            "davg_n": at["current_north"] * 6 / 7,
        }
        for i in range(t.size):
            out += self._one(i, t[i], at, cells, fixed, lost[i], rng)
        return bytes(out), truth_out

    def _one(self, i, t, at, cells, fixed, lost, rng) -> bytes:  # type: ignore[no-untyped-def]
        s = self.s
        h = math.radians(at["heading"][i])
        depth = at["depth"][i]
        below = depth - s.draft
        z = depth - (s.draft + cells)  # height above the bed
        ok = z > 0
        prof = np.where(ok, (np.clip(z, 0, None) / depth) ** POWER, math.nan)
        we = at["current_east"][i] * prof - at["boat_east"][i]
        wn = at["current_north"][i] * prof - at["boat_north"][i]
        we = we + rng.normal(0, s.noise, cells.size)
        wn = wn + rng.normal(0, s.noise, cells.size)
        x, y = we * math.cos(h) - wn * math.sin(h), we * math.sin(h) + wn * math.cos(h)
        w = np.where(ok, rng.normal(0, s.noise, cells.size), math.nan)
        vel = np.column_stack([x, y, w, np.where(ok, 0.0, math.nan)])
        blocks = [
            fixed,
            _variable(
                s, i + 1, t + s.clock_error_s, math.degrees(h) + s.compass_error_deg,
                at["water_temp"][i],
            ),
            _velocity(vel),
        ]  # fmt: skip
        if lost:
            blocks.append(_bottom(None, None))
        else:
            be = -at["boat_east"][i] + rng.normal(0, s.bt_noise)
            bn = -at["boat_north"][i] + rng.normal(0, s.bt_noise)
            bx, by = be * math.cos(h) - bn * math.sin(h), be * math.sin(h) + bn * math.cos(h)
            blocks.append(_bottom(np.full(4, below), np.array([bx, by, 0.0, 0.0])))
        if i % s.gps_every == 0:
            dlat = rng.normal(0, s.gps_noise_m) / 111_320.0
            dlon = rng.normal(0, s.gps_noise_m) / (111_320.0 * math.cos(math.radians(at["lat"][i])))
            blocks.append(_gga(t, at["lat"][i] + dlat, at["lon"][i] + dlon, s.hdop))
        return ensemble(blocks)


def write_pd0(path: str | Path, data: bytes) -> Path:
    """The PD0 bytes to ``path``."""
    p = Path(path)
    p.write_bytes(data)
    return p


def parse_setup(text: str) -> AdcpSetup:
    """``key=value,...`` of AdcpSetup's fields (``bt_loss=0.1,compass_error_deg=6``); ValueError."""
    known = {f.name: f.type for f in fields(AdcpSetup)}
    kw: dict[str, float | int] = {}
    for item in filter(None, (p.strip() for p in text.split(","))):
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or key not in known:
            raise ValueError(
                f"ADCP setting {item!r}: give key=value with a key of {', '.join(sorted(known))}"
            )
        try:
            kw[key] = int(value) if known[key] in ("int", int) else float(value)
        except ValueError:
            raise ValueError(f"ADCP setting {key}: {value!r} is not a number") from None
    return AdcpSetup(**kw)  # type: ignore[arg-type]


def record_run(truth_dir: str | Path, setup: AdcpSetup) -> Path:
    """``truth_dir/adcp.PD0`` from the run's true track (``truth_dir/samples.csv``)."""
    truth = read_truth(Path(truth_dir) / "samples.csv")
    data, _ = SimAdcp(setup).record(truth)
    return write_pd0(Path(truth_dir) / "adcp.PD0", data)
