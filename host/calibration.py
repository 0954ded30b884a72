"""Boat calibration and config from ``boat.toml``: sensible defaults, one clear error per bad key."""

from __future__ import annotations

import math
import tomllib
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from forcemap.host.vane import DEFAULT_TABLE

SYNC_MODES = ("interpolate", "approximate")
CURRENT_ESTIMATORS = ("lsq", "paper")
# 20 000 pulses per nautical mile (Airmar paddle-wheel format) = 10.8 pulses per metre
DEFAULT_WHEEL_PPM = 10.8
DEFAULT_WHEEL_ANGLES = (45.0, 135.0, -135.0, -45.0)


class ConfigError(ValueError):
    """An invalid ``boat.toml``: the message names the key."""


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
    extra: dict[str, Any] = field(default_factory=dict, compare=False)

    @property
    def wheel_angles_rad(self) -> list[float]:
        return [math.radians(w.angle_deg) for w in self.wheels]

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


def from_dict(doc: dict) -> Calibration:
    """Validate a parsed ``boat.toml`` document and build the Calibration."""
    if not isinstance(doc, dict):
        raise ConfigError("boat.toml: expected a table at the top level")
    top = {"boat", "anemometer", "vane", "wheels", "current", "depth", "compass", "sync"}
    _known(doc, "", top)
    kw: dict[str, Any] = {}

    a = _table(doc, "anemometer")
    _known(a, "anemometer.", {"mps_per_hz", "min_speed_mps"})
    if "mps_per_hz" in a:
        kw["anemo_mps_per_hz"] = _num(a["mps_per_hz"], "anemometer.mps_per_hz", positive=True)
    if "min_speed_mps" in a:
        kw["anemo_min_speed"] = _num(a["min_speed_mps"], "anemometer.min_speed_mps", lo=0)

    v = _table(doc, "vane")
    _known(v, "vane.", {"vref", "pullup_ohm", "adc_ref", "offset_deg", "resistors_ohm"})
    if "vref" in v:
        kw["vane_vref"] = _num(v["vref"], "vane.vref", positive=True)
    if "adc_ref" in v:
        kw["vane_adc_ref"] = _num(v["adc_ref"], "vane.adc_ref", positive=True)
    if "pullup_ohm" in v:
        kw["vane_pullup_ohm"] = _num(v["pullup_ohm"], "vane.pullup_ohm", positive=True)
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

    if "wheels" in doc:
        ws = doc["wheels"]
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
                w.get("pulses_per_m", DEFAULT_WHEEL_PPM), f"wheels[{i}].pulses_per_m", positive=True
            )
            ang = _num(
                w.get("angle_deg", DEFAULT_WHEEL_ANGLES[i]),
                f"wheels[{i}].angle_deg",
                lo=-180,
                hi=180,
            )
            wheels.append(Wheel(ppm, ang))
        kw["wheels"] = tuple(wheels)

    c = _table(doc, "current")
    _known(c, "current.", {"min_speed_mps", "estimator", "noise_mps", "rate_window_s"})
    if "rate_window_s" in c:
        kw["rate_window_s"] = _num(c["rate_window_s"], "current.rate_window_s", lo=0.1, hi=10)
    if "min_speed_mps" in c:
        kw["wheel_min_speed"] = _num(c["min_speed_mps"], "current.min_speed_mps", lo=0)
    if "noise_mps" in c:
        kw["wheel_noise"] = _num(c["noise_mps"], "current.noise_mps", positive=True)
    if "estimator" in c:
        e = c["estimator"]
        if e not in CURRENT_ESTIMATORS:
            raise ConfigError(
                f"current.estimator: expected one of {CURRENT_ESTIMATORS}, got {_show(e)}"
            )
        kw["current_estimator"] = e

    d = _table(doc, "depth")
    _known(d, "depth.", {"offset_m"})
    if "offset_m" in d:
        kw["depth_offset_m"] = _num(d["offset_m"], "depth.offset_m", lo=-10, hi=10)

    m = _table(doc, "compass")
    _known(m, "compass.", {"variation_deg"})
    if "variation_deg" in m:
        var = m["variation_deg"]
        if var != "auto":
            kw["magnetic_variation_deg"] = _num(var, "compass.variation_deg", lo=-180, hi=180)

    s = _table(doc, "sync")
    _known(s, "sync.", {"mode", "max_gap_s"})
    if "mode" in s:
        if s["mode"] not in SYNC_MODES:
            raise ConfigError(f"sync.mode: expected one of {SYNC_MODES}, got {_show(s['mode'])}")
        kw["sync"] = s["mode"]
    if "max_gap_s" in s:
        kw["max_state_gap_s"] = _num(s["max_gap_s"], "sync.max_gap_s", positive=True)

    b = _table(doc, "boat")
    kw["extra"] = {"boat": dict(b)}
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
    return Path(__file__).with_name("data") / "boat.example.toml"
