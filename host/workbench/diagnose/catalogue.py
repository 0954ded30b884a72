"""The effect catalogue: for a covariate that explains what the model misses, its likely physical cause and a term."""

from __future__ import annotations

import re

# (pattern on the covariate name, likely cause, suggested term); the first match wins
CATALOGUE: list[tuple[str, str, str]] = [
    (
        "^depth$",
        "continuity and bed friction: the flow speeds up over shallows and slows in pools "
        "(Manning: speed ~ depth^(2/3))",
        "gp(depth, matern32), or power(depth) for a Manning-type law",
    ),
    (
        "^t$",
        "something changes in time: unsteady discharge (a dam release, rain, tide) for current, "
        "gusts or a passing front for wind",
        "gp(t, matern32)",
    ),
    (
        "^clock_offset$",
        "a clock offset or latency between the autopilot and the bridge: the boat-frame reading is "
        "turned by the heading of another moment, so the vector swings in every turn (a buffering "
        "telemetry link, a serial port read late, a source stamped on arrival instead of at measurement)",
        "clock_offset (re-references the vector with the autopilot's data at the fitted offset); "
        "better still, fix the time stamps at the source",
    ),
    (
        "^heading_rel_",
        "a sensor that reads differently depending on how the bow meets the flow: a misaligned or "
        "shadowed paddle wheel, mast/hull shadow on the anemometer, or compass deviation (in a steady "
        "flow the heading relative to it is the heading less a constant)",
        "gp(HEADING_REL, periodic)",
    ),
    (
        "^heading$",
        "a misaligned or shadowed sensor, or compass deviation (heading error A*sin(heading+phi)) "
        "that rotates every compensated vector",
        "gp(heading, periodic), or cos(heading) for pure deviation",
    ),
    (
        "^(sog|throttle|stw)$",
        "a calibration or compensation error that grows with boat speed: anemometer in the bow "
        "wave's upwash, paddle-wheel gain, or a wrong boat-velocity subtraction",
        "gp(COV, matern32), or linear(COV)",
    ),
    (
        "^app_wind_angle$",
        "a sensor that reads differently depending on how the bow meets the wind: mast or hull "
        "shadow on the anemometer, a misaligned vane; on straight survey legs the apparent wind "
        "angle follows the heading, so also a misaligned paddle wheel or compass deviation",
        "gp(app_wind_angle, periodic), or gp(heading, periodic)",
    ),
    (
        "^yaw_rate$",
        "an error that appears in turns: a sensor lever arm (the mast sweeps through the air), or a "
        "clock offset between two sources (diagnose tries that directly as clock_offset)",
        "gp(yaw_rate, matern32), or clock_offset",
    ),
    (
        "^(cog|crab)$",
        "course or leeway dependence: a sensor that sees the flow differently when the boat crabs, "
        "or an error in the course used for compensation",
        "gp(COV, periodic)",
    ),
    (
        "^wind_dir$",
        "shelter or funnelling by the banks: wind speed depends on where the wind comes from "
        "(lee of a bank, tree line, fetch)",
        "gp(wind_dir, periodic)",
    ),
    (
        "^current_dir$",
        "the flow's speed depends on its direction: eddies, a side channel or a confluence",
        "gp(current_dir, periodic)",
    ),
    (
        "^(wind_|app_wind_)",
        "wind-driven surface drift (about 3 % of wind speed) or wind set-up on the water",
        "gp(COV, matern32)",
    ),
    (
        "^(current_|wheel)",
        "the current moves the boat and the air it measures: a compensation error coupling "
        "current into the wind estimate",
        "gp(COV, matern32)",
    ),
    (
        "^water_temp$",
        "stratification or a tributary of different temperature, or a sensor's temperature drift",
        "gp(water_temp, matern32)",
    ),
]


def explain(covariate: str) -> tuple[str, str]:
    """(likely cause, suggested term) for a covariate."""
    for pattern, cause, term in CATALOGUE:
        if re.search(pattern, covariate):
            return cause, term.replace("COV", covariate).replace("HEADING_REL", covariate)
    return (
        f"an effect tied to '{covariate}' that the map model does not carry (check the sensor and its processing)",
        f"gp({covariate}, matern32)",
    )
