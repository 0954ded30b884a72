"""Per-run fault schedules: damaged bytes, cable pulls, board resets, GPS loss, NMEA garbage, clock jumps."""

from __future__ import annotations

import math
import tomllib
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

SOURCES = ("bridge", "depth", "mavlink", "nmea")
# faults that are instruments: they put the NMEA bus (nmea_bus.py) on the "nmea" port
SOURCE_KINDS = ("second_gnss", "relay_position", "second_compass", "rate_of_turn")
# faults of the bus's own instruments with a known truth (issue 28): the estimators must find them
CAL_KINDS = ("speed_log", "dead_log", "rot_deg_s")
BUS_KINDS = (
    SOURCE_KINDS
    + (
        "poor_gnss",
        "dgps_gnss",
        "no_variation",
        "checksum_variant",
        "position_jump",
        "nav_receivers",
        "late_compass",
    )
    + CAL_KINDS
)

KINDS: dict[str, str] = {
    "corrupt": "bytes replaced by random values at `rate` per byte (source=all|bridge|depth|mavlink)",
    "drop": "bytes lost at `rate` per byte",
    "pull": "cable pull: the port disappears for `for` s and comes back under the same path (a bridge re-boots)",
    "reset": "bridge board reset (watchdog by default: cause=3) at `at`",
    "gps_loss": "the autopilot loses GPS for `for` s: no fix, the position coasts",
    "nmea_garbage": "the sounder line gets spliced sentences, bad checksum digits and junk lines at `rate` per sentence",
    "clock_jump": "the autopilot's clocks (time_boot_ms, UNIX time) step by `jump` s at `at`",
    "second_gnss": "NMEA bus: a second GP receiver, antenna 2 m to starboard, hhmmss and 3 decimals "
    "every 2 s, 1 s late",
    "relay_position": "NMEA bus: the instrument bus re-sends the GNSS fix as IIRMC at 3 decimals",
    "second_compass": "NMEA bus: a damped IIHDT (2 s time constant, 1 Hz) beside the HCHDG fluxgate",
    "rate_of_turn": "NMEA bus: a rate gyro's TIROT at 2 Hz",
    "poor_gnss": "NMEA bus: the GP receiver is autonomous with HDOP 2.1 and a 2 m error that "
    "wanders in seconds",
    "dgps_gnss": "NMEA bus: a second receiver, GN, 4 decimals, DGPS with HDOP 0.9 and a 0.3 m error; "
    "it loses its corrections (autonomous, HDOP 4.5, 3 m error) from `at` for `for` s",
    "no_variation": "NMEA bus: the compass's HDG has empty variation fields (its magnetic heading "
    "is the truth less IGRF-14's declination), as RMC's",
    "checksum_variant": "NMEA bus: every sentence's checksum computed over its address only",
    "position_jump": "NMEA bus: the GNSS's fixes are 500 km north of the boat from `at` for `for` s",
    "bottom_lost": "the sounder loses the bottom from `at` for `for` s: its returns scatter "
    "from 3 to 70 m",
    "beyond_range": "the sounder's range is `range` m (default 90) and the sea is rough: where the bed "
    "is deeper, it loses the bottom and its returns scatter from 3 m to its range",
    "speed_log": "NMEA bus: the speed log reads STW / `gain` (default 1.06) and its axis is turned "
    "`misalign` deg (default 2) clockwise from the compass's: HCHDG reads heading - misalign",
    "dead_log": "NMEA bus: the speed log reads 0.00 kn from `at` for `for` s",
    "rot_deg_s": "NMEA bus: a rate gyro's TIROT at 2 Hz in deg/s, where NMEA 0183 says deg/min",
    "nav_receivers": "NMEA bus: a coarse GP receiver (1 Hz, 1 m error) and a precise GN one (every 4 s, "
    "0.1 m error), each sending RMC, GGA and GLL at their own instants and UTC stamps",
    "late_compass": "NMEA bus: a HEHDT gyro compass at 2 Hz, 5 s late, beside the on-time HCHDG fluxgate",
    "false_echoes": "the sounder returns 3-20 m at `rate` per sounding in water deeper than 70 m "
    "(a share of it from 40 m)",
}


@dataclass
class Fault:
    """One scheduled fault. Times are seconds from the start; ``at_frac`` places it by run fraction."""

    kind: str
    source: str = "all"
    at: float | None = None
    at_frac: float | None = None
    dur: float = 0.0  # "for" in specs
    rate: float = 0.0
    jump: float = 0.0
    cause: int = 3
    params: dict[str, float] = field(default_factory=dict)

    def start(self, duration_s: float) -> float:
        if self.at is not None:
            return self.at
        if self.at_frac is not None:
            return self.at_frac * duration_s
        return 0.0

    def end(self, duration_s: float) -> float:
        if self.kind in ("corrupt", "drop", "nmea_garbage") and self.dur <= 0:
            return float("inf")
        return self.start(duration_s) + self.dur

    def applies_to(self, source: str) -> bool:
        return self.source in ("all", source)

    def resolved(self, duration_s: float) -> dict[str, object]:
        d = asdict(self)
        d["at"] = self.start(duration_s)
        d["end"] = min(self.end(duration_s), duration_s)
        d.pop("at_frac")
        d["for"] = d.pop("dur")
        return d


def default_set() -> list[Fault]:
    """The `default` fault set: a bit of everything, placed by fraction of the run."""
    return [
        Fault("corrupt", "all", rate=2e-5),
        Fault("drop", "all", rate=1e-5),
        Fault("nmea_garbage", "depth", rate=0.02),
        Fault("pull", "bridge", at_frac=0.30, dur=5.0),
        Fault("reset", "bridge", at_frac=0.50),
        Fault("gps_loss", "mavlink", at_frac=0.65, dur=15.0),
        Fault("pull", "depth", at_frac=0.75, dur=4.0),
        Fault("clock_jump", "mavlink", at_frac=0.85, jump=2.0),
    ]


def sources_set() -> list[Fault]:
    """The `sources` set: two of everything on an NMEA bus, and false echoes (issue 20)."""
    return [Fault(k, "nmea") for k in SOURCE_KINDS] + [Fault("false_echoes", "depth", rate=0.1)]


SETS = {"default": default_set, "none": list, "sources": sources_set}


def parse_one(spec: str) -> Fault:
    """``kind:key=value:...``, e.g. ``pull:source=bridge:at=120:for=5`` or ``corrupt:rate=1e-3``."""
    kind, *kvs = spec.strip().split(":")
    if kind not in KINDS:
        raise ValueError(f"unknown fault {kind!r}; known: {', '.join(KINDS)}")
    f = Fault(
        kind,
        source={
            "reset": "bridge",
            "gps_loss": "mavlink",
            "clock_jump": "mavlink",
            "nmea_garbage": "depth",
            "false_echoes": "depth",
            "bottom_lost": "depth",
            "beyond_range": "depth",
            **dict.fromkeys(BUS_KINDS, "nmea"),
        }.get(kind, "all"),
    )
    for kv in kvs:
        k, _, v = kv.partition("=")
        if k == "source":
            if v not in SOURCES + ("all",):
                raise ValueError(f"fault source must be one of {SOURCES} or all, not {v!r}")
            f.source = v
        elif k in ("at", "at_frac", "rate", "jump"):
            setattr(f, k, float(v))
        elif k in ("for", "dur"):
            f.dur = float(v)
        elif k == "cause":
            f.cause = int(v)
        elif k in ("gain", "misalign") and kind == "speed_log":
            f.params[k] = float(v)
        elif k == "range" and kind == "beyond_range":
            f.params[k] = float(v)
        else:
            raise ValueError(f"fault {kind} has no parameter {k!r}")
    if kind == "pull" and f.source == "all":
        raise ValueError("a pull needs source=bridge|depth|mavlink")
    return f


def parse(spec: str | list[str | Fault] | None) -> list[Fault]:
    """Faults from None, a set name (default, none), a TOML file, comma-separated specs or a list."""
    if spec is None:
        return []
    if isinstance(spec, list):
        return [s if isinstance(s, Fault) else parse_one(s) for s in spec]
    if spec in SETS:
        return SETS[spec]()
    p = Path(spec)
    if p.suffix == ".toml" and p.exists():
        data = tomllib.loads(p.read_text())
        out = []
        for t in data.get("fault", []):
            kvs = [f"{k}={v}" for k, v in t.items() if k != "kind"]
            out.append(parse_one(":".join([t["kind"], *kvs])))
        return out
    out = []
    for part in spec.split(","):
        part = part.strip()
        if part in SETS:
            out += SETS[part]()
        elif part:
            out.append(parse_one(part))
    return out


def lines() -> list[str]:
    """One line per fault kind, and the sets, for ``forcemap sim --list``."""
    out = [f"{k:14s} {v}" for k, v in KINDS.items()]
    out.append(
        f"{'default':14s} set: "
        + ", ".join(
            f"{f.kind}({f.source}{'' if f.at_frac is None else f' at {f.at_frac:.0%}'})"
            for f in default_set()
        )
    )
    out.append(f"{'sources':14s} set: " + ", ".join(f.kind for f in sources_set()))
    return out


class ByteDamage:
    """Applies corruption and drops to one source's chunks, deterministically per seed."""

    def __init__(self, source: str, faults: list[Fault], duration_s: float, seed: int) -> None:
        self.rng = np.random.default_rng([seed, 7, SOURCES.index(source)])
        self.windows = [
            (f.kind, f.rate, f.start(duration_s), f.end(duration_s))
            for f in faults
            if f.kind in ("corrupt", "drop") and f.applies_to(source) and f.rate > 0
        ]
        self.corrupted = 0
        self.dropped = 0
        self.log: list[tuple[float, str, int]] = []  # (t s, kind, bytes) for tests and truth

    def apply(self, t_s: float, data: bytes) -> bytes:
        if not self.windows:
            return data
        for kind, rate, a, b in self.windows:
            if not a <= t_s < b or not data:
                continue
            n = int(self.rng.binomial(len(data), rate))
            if n == 0:
                continue
            pos = self.rng.choice(len(data), size=min(n, len(data)), replace=False)
            arr = np.frombuffer(data, dtype=np.uint8).copy()
            if kind == "corrupt":
                arr[pos] ^= self.rng.integers(1, 256, size=len(pos), dtype=np.uint8)
                self.corrupted += len(pos)
            else:
                arr = np.delete(arr, pos)
                self.dropped += len(pos)
            self.log.append((t_s, kind, len(pos)))
            data = arr.tobytes()
        return data


def schedule(faults: list[Fault], duration: float) -> list[tuple[float, str, Fault]]:
    """Time-ordered (t s, action, fault) list for the simulation's step loop."""
    acts: list[tuple[float, str, Fault]] = []
    for f in faults:
        a, b = f.start(duration), f.end(duration)
        if f.kind == "pull":
            acts += [(a, "unplug", f), (b, "plug", f)]
        elif f.kind == "reset":
            acts.append((a, "reset", f))
        elif f.kind == "gps_loss":
            acts += [(a, "gps_off", f), (b, "gps_on", f)]
        elif f.kind == "clock_jump":
            acts.append((a, "clock_jump", f))
        elif f.kind == "nmea_garbage":
            acts += [(a, "garble_on", f)] + ([(b, "garble_off", f)] if math.isfinite(b) else [])
    acts.sort(key=lambda x: x[0])
    return acts
