"""The autopilot over MAVLink (live or tlog): navigation to the boat state, readings to the assembler.

Navigation: GLOBAL_POSITION_INT (or GPS_RAW_INT without it), ATTITUDE, VFR_HUD (throttle); once
the autopilot gives navigation, it replaces NMEA's. Readings: WIND (ArduPilot, 168: its true wind),
RANGEFINDER (173), DISTANCE_SENSOR (132) looking down (orientation 25) and WATER_DEPTH (11038):
depth below the transducer, plus the calibration's transducer depth; WATER_DEPTH's temperature.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from forcemap.host.decode import mavlink as mav
from forcemap.host.fuse import compensation as comp
from forcemap.host.fuse import fix_quality as fq
from forcemap.host.fuse.timesync import SourceClock
from forcemap.host.log.messages import BoatStateRecord, ClockMapping, Depth, RawMessage, TrueWind

if TYPE_CHECKING:
    from forcemap.host.fuse.feed import FeedContext


class MavDecoder:
    """MAVLink bytes to messages, timed by the autopilot's boot clock and GPS UTC."""

    def __init__(self, pipe: FeedContext) -> None:
        self.pipe = pipe
        self.packets = mav.MavlinkDecoder()
        self.clock = SourceClock("mavlink")
        self.vehicle: tuple[int, int] | None = None
        self.gpi = 0
        self.unknown = 0  # messages pymavlink cannot name: corrupt frames that passed, not topics

    def feed(self, source: str, t_mono_ns: int, t_wall_ns: int, data: bytes) -> None:
        mono = t_mono_ns * 1e-9
        for m in self.packets.feed(data):
            try:
                self._message(m, mono)
            except Exception:
                self.pipe.internal("mavlink")

    def gap(self, source: str = "mavlink") -> None:
        self.packets.reset()

    def counters(self) -> dict[str, Any]:
        vehicle = list(self.vehicle) if self.vehicle else None
        return {**self.packets.counters(), "unknown_messages": self.unknown, "vehicle": vehicle}

    def _message(self, m: Any, mono: float) -> None:
        pipe = self.pipe
        ty = m.get_type()
        if ty.startswith("UNKNOWN"):
            self.unknown += 1
            return
        if self.vehicle is None and ty == "HEARTBEAT":
            self.vehicle = mav.vehicle_of(m)
        vehicle = mav.is_vehicle(m, self.vehicle)
        t_mono = mono
        tb = getattr(m, "time_boot_ms", None) if vehicle else None
        if tb is not None:
            t_mono, mapping = self.clock.observe(tb * 1e-3, mono)
            pipe.emit_mapping(mapping)
        t = pipe.wall.to_wall(t_mono)
        if ty == "SYSTEM_TIME" and vehicle and m.time_unix_usec:
            if pipe.utc.observe(m.time_unix_usec * 1e-6, t):
                msg = ClockMapping("mavlink", "utc", pipe.utc.correction, 0.0, kind="utc")
                msg.points = len(pipe.utc.diffs)
                pipe.write("/timesync", t, msg)
        pipe.write("/mavlink/" + ty, t, RawMessage(mav.raw_dict(m)))
        if vehicle and ty in mav.USED:
            d = mav.to_si(m)
            if d is not None:
                self.values(ty, d, t)

    def values(self, ty: str, d: dict[str, Any], t: float, label: str = "") -> None:
        """SI values of one message (``mavlink.to_si``) at host wall time ``t``; ``label`` names
        the source in the ``columns`` metadata (default: ``mavlink <TYPE>``)."""
        pipe = self.pipe
        asm = pipe.assembler
        st = asm.state
        label = label or "mavlink " + ty
        if ty == "ATTITUDE":
            pipe.take_nav()
            if d.get("roll_deg") is not None:
                att = (d["roll_deg"], d.get("pitch_deg"))
                if pipe.source_reading("attitude", label, t, att):
                    asm.reading("attitude", t, att, label)
            if d["yaw_rate"] is not None:
                pipe.source_reading("yaw_rate", label, t, (d["yaw_rate"],))
            if pipe.source_reading("heading", label, t, (d["heading"],)):
                st.add_heading(t, d["heading"], d["yaw_rate"])
                asm.nav["heading"] = label
        elif ty == "GLOBAL_POSITION_INT":
            if d["lat"] == 0.0 and d["lon"] == 0.0:
                return  # no position yet
            pipe.take_nav()
            if not pipe.source_reading("position", label, t, (d["lat"], d["lon"], None, None)):
                return
            self.gpi += 1
            st.add_position(t, d["lat"], d["lon"], d["v_east"], d["v_north"])
            asm.nav["position"] = asm.nav["velocity"] = label
            pipe.fix(t, d["lat"], d["lon"], d["alt"], None)
            pipe.write(
                "/boat/state",
                t,
                BoatStateRecord(**st.at(t, edge=True).as_message(), source="mavlink"),
            )
        elif ty == "GPS_RAW_INT":
            pipe.selector.report_fix(label, ty, t, fq.mav_fix(d["fix_type"]), d["eph"])
            fix = (d["lat"], d["lon"], d["sog"], d["cog"])
            if d["fix_type"] >= 2 and pipe.source_reading("position", label, t, fix):
                pipe.take_nav()
                st.add_position_sog_cog(t, d["lat"], d["lon"], d["sog"], d["cog"])
                asm.nav["position"] = asm.nav["velocity"] = label
                pipe.fix(t, d["lat"], d["lon"], d["alt"], d["eph"])
        elif ty == "VFR_HUD":
            st.add_throttle(t, d["throttle"])
            asm.nav["throttle"] = label
        elif ty == "WIND":
            self._wind(t, d["speed"], d["dir"], label)
        elif ty in ("RANGEFINDER", "DISTANCE_SENSOR", "WATER_DEPTH"):
            self._depth(ty, d, t, label)

    def _wind(self, t: float, speed: float, direction: float, label: str) -> None:
        pipe = self.pipe
        if pipe.source_reading("wind_true", label, t, (speed, direction)):
            pipe.assembler.reading("true", t, (speed, direction), label)
        e, n = comp.velocity(speed, direction)
        msg = TrueWind(pipe.utc_s(t), speed, direction, -e, -n, source="mavlink")
        msg.route, msg.sentence = "instrument", "WIND"
        pipe.write("/wind/true", t, msg)

    def _depth(self, ty: str, d: dict[str, Any], t: float, label: str) -> None:
        if ty == "DISTANCE_SENSOR" and (d["orientation"] != mav.SENSOR_DOWNWARD or not d["valid"]):
            return
        if ty == "WATER_DEPTH" and not d["healthy"]:
            return
        pipe = self.pipe
        depth = d["distance"] + pipe.cal.depth_offset_m
        if pipe.source_reading("depth", label, t, (depth,)):
            pipe.assembler.reading("depth", t, (depth,), label)
        temp = d.get("temperature")
        if temp is not None and pipe.source_reading("water_temp", label, t, (temp,)):
            pipe.assembler.reading("temp", t, (temp,), label)
        pipe.write("/depth", t, Depth(pipe.utc_s(t), depth, temp, ty, "mavlink"))
