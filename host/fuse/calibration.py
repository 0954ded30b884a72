"""Boat calibration and config from ``boat.toml``: sensible defaults, one clear error per bad key."""

from __future__ import annotations

import math
import tomllib
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from forcemap.host.decode.vane import DEFAULT_TABLE
from forcemap.host.errors import CliError

SYNC_MODES = ("interpolate", "approximate")
ROT_UNITS = ("deg/min", "deg/s")
STW_GAIN = (0.5, 2.0)  # a speed log off by more than a factor 2 is broken, not miscalibrated
CURRENT_ESTIMATORS = ("lsq", "paper")
# 20 000 pulses per nautical mile (Airmar paddle-wheel format) = 10.8 pulses per metre
DEFAULT_WHEEL_PPM = 10.8
DEFAULT_WHEEL_ANGLES = (45.0, 135.0, -135.0, -45.0)


class ConfigError(CliError, ValueError):
    """An invalid ``boat.toml``: the message names the key (the CLI prints it on one line, exit 2)."""


# Physical ranges: a value outside is a wrong unit or a typo, refused with the range in the message.
ANEMO_MPS_PER_HZ = (0.1, 2.0)  # cup anemometers; 2.4 is the km/h figure, 0.0 a missing value
ADC_VOLTS = (1.0, 5.5)  # 3.3 V or 5 V logic; 3300 is millivolts
PULLUP_OHM = (100.0, 1_000_000.0)
WHEEL_PULSES_PER_M = (0.5, 500.0)


@dataclass(frozen=True)
class Wheel:
    """One paddle wheel: pulses per metre of water along its axis, axis angle clockwise from the bow."""

    pulses_per_m: float = DEFAULT_WHEEL_PPM
    angle_deg: float = 45.0


@dataclass(frozen=True)
class Calibration:
    """Everything the compensation needs to know about this boat's instruments (SI, degrees)."""

    anemo_mps_per_hz: float = 0.6667
    anemo_min_speed: float = 0.0
    vane_table: tuple[tuple[float, float], ...] = DEFAULT_TABLE
    vane_vref: float = 3.3
    vane_pullup_ohm: float = 10_000.0
    vane_adc_ref: float = 3.3
    vane_offset_deg: float = 0.0
    wheels: tuple[Wheel, ...] = tuple(Wheel(DEFAULT_WHEEL_PPM, a) for a in DEFAULT_WHEEL_ANGLES)
    wheel_min_speed: float = 0.05
    wheel_noise: float = 0.03
    rate_window_s: float = 1.0
    current_estimator: str = "lsq"
    depth_offset_m: float = 0.0
    magnetic_variation_deg: float | None = None
    sync: str = "interpolate"
    max_state_gap_s: float = 2.0
    # [sync] navigation: "smoothed" (every source, docs/NAVIGATION.md) or "logged" (the chosen
    # source's, as the pipeline made the rows); latency: "remove" each source's measured latency
    # before the compensation, or "keep" it
    navigation: str = "smoothed"
    latency: str = "remove"
    # [sync] live_lag_s: how long `forcemap run` holds a row back for the readings after it (its
    # fixed-lag filter, docs/NAVIGATION.md); 0 is a pure filter
    live_lag_s: float = 3.0
    # [sources]: per quantity, substrings of source names in order of preference; silence timeouts
    source_priorities: dict[str, list[str]] = field(default_factory=dict)
    source_timeouts: dict[str, float] = field(default_factory=dict)
    # the speed log and rate of turn: pinned in boat.toml, or estimated at import (None: not known)
    stw_gain: float | None = None
    stw_misalignment_deg: float | None = None
    rot_unit: str | None = None  # "deg/min" (NMEA 0183) or "deg/s" (a vendor's)
    stw_dead: tuple[tuple[float, float], ...] = ()  # UNIX-second stretches the speed log was dead
    # [sounder]: the beam's full angle (deg) for the tilt correction (None: not known; an import
    # estimates it from the log, docs/SOUNDINGS.md), and its stated accuracy (1 sd: m + share of depth)
    sounder_beam_deg: float | None = None
    sounder_accuracy_m: float | None = None
    sounder_accuracy_share: float | None = None
    depth_lost: tuple[tuple[float, float], ...] = ()  # UNIX-second stretches the bottom was lost
    extra: dict[str, Any] = field(default_factory=dict, compare=False)

    def as_metadata(self) -> dict[str, str]:
        """Flat string map for MCAP metadata."""
        d = asdict(self)
        d.pop("extra")
        out = {k: repr(v) if not isinstance(v, str) else v for k, v in d.items()}
        out["wheels"] = repr([(w.pulses_per_m, w.angle_deg) for w in self.wheels])
        return out


def _num(
    value: Any,
    key: str,
    *,
    lo: float | None = None,
    hi: float | None = None,
    positive: bool = False,
    plausible: tuple[float, float] | None = None,
    unit: str = "",
) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ConfigError(f"{key}: expected a number, got {_show(value)}")
    x = float(value)
    if not math.isfinite(x):
        raise ConfigError(f"{key}: expected a finite number, got {value}")
    if positive and x <= 0:
        raise ConfigError(f"{key}: expected a positive number, got {value}")
    if lo is not None and x < lo:
        raise ConfigError(f"{key}: expected at least {lo}, got {value}")
    if hi is not None and x > hi:
        raise ConfigError(f"{key}: expected at most {hi}, got {value}")
    if plausible is not None and not plausible[0] <= x <= plausible[1]:
        raise ConfigError(
            f"{key}: {value} is outside the plausible range {plausible[0]:g} to {plausible[1]:g}"
            f"{unit}; check the unit"
        )
    return x


def _show(value: Any) -> str:
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, dict):
        return "a table"
    if isinstance(value, list):
        return "a list"
    return repr(value)


def _table(doc: dict, name: str) -> dict:
    t = doc.get(name, {})
    if not isinstance(t, dict):
        raise ConfigError(f"{name}: expected a table, got {_show(t)}")
    return t


def _known(t: dict, prefix: str, keys: set[str]) -> None:
    for k in t:
        if k not in keys:
            raise ConfigError(
                f"{prefix}{k}: unknown key (expected one of {', '.join(sorted(keys))})"
            )


def _anemometer(a: dict) -> dict[str, Any]:
    _known(a, "anemometer.", {"mps_per_hz", "min_speed_mps"})
    kw: dict[str, Any] = {}
    if "mps_per_hz" in a:
        kw["anemo_mps_per_hz"] = _num(
            a["mps_per_hz"], "anemometer.mps_per_hz", plausible=ANEMO_MPS_PER_HZ, unit=" m/s per Hz"
        )
    if "min_speed_mps" in a:
        kw["anemo_min_speed"] = _num(a["min_speed_mps"], "anemometer.min_speed_mps", lo=0)
    return kw


def _vane(v: dict) -> dict[str, Any]:
    _known(v, "vane.", {"vref", "pullup_ohm", "adc_ref", "offset_deg", "resistors_ohm"})
    kw: dict[str, Any] = {}
    if "vref" in v:
        kw["vane_vref"] = _num(v["vref"], "vane.vref", plausible=ADC_VOLTS, unit=" V")
    if "adc_ref" in v:
        kw["vane_adc_ref"] = _num(v["adc_ref"], "vane.adc_ref", plausible=ADC_VOLTS, unit=" V")
    if "pullup_ohm" in v:
        kw["vane_pullup_ohm"] = _num(
            v["pullup_ohm"], "vane.pullup_ohm", plausible=PULLUP_OHM, unit=" ohm"
        )
    if "offset_deg" in v:
        kw["vane_offset_deg"] = _num(v["offset_deg"], "vane.offset_deg", lo=-360, hi=360)
    if "resistors_ohm" in v:
        rs = v["resistors_ohm"]
        if not isinstance(rs, list) or len(rs) != 16:
            raise ConfigError(
                f"vane.resistors_ohm: expected a list of 16 resistances (0 to 337.5 deg), got {_show(rs)}"
                + (f" of {len(rs)}" if isinstance(rs, list) else "")
            )
        kw["vane_table"] = tuple(
            (22.5 * i, _num(r, f"vane.resistors_ohm[{i}]", positive=True)) for i, r in enumerate(rs)
        )
    return kw


def _wheels(ws: Any) -> dict[str, Any]:
    if not isinstance(ws, list) or not ws:
        raise ConfigError(f"wheels: expected an array of tables ([[wheels]]), got {_show(ws)}")
    if len(ws) != 4:
        raise ConfigError(f"wheels: expected 4 paddle wheels, got {len(ws)}")
    wheels = []
    for i, w in enumerate(ws):
        if not isinstance(w, dict):
            raise ConfigError(f"wheels[{i}]: expected a table, got {_show(w)}")
        _known(w, f"wheels[{i}].", {"pulses_per_m", "angle_deg"})
        ppm = _num(
            w.get("pulses_per_m", DEFAULT_WHEEL_PPM),
            f"wheels[{i}].pulses_per_m",
            plausible=WHEEL_PULSES_PER_M,
            unit=" pulses per metre",
        )
        key = f"wheels[{i}].angle_deg"
        ang = _num(w.get("angle_deg", DEFAULT_WHEEL_ANGLES[i]), key, lo=-180, hi=180)
        wheels.append(Wheel(ppm, ang))
    angles = [abs(w.angle_deg) for w in wheels]
    # four axes within 2 pi of the bow cannot resolve a current: these are radians
    if max(angles) <= 2 * math.pi and max(angles) > 0:
        raise ConfigError(
            "wheels.angle_deg: the angles "
            + ", ".join(f"{w.angle_deg:g}" for w in wheels)
            + " look like radians; give degrees clockwise from the bow (e.g. 45, 135, -135, -45)"
        )
    return {"wheels": tuple(wheels)}


def _current(c: dict) -> dict[str, Any]:
    _known(c, "current.", {"min_speed_mps", "estimator", "noise_mps", "rate_window_s"})
    kw: dict[str, Any] = {}
    if "rate_window_s" in c:
        kw["rate_window_s"] = _num(c["rate_window_s"], "current.rate_window_s", lo=0.1, hi=10)
    if "min_speed_mps" in c:
        kw["wheel_min_speed"] = _num(c["min_speed_mps"], "current.min_speed_mps", lo=0, hi=2)
    if "noise_mps" in c:
        kw["wheel_noise"] = _num(c["noise_mps"], "current.noise_mps", positive=True, hi=2)
    if "estimator" in c:
        e = c["estimator"]
        if e not in CURRENT_ESTIMATORS:
            raise ConfigError(
                f"current.estimator: expected one of {CURRENT_ESTIMATORS}, got {_show(e)}"
            )
        kw["current_estimator"] = e
    return kw


def _depth_compass_sync(d: dict, m: dict, s: dict) -> dict[str, Any]:
    _known(d, "depth.", {"offset_m"})
    _known(m, "compass.", {"variation_deg"})
    _known(s, "sync.", {"mode", "max_gap_s", "navigation", "latency", "live_lag_s"})
    kw: dict[str, Any] = {}
    if "offset_m" in d:
        kw["depth_offset_m"] = _num(d["offset_m"], "depth.offset_m", lo=-10, hi=10)
    if m.get("variation_deg", "auto") != "auto":
        kw["magnetic_variation_deg"] = _num(
            m["variation_deg"], "compass.variation_deg", lo=-180, hi=180
        )
    if "mode" in s:
        if s["mode"] not in SYNC_MODES:
            raise ConfigError(f"sync.mode: expected one of {SYNC_MODES}, got {_show(s['mode'])}")
        kw["sync"] = s["mode"]
    for key, choices in (("navigation", ("smoothed", "logged")), ("latency", ("remove", "keep"))):
        if key in s:
            if s[key] not in choices:
                raise ConfigError(f"sync.{key}: expected one of {choices}, got {_show(s[key])}")
            kw[key] = s[key]
    if "max_gap_s" in s:
        kw["max_state_gap_s"] = _num(s["max_gap_s"], "sync.max_gap_s", positive=True)
    if "live_lag_s" in s:
        kw["live_lag_s"] = _num(s["live_lag_s"], "sync.live_lag_s", lo=0, hi=30)
    return kw


def _sources(t: dict) -> dict[str, Any]:
    """``[sources]``: ``QUANTITY = ["substring", ...]`` and ``timeout_s`` (a number or a table)."""
    from forcemap.host.fuse.sources import QUANTITIES

    _known(t, "sources.", set(QUANTITIES) | {"timeout_s"})
    prio: dict[str, list[str]] = {}
    for q in QUANTITIES:
        if q not in t:
            continue
        v = t[q]
        if isinstance(v, str):
            v = [v]
        if not isinstance(v, list) or not all(isinstance(x, str) and x.strip() for x in v):
            raise ConfigError(
                f'sources.{q}: expected a list of source names, e.g. ["GPRMC", "IIRMC"], '
                f"got {_show(v)}"
            )
        prio[q] = [x.strip() for x in v]
    timeouts: dict[str, float] = {}
    to = t.get("timeout_s", {})
    if isinstance(to, dict):
        _known(to, "sources.timeout_s.", set(QUANTITIES))
        for q, v in to.items():
            timeouts[q] = _num(v, f"sources.timeout_s.{q}", positive=True, hi=3600)
    else:
        x = _num(to, "sources.timeout_s", positive=True, hi=3600)
        timeouts = dict.fromkeys(QUANTITIES, x)
    return {"source_priorities": prio, "source_timeouts": timeouts}


def _sounder(s: dict) -> dict[str, Any]:
    """``[sounder] beam_angle_deg, accuracy_m, accuracy_share``: pinned, the beam never estimated then."""
    _known(s, "sounder.", {"beam_angle_deg", "accuracy_m", "accuracy_share"})
    kw: dict[str, Any] = {}
    if "beam_angle_deg" in s:
        kw["sounder_beam_deg"] = _num(s["beam_angle_deg"], "sounder.beam_angle_deg", lo=0, hi=90)
    if "accuracy_m" in s:
        kw["sounder_accuracy_m"] = _num(s["accuracy_m"], "sounder.accuracy_m", lo=0, hi=5)
    if "accuracy_share" in s:
        kw["sounder_accuracy_share"] = _num(
            s["accuracy_share"], "sounder.accuracy_share", lo=0, hi=0.2
        )
    return kw


def _speed_log_rot(s: dict, r: dict) -> dict[str, Any]:
    """``[speed_log] gain, misalignment_deg`` and ``[rate_of_turn] unit``: pinned, never estimated."""
    _known(s, "speed_log.", {"gain", "misalignment_deg"})
    _known(r, "rate_of_turn.", {"unit"})
    kw: dict[str, Any] = {}
    if "gain" in s:
        kw["stw_gain"] = _num(s["gain"], "speed_log.gain", plausible=STW_GAIN)
    if "misalignment_deg" in s:
        kw["stw_misalignment_deg"] = _num(
            s["misalignment_deg"], "speed_log.misalignment_deg", lo=-45, hi=45
        )
    if "unit" in r:
        if r["unit"] not in ROT_UNITS:
            raise ConfigError(
                f"rate_of_turn.unit: expected one of {ROT_UNITS}, got {_show(r['unit'])}"
            )
        kw["rot_unit"] = r["unit"]
    return kw


def from_dict(doc: dict) -> Calibration:
    """Validate a parsed ``boat.toml`` document and build the Calibration."""
    if not isinstance(doc, dict):
        raise ConfigError("boat.toml: expected a table at the top level")
    top = {"boat", "anemometer", "vane", "wheels", "current", "depth", "compass", "sync", "sources"}
    top |= {"speed_log", "rate_of_turn", "sounder"}
    _known(doc, "", top)
    kw: dict[str, Any] = {}
    kw.update(_anemometer(_table(doc, "anemometer")))
    kw.update(_vane(_table(doc, "vane")))
    if "wheels" in doc:
        kw.update(_wheels(doc["wheels"]))
    kw.update(_current(_table(doc, "current")))
    kw.update(
        _depth_compass_sync(_table(doc, "depth"), _table(doc, "compass"), _table(doc, "sync"))
    )
    kw.update(_sources(_table(doc, "sources")))
    kw.update(_speed_log_rot(_table(doc, "speed_log"), _table(doc, "rate_of_turn")))
    kw.update(_sounder(_table(doc, "sounder")))
    kw["extra"] = {"boat": dict(_table(doc, "boat"))}
    return Calibration(**kw)


def load(path: str | Path | None) -> Calibration:
    """Read ``boat.toml`` (None: the defaults). Raises ConfigError with the file and key on error."""
    if path is None:
        return Calibration()
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as e:
        raise ConfigError(f"{p}: cannot read: {e.strerror or e}") from None
    except UnicodeDecodeError:
        raise ConfigError(f"{p}: not UTF-8 text") from None
    return loads(text, source=str(p))


def loads(text: str, source: str = "boat.toml") -> Calibration:
    """Parse and validate TOML text."""
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"{source}: invalid TOML: {e}") from None
    try:
        return from_dict(doc)
    except ConfigError as e:
        raise ConfigError(f"{source}: {e}") from None


def example_path() -> Path:
    """The shipped example ``boat.toml``."""
    return Path(__file__).parents[1] / "data" / "boat.example.toml"
