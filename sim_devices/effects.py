"""Named effects: composable world and instrument terms, each with its physical story and parameters."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


@dataclass(frozen=True)
class EffectSpec:
    """One catalogue entry: what the effect is and its default parameters."""

    name: str
    kind: str  # "world" or "instrument"
    story: str
    does: str
    params: dict[str, Any] = field(default_factory=dict)


CATALOGUE: dict[str, EffectSpec] = {
    e.name: e
    for e in (
        EffectSpec(
            "depth_current",
            "world",
            "continuity and bed friction (Manning)",
            "current speed ~ depth^(2/3) everywhere (2.5 m/s over the deepest water): slow over sand bars and "
            "shoals, fast over the thalweg",
            {"exponent": 2.0 / 3.0},
        ),
        EffectSpec(
            "dam_release",
            "world",
            "unsteady discharge from an upstream dam",
            "discharge, and with it the current, ramps up smoothly by `increase` between two times",
            {"increase": 0.6, "start_frac": 0.15, "end_frac": 0.85},
        ),
        EffectSpec(
            "gusts",
            "world",
            "gusty wind",
            "wind speed x gust factor: slow swell over minutes plus fast gusts carried downwind, peaks >= peak_factor (12 m/s on the river)",
            {
                "slow_amplitude": 0.35,
                "slow_period_s": 600.0,
                "fast_std": 0.06,
                "peak_factor": 1.65,
            },
        ),
        EffectSpec(
            "bank_shelter",
            "world",
            "lee of a wooded bank",
            "wind reduced near the wooded bank when it blows from over it; showers make the wind veer and back "
            "between two directions, and it wanders by `wander_deg` (std) over 10-60 s, so the shelter comes and goes",
            {
                "strength": 0.6,
                "length_m": 200.0,
                "veer_from_deg": 110.0,
                "veer_to_deg": 270.0,
                "swing_period_s": 600.0,
                "wander_deg": 30.0,
            },
        ),
        EffectSpec(
            "wheel_misalignment",
            "instrument",
            "a paddle wheel mounted some degrees off its nominal angle",
            "wheel `wheel` (1-4)'s axis is rotated by `angle_deg` from its nominal mounting angle",
            {"wheel": 1, "angle_deg": 20.0},
        ),
        EffectSpec(
            "anemometer_upwash",
            "instrument",
            "anemometer in the bow wave's upwash",
            "measured apparent wind speed x (1 + k * boat speed through the water, m/s)",
            {"k": 0.08},
        ),
        EffectSpec(
            "heel",
            "instrument",
            "a hull that heels with the wind on its beam, and the sounder with it",
            "roll = -max_deg min(1, (apparent wind / wind_ref)^2) sin(apparent wind angle): to leeward, "
            "largest on a beam reach, none downwind; the sounder's first return is the bed's nearest "
            "point inside its cone of beam_deg, so beyond half the beam it reads long "
            "(forcemap.host.fuse.attitude); the autopilot's ATTITUDE reports the roll",
            {"max_deg": 25.0, "wind_ref": 6.0, "beam_deg": 10.0},
        ),
        EffectSpec(
            "compass_deviation",
            "instrument",
            "uncompensated magnetic deviation",
            "reported heading = true + A sin(heading + phase)",
            {"amplitude_deg": 10.0, "phase_deg": 30.0},
        ),
        EffectSpec(
            "clock_offset",
            "instrument",
            "one source's clock is off",
            "the autopilot's data and time stamps run `offset_s` late relative to the bridge",
            {"offset_s": 1.5},
        ),
        EffectSpec(
            "tide",
            "world",
            "a tide under the survey",
            "the water surface moves by amplitude_m sin(2 pi (t - mid) / period_s + phase): every sounding is "
            "deeper by the level; phase_deg 0 is mid-tide, rising, at the survey's middle",
            {"amplitude_m": 0.7, "period_s": 44712.0, "phase_deg": 0.0},
        ),
        EffectSpec(
            "tidal_stream",
            "world",
            "a tidal stream along the river or estuary",
            "the current along the channel (the flow direction in a lake) is river x the scenario's own plus "
            "the astronomical tide at the run's UTC time: amplitude_m_s f cos(V + u - g) for M2 with Greenwich "
            "phase phase_deg (nodal corrections f, u and argument V of host/vessel/tides.py), plus S2 with "
            "s2_m_s and s2_phase_deg; river 0 is a stream that reverses at every slack water, river 1 a "
            "river whose flow the tide modulates",
            {
                "amplitude_m_s": 0.8,
                "phase_deg": 120.0,
                "s2_m_s": 0.0,
                "s2_phase_deg": 150.0,
                "river": 0.0,
            },
        ),
        EffectSpec(
            "reference_stream",
            "world",
            "a tidal stream that is a reference station's, times a ratio and later by an offset",
            "the current along the channel (the flow direction in a lake) is river x the scenario's own plus "
            "ratio(x) r(t - offset(x)): r the NOAA station's prediction (host/data/noaa_sfbay_currents.json), "
            "ratio = ratio + ratio_east xi and offset = offset_min + offset_east_min xi minutes, xi the "
            "place's east position over half the survey's width (sim_devices/reference_stream.py)",
            {
                "station": "SFB1204",
                "ratio": 0.8,
                "ratio_east": 0.25,
                "offset_min": 20.0,
                "offset_east_min": 25.0,
                "river": 0.0,
            },
        ),
        EffectSpec(
            "seiche",
            "world",
            "a lake's standing wave",
            "the current along the flow direction (the channel in a river) gains amplitude_m_s "
            "sin(2 pi t / period_s + phase_deg), t from the run's start: the basin's water sloshing "
            "from end to end",
            {"amplitude_m_s": 0.15, "period_s": 4440.0, "phase_deg": 0.0},
        ),
        EffectSpec(
            "stage",
            "world",
            "the river's stage follows its discharge",
            "a rating curve Q = C (h - e)^b: the stage is scale_m ((Q / Q0)^(1 / b) - 1) above the start's, "
            "so it rises with dam_release's discharge; every sounding is deeper by it",
            {"scale_m": 1.0, "b": 1.6},
        ),
    )
}


@dataclass
class Effect:
    """An effect switched on for a run, with its parameters resolved."""

    name: str
    params: dict[str, Any]

    @property
    def spec(self) -> EffectSpec:
        return CATALOGUE[self.name]


def parse(spec: str | Effect) -> Effect:
    """``name`` or ``name:key=value:key=value`` to an Effect with defaults filled in."""
    if isinstance(spec, Effect):
        return spec
    name, *kvs = spec.strip().split(":")
    if name not in CATALOGUE:
        raise ValueError(f"unknown effect {name!r}; known: {', '.join(CATALOGUE)}")
    params = dict(CATALOGUE[name].params)
    for kv in kvs:
        k, _, v = kv.partition("=")
        if k not in params:
            raise ValueError(f"effect {name} has no parameter {k!r}; it has {', '.join(params)}")
        params[k] = type(params[k])(float(v)) if isinstance(params[k], int | float) else v
    return Effect(name, params)


def parse_list(specs: str | list[str | Effect] | None) -> list[Effect]:
    """Effects from a comma-separated string or a list; ``none`` or empty gives []."""
    if specs is None:
        return []
    if isinstance(specs, str):
        specs = [s for s in specs.split(",") if s.strip() and s.strip() != "none"]
    out = [parse(s) for s in specs]
    names = [e.name for e in out]
    if len(set(names)) != len(names):
        raise ValueError(f"effect given twice: {names}")
    return out


def lines() -> list[str]:
    """One line per effect for ``forcemap sim --list``."""
    return [f"{e.name:20s} {e.kind:10s} {e.story}: {e.does}" for e in CATALOGUE.values()]
