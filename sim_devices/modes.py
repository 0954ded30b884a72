"""The autopilot's flight modes as ArduPilot Rover numbers them, and what the boat does in each.

    [[operator]]            # in a scenario TOML: the operator switches modes at these times
    at_s = 300.0            # s since the start of the run
    mode = "MANUAL"         # MANUAL | HOLD | AUTO | RTL

- AUTO (10): the mission, from the current item;
- MANUAL (0): the scripted operator holds the heading the boat had at the switch, at cruise speed;
- HOLD (4): motor off, steering centred (the boat drifts);
- RTL (11): straight for home (the mission's first waypoint), then HOLD there.

A return to AUTO resumes the mission at its current item, as Rover does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

MODES = {"MANUAL": 0, "HOLD": 4, "AUTO": 10, "RTL": 11}
MODE_NAMES = {v: k for k, v in MODES.items()}
AUTO = MODES["AUTO"]


@dataclass(frozen=True)
class ModeChange:
    at_s: float
    mode: int


def schedule(tables: dict[str, Any]) -> list[ModeChange]:
    """The scenario's ``[[operator]]`` mode changes, in time order."""
    out = []
    for row in tables.get("operator", []):
        name = str(row.get("mode", "")).upper()
        if name not in MODES:
            raise ValueError(f"[[operator]] mode must be one of {', '.join(MODES)}, not {name!r}")
        out.append(ModeChange(float(row["at_s"]), MODES[name]))
    return sorted(out, key=lambda c: c.at_s)


class ModePilot:
    """The desired heading in the modes other than AUTO (None: motor off and steering centred)."""

    def __init__(self, home: tuple[float, float], radius_m: float) -> None:
        self.home = home
        self.radius = radius_m
        self.held_psi = 0.0
        self.arrived = False

    def entered(self, mode: int, psi: float) -> None:
        self.held_psi = psi
        self.arrived = False

    def heading(self, mode: int, x: float, y: float) -> float | None:
        if mode == MODES["MANUAL"]:
            return self.held_psi
        if mode == MODES["RTL"] and not self.arrived:
            dx, dy = self.home[0] - x, self.home[1] - y
            if math.hypot(dx, dy) < self.radius:
                self.arrived = True
                return None
            return math.atan2(dx, dy) % (2 * math.pi)
        return None
