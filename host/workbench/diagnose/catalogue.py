"""The effect catalogue: for a covariate that explains what the model misses, its likely physical cause and a term.

Depth is its own case: a sounding that depends on the heading, the wind's angle on the bow or the hull's
attitude is a tilted sounder (heel), never a misaligned sensor (docs/SOUNDINGS.md).

Causes name instruments: only those the survey has (host/workbench/survey/instruments.py), by the name its log
gives them ("the speed log (VW VHW)"); a clause about an instrument the survey does not show is left out.
"""

from __future__ import annotations

import re
from collections.abc import Callable

from forcemap.host.workbench.survey.instruments import Instruments

Cause = Callable[[Instruments, str], str]


def _either(*clauses: str | None) -> str:
    """'a, b, or c' of the clauses that apply."""
    parts = [c for c in clauses if c]
    return parts[0] if len(parts) == 1 else ", ".join(parts[:-1]) + ", or " + parts[-1]


def _clock(i: Instruments, family: str) -> str:
    late = i.late_source()
    measured = f" (the measured latencies name {late})" if late else ""
    return (
        f"a clock offset or latency between {i.boat_frame(family)} and {i.navigation()}{measured}: the "
        "boat-frame reading is turned by the heading of another moment, so the vector swings in every "
        "turn (a buffering link, a serial port read late, a source stamped on arrival instead of at "
        "measurement, an instrument bus that re-sends late)"
    )


def _heading_rel(i: Instruments, family: str) -> str:
    flow = i.flow_sensor()
    return "a sensor that reads differently depending on how the bow meets the flow: " + _either(
        f"a misaligned or shadowed {_bare(flow)}" if flow else None,
        "mast/hull shadow on the anemometer" if i.anemometer else None,
        "compass deviation (in a steady flow the heading relative to it is the heading less a constant)",
    )


def _heading(i: Instruments, family: str) -> str:
    return (
        "a misaligned or shadowed sensor, or deviation of "
        f"{i.name('heading', 'the compass')} (heading error A*sin(heading+phi)) that rotates every "
        "compensated vector"
    )


def _speed(i: Instruments, family: str) -> str:
    flow = i.flow_sensor()
    return "a calibration or compensation error that grows with boat speed: " + _either(
        "the anemometer in the bow wave's upwash" if i.anemometer else None,
        f"the gain of {flow}" if flow else None,
        "a wrong boat-velocity subtraction",
    )


def _app_angle(i: Instruments, family: str) -> str:
    flow = i.flow_sensor()
    return (
        "a sensor that reads differently depending on how the bow meets the wind: mast or hull shadow "
        "on the anemometer, a misaligned vane; on straight survey legs the apparent wind angle follows "
        "the heading, so also "
        + _either(f"a misaligned {_bare(flow)}" if flow else None, "compass deviation")
    )


def _time(i: Instruments, family: str) -> str:
    if family == "depth":
        return (
            "the water level changes during the survey (tide, river stage): give a gauge with "
            "--water-level, or let forcemap estimate the level from the crossings (the term water_level)"
        )
    return (
        "something changes in time: unsteady discharge (a dam release, rain, tide) for current, "
        "gusts or a passing front for wind"
    )


def _heel(i: Instruments, family: str) -> str:
    """Depth that follows the heading, the wind's angle or the hull's attitude: the sounder tilts."""
    physics = (
        "the sounder tilts with the hull: a single-beam sounder's first return is the nearest point "
        "of the bed inside its cone, so once the hull heels (or trims) beyond half the beam angle it "
        "reads long by 1/cos(tilt - half the beam), on the legs that take the wind on the beam and not "
        "on those up or down wind: depth follows the heading relative to the wind (docs/SOUNDINGS.md)"
    )
    if "roll" in i.columns:
        return (
            physics + "; the log has the hull's roll and pitch: give the beam angle in boat.toml "
            "([sounder] beam_angle_deg), or import the raw log again to estimate it from the "
            "crossings, and each sounding is corrected"
        )
    return (
        "heel: " + physics + "; the log has no attitude: log the hull's roll and pitch (a heel or "
        "attitude sensor's NMEA XDR, ROLL/PTCH or HEEL/TRIM) and give [sounder] beam_angle_deg. A "
        "misaligned sensor does not make a depth depend on the heading"
    )


# covariates through which a tilted sounder shows in depth (the legs' heading, the wind's angle
# and strength on them, the hull's attitude itself)
TILT = r"^(heading|heading_rel_\w+|app_wind_\w+|wind_\w+|roll|pitch|cog|crab)$"
TILT_TERM = "log roll and pitch and give [sounder] beam_angle_deg; meanwhile gp(COV, periodic)"


def _bare(name: str | None) -> str:
    """'the speed log (VHW)' -> 'speed log (VHW)', for 'a misaligned ...'."""
    return (name or "").removeprefix("the ")


# (pattern on the covariate name, likely cause, suggested term); the first match wins
CATALOGUE: list[tuple[str, str | Cause, str]] = [
    (
        "^depth$",
        "continuity and bed friction: the flow speeds up over shallows and slows in pools "
        "(Manning: speed ~ depth^(2/3))",
        "gp(depth, matern32), or power(depth) for a Manning-type law",
    ),
    ("^t$", _time, "gp(t, matern32)"),
    (
        "^clock_offset$",
        _clock,
        "clock_offset (re-references the vector at the fitted offset); better still, fix the time "
        "stamps at the source",
    ),
    ("^heading_rel_", _heading_rel, "gp(HEADING_REL, periodic)"),
    ("^heading$", _heading, "gp(heading, periodic), or cos(heading) for pure deviation"),
    ("^(sog|throttle|stw)$", _speed, "gp(COV, matern32), or linear(COV)"),
    ("^app_wind_angle$", _app_angle, "gp(app_wind_angle, periodic), or gp(heading, periodic)"),
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


def is_linear(covariate: str) -> bool:
    """A covariate that is not an angle (a wind speed, roll and pitch are signed magnitudes)."""
    return covariate in ("roll", "pitch") or covariate.endswith(("_speed", "_east", "_north"))


def explain(
    covariate: str, instruments: Instruments | None = None, family: str = "current"
) -> tuple[str, str]:
    """(likely cause, suggested term) for a covariate, naming only the survey's own instruments."""
    inst = instruments or Instruments(set())
    if family == "depth" and re.search(TILT, covariate):
        term = TILT_TERM if not is_linear(covariate) else TILT_TERM.replace("periodic", "matern32")
        return _heel(inst, family), term.replace("COV", covariate)
    for pattern, cause, term in CATALOGUE:
        if re.search(pattern, covariate):
            text = cause(inst, family) if callable(cause) else cause
            if covariate == "t" and family == "depth":
                term = "water_level, or --water-level GAUGE.csv"
            return text, term.replace("COV", covariate).replace("HEADING_REL", covariate)
    return (
        f"an effect tied to '{covariate}' that the map model does not carry (check the sensor and its processing)",
        f"gp({covariate}, matern32)",
    )


KIND_NAMES = {
    "drift": "a steady drift",
    "tide": "a tide",
    "periodic": "another period",
    "reference": "the reference station's tide",
}


def _hours(seconds: float) -> str:
    return f"{seconds / 3600:.2f} h" if seconds >= 3 * 3600 else f"{seconds / 60:.0f} min"


def _spread(sd_s: float, period_s: float | None) -> str:
    """A period's sd in the unit `_hours` gives the period, one more digit."""
    if period_s is not None and period_s >= 3 * 3600:
        return f"{sd_s / 3600:.3f} h"
    return f"{sd_s / 60:.1f} min"


def time_form_cause(verdict, family: str, short_for_tide: bool) -> str:
    """The likely cause of a change in time the revisits found, named by its form (a tide near 12.42 or
    23.93 h, another period a seiche, a steady change a stage or a drift), with what they cannot tell apart."""
    form = verdict.best
    sd = f" ± {_spread(verdict.period_sd_s, form.period_s)}" if verdict.period_sd_s else ""
    if family == "wind":
        return "the wind changes in time: gusts, a veer or a front passing"
    level = family == "depth"
    what = "the water level changes during the survey" if level else f"the {family} changes in time"
    if form.name == "reference":
        cause = f"{what}: a tide, as the reference station predicts it ({reference_words(verdict)})"
    elif form.name == "tide" and not short_for_tide:
        cause = f"{what}: a tide (the revisits' differences follow a period of {_hours(form.period_s)}{sd})"
    elif form.name in ("tide", "periodic"):
        cause = (
            f"{what}: an oscillation with a period of {_hours(form.period_s)}{sd}, such as a seiche of "
            "the lake or basin (Merian: T = 2 L / (n sqrt(g h)) for a basin of length L and depth h)"
        )
        if verdict.fitted_period_s:
            cause += (
                f"; fitted with the map on every row, {verdict.fitted_period_s / 60:.1f} ± "
                f"{verdict.fitted_period_sd_s / 60:.1f} min, which agrees"
            )
    elif verdict.departure > 0:
        cause = (
            f"{what}: a rise and a fall within the survey that the record does not repeat (a tide "
            "turning, a discharge or a wind set-up that builds and relaxes)"
        )
    else:
        cause = (
            f"{what}: a steady rise or fall (a river's stage, a discharge changing, a slow drift)"
        )
    if short_for_tide and form.name not in ("tide", "reference"):
        cause += (
            f"; a record of {_hours(verdict.span_s)} cannot tell a tide (12.42 h) from it: in tidal water "
            "the term tide predicts beyond the survey"
        )
    others = [k for k in verdict.indistinct if not (short_for_tide and k == "tide")]
    if form.name == "reference":
        better = fits_better(verdict, others)
        others = [k for k in others if k not in better]
        if better:
            cause += (
                f"; {' and '.join(kind_named(verdict, k) for k in better)} "
                f"{'fits' if len(better) == 1 else 'fit'} the revisits better: "
                "what the station does not predict here is left for the next round"
            )
    if others:
        cause += f"; the revisits cannot tell it from {' or '.join(kind_named(verdict, k) for k in others)}"
    if level:
        cause += "; or give a gauge's record with --water-level"
    return cause


def reference_words(verdict) -> str:
    """A reference form's station, and the place's ratio to it and offset, as its coefficients give them
    (linearised: the term tide(reference) fits both, and maps them)."""
    offset = verdict.offset_s / 60.0
    when = f"{abs(offset):.0f} min {'later' if offset >= 0 else 'earlier'}"
    return f"station {verdict.station}: what the map leaves follows {verdict.ratio:.2f} x its current, {when}"


def fits_better(verdict, kinds: list[str]) -> list[str]:
    """The kinds among `kinds` whose best member the revisits prefer to the best form by more than
    `judge.TELL_APART` in log-likelihood."""
    from forcemap.host.workbench.timejudge.judge import TELL_APART, log_lik

    n_eff = max(verdict.crossings, 2)
    top = log_lik(verdict.best.share, n_eff)
    out = []
    for kind in kinds:
        members = [f.share for f in verdict.forms if f.name == kind]
        if members and log_lik(max(members), n_eff) - top >= TELL_APART:
            out.append(kind)
    return out


def kind_named(verdict, kind: str) -> str:
    """A kind of form in words, with the period of its best member (a tide's, another period's)."""
    periodic = [f for f in verdict.forms if f.name == kind and f.period_s is not None]
    if kind == "drift" or not periodic:
        return KIND_NAMES[kind]
    return f"{KIND_NAMES[kind]} ({_hours(max(periodic, key=lambda f: f.share).period_s)})"
