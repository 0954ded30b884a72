"""The instruments a survey actually has, named the way the user knows them, for every text that names one.

A log written by `forcemap run` or `forcemap import` says in its ``columns`` metadata who fed each column
(``nmea VHW``, ``nmea GP RMC``, ``mavlink ATTITUDE``, ``bridge paddle wheels``; two sources of one column
are joined by ``; ``). From that, "the speed log (VHW)" and "the GNSS (GP RMC)". A CSV or Parquet table
carries no such record: then the columns name the readings ("the speed through water (stw)"), and nothing
is named that the table does not show: never a bridge or an autopilot a boat may not have.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from forcemap.host.workbench.survey.table import Survey

# NMEA 0183 sentence -> the instrument that sends it
NMEA_KINDS = {
    "speed log": ("VHW", "VBW", "VLW"),
    "GNSS": ("RMC", "GGA", "GLL", "VTG", "GNS", "ZDA", "GSA", "GST"),
    "compass": ("HDM", "HDG", "HDT", "THS"),
    "rate-of-turn sensor": ("ROT",),
    "sounder": ("DBT", "DPT", "DBS"),
    "water temperature sensor": ("MTW",),
    "anemometer": ("MWV", "VWR", "VWT", "MWD"),
}
MAVLINK_KINDS = {
    "autopilot's wind estimate": ("WIND",),
    "autopilot's rangefinder": ("RANGEFINDER", "DISTANCE_SENSOR", "WATER_DEPTH"),
}


def _nmea_name(rest: str) -> str:
    """'GPRMC [hhmmss.ss 5dp]', 'GP RMC' or 'HDM+variation' -> 'the GNSS (GP RMC, hhmmss.ss 5dp)': the
    talker apart from the sentence, the receiver's fingerprint (where two share a talker) after them."""
    fingerprint = re.findall(r"\[([^\]]*)\]", rest)
    words = re.sub(r"\[[^\]]*\]|\+\S*", "", rest).split()
    sentence = next(
        (w[-3:] for w in reversed(words) if len(w) >= 3 and w[-3:].isalpha() and w[-3:].isupper()),
        "",
    )
    kind = next((k for k, types in NMEA_KINDS.items() if sentence in types), "NMEA instrument")
    words = [f"{w[:-3]} {w[-3:]}" if len(w) == 5 and w[-3:] == sentence else w for w in words]
    return f"the {kind} ({', '.join([' '.join(words), *fingerprint])})"


def source_name(label: str) -> str:
    """One ``columns`` label (one source) as the user knows it."""
    conn, _, rest = label.strip().partition(" ")
    if conn == "nmea":
        return _nmea_name(rest)
    if conn == "mavlink":
        first = rest.split()[0] if rest else ""
        kind = next((k for k, types in MAVLINK_KINDS.items() if first in types), "autopilot")
        return f"the {kind} (MAVLink {rest})"
    if conn == "dataflash":
        return f"the autopilot's log (DataFlash {rest})"
    if conn == "bridge":
        return f"the bridge's {rest}" if rest else "the bridge"
    return label.strip()


@dataclass
class Instruments:
    """Who fed each column of one survey, and which kinds of instrument it shows."""

    columns: set[str]
    provenance: dict[str, str] = field(default_factory=dict)
    # each navigation source's measured latency (Survey.latencies; docs/NAVIGATION.md)
    latencies: dict[str, dict] = field(default_factory=dict)

    @classmethod
    def of(cls, survey: Survey) -> Instruments:
        return cls(set(survey.columns), dict(survey.provenance), dict(survey.latencies))

    def late_source(self, min_s: float = 0.5) -> str:
        """'the compass (HE HDT), +5.0 s late' for the latest source whose latency stayed in the
        rows, or ''."""
        kept = [
            (n, d["latency"])
            for n, d in self.latencies.items()
            if d.get("latency") is not None and abs(d["latency"]) >= min_s and not d.get("removed")
        ]
        if not kept:
            return ""
        n, lat = max(kept, key=lambda x: abs(x[1]))
        return f"{source_name(n)}, {lat:+.1f} s late"

    def sources(self, column: str) -> list[str]:
        """The labels of the sources that fed `column`: the parts of a derived column's label joined by
        ' + ', and the alternatives joined by '; '."""
        label = self.provenance.get(column, "")
        out: list[str] = []
        for alt in label.split(";"):
            for part in alt.split(" + "):
                if part.strip() and part.strip() not in out:
                    out.append(part.strip())
        return out

    def name(self, column: str, fallback: str) -> str:
        """Who fed `column` ('the speed log (VHW)'; two sources: 'A and B, interleaved'), or `fallback`."""
        labels = [x.strip() for x in self.provenance.get(column, "").split(";") if x.strip()]
        if not labels:
            return fallback
        names = list(dict.fromkeys(source_name(x) for x in labels))
        return names[0] if len(names) == 1 else " and ".join(names) + ", interleaved"

    # ---- the instruments a text may name
    @property
    def paddle_wheels(self) -> bool:
        return any(re.fullmatch(r"wheel\d+_speed", c) for c in self.columns) or any(
            "paddle wheels" in v for v in self.provenance.values()
        )

    @property
    def speed_log(self) -> bool:
        return "stw" in self.columns

    @property
    def anemometer(self) -> bool:
        return any(c.startswith(("app_wind_", "wind_")) for c in self.columns)

    @property
    def compass(self) -> bool:
        return "heading" in self.columns

    def flow_sensor(self) -> str | None:
        """The instrument that reads the water past the hull, or None."""
        if self.paddle_wheels:
            return self.name("wheel1_speed", "the paddle wheels")
        if self.speed_log:
            return self.name("stw", "the speed log (stw)")
        return None

    def wind_sensor(self) -> str | None:
        if not self.anemometer:
            return None
        return self.name("app_wind_speed", "the anemometer")

    def boat_frame(self, family: str) -> str:
        """What measures a wind or current vector in the boat's frame."""
        if family == "wind":
            return self.wind_sensor() or "the apparent wind"
        return self.flow_sensor() or "the flow reading in the boat's frame"

    def navigation(self) -> str:
        """Where the heading and the ground velocity a vector is turned with come from."""
        hdg = self.name("heading", "")
        vel = self.name("sog", "")
        if not hdg and not vel:
            return "the heading and ground velocity (heading, sog, cog)"
        if hdg == vel or not vel:
            return hdg or vel
        return f"{hdg} with {vel}" if hdg else vel
