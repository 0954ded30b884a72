"""The records an ADCP import logs: a samples-table row with the ADCP's own columns, and the profile.

``AdcpSample`` is a ``Sample`` (docs/CONVENTIONS.md) plus the columns only an ADCP has; it goes on
``/samples`` like any row, so ``export`` and the workbench read it as any survey (the extra columns
follow the conventions' ones). ``AdcpProfile`` on ``/adcp/profile`` keeps each ensemble's profile of
water velocity over ground.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from forcemap.host.log.messages import Opt, Sample
from forcemap.host.log.record import Record

PROFILE_TOPIC = "/adcp/profile"


@dataclass(slots=True)
class AdcpSample(Sample):
    """A samples-table row from an ADCP ensemble: ``current_*`` is the near-surface cell's."""

    NAME = "forcemap.AdcpSample"
    DESCRIPTION = (
        "One samples-table row from an ADCP ensemble (docs/CONVENTIONS.md, docs/ADCP.md): current_* "
        "near the surface, current_*_davg depth-averaged, both water over ground, TO"
    )
    current_speed_davg: Opt = None
    current_dir_davg: Opt = None
    current_east_davg: Opt = None
    current_north_davg: Opt = None
    boat_east: Opt = None
    boat_north: Opt = None
    pitch: Opt = None
    roll: Opt = None
    position_dr: Opt = None
    boat_vel_filled: Opt = None


@dataclass(slots=True)
class AdcpProfile(Record):
    """One ensemble's profile: water over ground per cell (null where invalid)."""

    NAME = "forcemap.AdcpProfile"
    DESCRIPTION = (
        "One ADCP ensemble: cell depths below the surface (m) and the water's velocity over ground "
        "per cell (m/s; east, north, up), referenced to `reference` (bt or gps); null = no valid cell"
    )
    t: float
    ensemble: int
    reference: str
    depth: Opt = None
    cell_depth: list[float] = field(default_factory=list)
    east: list[Opt] = field(default_factory=list)
    north: list[Opt] = field(default_factory=list)
    up: list[Opt] = field(default_factory=list)
