"""Scenarios: the TOML files that describe a place (river, lake), loaded by name or path.

The `[scenario]` table is what missions are laid out in (origin, survey box, flow direction); the other
tables are the world the simulator builds there (`sim_devices.fields`), kept raw in `Scenario.tables`."""

from __future__ import annotations

import datetime as dt
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

SCENARIO_DIR = "scenarios"


@dataclass
class Scenario:
    """A loaded scenario: the raw TOML tables plus the few fields every part needs."""

    name: str
    description: str
    lat0: float
    lon0: float
    t0: float  # UNIX seconds of the start
    extent: tuple[float, float, float, float]
    survey_box: tuple[float, float, float, float]
    flow_dir_deg: float
    default_effects: list[str]
    magnetic_variation_deg: float
    tables: dict[str, Any] = field(default_factory=dict)
    path: str = ""

    @property
    def kind(self) -> str:
        return "river" if "channel" in self.tables else "lake"

    def table(self, name: str) -> dict[str, Any]:
        return dict(self.tables.get(name, {}))


def builtin_names() -> list[str]:
    """Names of the scenarios shipped with the package."""
    root = resources.files("forcemap.host.vessel") / SCENARIO_DIR
    return sorted(p.name[:-5] for p in root.iterdir() if p.name.endswith(".toml"))


def _read(name_or_path: str) -> tuple[dict[str, Any], str]:
    p = Path(name_or_path)
    if p.suffix == ".toml" or p.exists():
        return tomllib.loads(p.read_text()), str(p)
    res = resources.files("forcemap.host.vessel") / SCENARIO_DIR / f"{name_or_path}.toml"
    if not res.is_file():
        raise ValueError(
            f"unknown scenario {name_or_path!r}; built in: {', '.join(builtin_names())}"
        )
    return tomllib.loads(res.read_text()), str(res)


def parse_utc(text: str) -> float:
    """UNIX seconds of an ISO-8601 UTC time such as 2026-06-01T14:00:00Z."""
    t = dt.datetime.fromisoformat(text.replace("Z", "+00:00"))
    if t.tzinfo is None:
        t = t.replace(tzinfo=dt.UTC)
    return t.timestamp()


def load(name_or_path: str | Scenario) -> Scenario:
    """Load a built-in scenario by name (``river``, ``lake``) or any scenario TOML by path."""
    if isinstance(name_or_path, Scenario):
        return name_or_path
    data, path = _read(name_or_path)
    s = data.get("scenario", {})
    return Scenario(
        name=str(s.get("name", Path(path).stem)),
        description=str(s.get("description", "")),
        lat0=float(s["lat0"]),
        lon0=float(s["lon0"]),
        t0=parse_utc(str(s.get("start_utc", "2026-06-01T14:00:00Z"))),
        extent=tuple(float(v) for v in s["extent"]),  # type: ignore[arg-type]
        survey_box=tuple(float(v) for v in s.get("survey_box", s["extent"])),  # type: ignore[arg-type]
        flow_dir_deg=float(s.get("flow_dir_deg", 90.0)),
        default_effects=list(s.get("default_effects", [])),
        magnetic_variation_deg=float(s.get("magnetic_variation_deg", 0.0)),
        tables=data,
        path=path,
    )


def describe_all() -> list[tuple[str, str]]:
    """(name, one-line description) for every built-in scenario."""
    return [(n, load(n).description) for n in builtin_names()]
