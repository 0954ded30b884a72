"""NMEA 0183 instruments: sentences logged, navigation to the boat state, readings to the assembler.

One line splitter per port, one strict parser for all. Navigation: RMC, GGA, GLL (position), VTG
(ground velocity), HDT, HDG/HDM with variation, VHW's true heading (heading), ROT (yaw rate);
ignored once an autopilot gives navigation. Readings: MWV R and VWR (apparent wind), MWV T and MWD
(the instrument's true wind), VHW (speed through water), DPT, DBT, DBS (depth), MTW (water
temperature), XDR (the hull's roll and pitch: ROLL/PTCH, HEEL/TRIM). Each reading is named by its source (port, talker, sentence and, for positions, a
fingerprint: forcemap.host.fuse.sources) and only the chosen source of each quantity is used.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

from forcemap.host.decode import nmea_checksum
from forcemap.host.decode.nmea import LineSplitter, NmeaParser, Sentence, depth_below_surface
from forcemap.host.fuse import compensation as comp
from forcemap.host.fuse import fix_quality as fq
from forcemap.host.fuse import nav_model
from forcemap.host.fuse.declination import DeclinationModel
from forcemap.host.fuse.position_jumps import JumpFilter
from forcemap.host.fuse.sources import (
    nmea_fingerprint,
    receiver_name,
    source_name,
    split_name,
)
from forcemap.host.log.messages import (
    ApparentWind,
    BoatStateRecord,
    Depth,
    NmeaSentence,
    TrueWind,
    WaterSpeed,
)
from forcemap.host.log.qa_records import QaFinding

if TYPE_CHECKING:
    from forcemap.host.fuse.feed import FeedContext

# which quantity each assembler reading is (forcemap.host.fuse.sources.QUANTITIES)
QUANTITY = {
    "app": "wind",
    "true": "wind_true",
    "stw": "stw",
    "depth": "depth",
    "temp": "water_temp",
    "attitude": "attitude",
}


class NmeaDecoder:
    """Lines from any number of NMEA ports; values to the pipeline's state and assembler."""

    def __init__(self, pipe: FeedContext, checksum: str = "strict") -> None:
        self.pipe = pipe
        self.splitters: dict[str, LineSplitter] = {}
        self.parser = NmeaParser(checksum)
        self.variation: float | None = pipe.cal.magnetic_variation_deg
        self.log_variation = False  # a sentence of the log gave the variation
        self.declination = DeclinationModel()  # where nothing gives it (IGRF-14)
        self.jumps = JumpFilter()
        self.conn = "nmea"  # the port of the line being handled
        # (port, talker) -> the receiver of its last position sentence: whose fix a GSA describes
        self.receivers: dict[tuple[str, str], str] = {}
        self.bytes = 0
        self.handlers = {
            "DPT": self._depth,
            "DBT": self._depth,
            "DBS": self._depth,
            "MTW": self._mtw,
            "RMC": self._rmc,
            "GGA": self._gga,
            "GLL": self._gll,
            "GSA": self._gsa,
            "VTG": self._vtg,
            "HDT": self._hdt,
            "ROT": self._rot,
            "HDM": self._hdm,
            "HDG": self._hdm,
            "VHW": self._vhw,
            "MWV": self._mwv,
            "VWR": self._vwr,
            "MWD": self._mwd,
            "XDR": self._xdr,
        }

    def feed(self, source: str, t_mono_ns: int, t_wall_ns: int, data: bytes) -> None:
        wall = t_wall_ns * 1e-9
        self.bytes += len(data)
        splitter = self.splitters.get(source)
        if splitter is None:
            splitter = self.splitters[source] = LineSplitter()
        for line in splitter.feed(data):
            try:
                self.line(line, source, wall, t_mono_ns, t_wall_ns)
            except Exception:
                self.pipe.internal("nmea")

    def gap(self, source: str) -> None:
        self.splitters.pop(source, None)

    def flush(self, now: float) -> None:
        """The unterminated last line of every port (at close)."""
        for source, splitter in self.splitters.items():
            for line in splitter.flush():
                self.line(line, source, now, None, int(now * 1e9))

    def counters(self) -> dict[str, Any]:
        return {**self.parser.counters(), "bytes": self.bytes, "position_jumps": self.jumps.jumps}

    def findings(self) -> list[QaFinding]:
        """What this decoder found about the log: a checksum variant, the declination model's use,
        position jumps (forcemap.host.log.qa_records)."""
        p = self.parser
        bad = p.rejected["bad_checksum"] + (
            sum(p.variants.values()) if p.checksum == "lenient" else 0
        )
        found = [
            nmea_checksum.finding(p.variants, p.variant_addresses, bad, p.lines, p.checksum),
            self.declination.finding(),
            self.jumps.finding(),
        ]
        return [f for f in found if f is not None]

    def line(
        self, line: bytes, source: str, t: float, t_mono_ns: int | None, t_wall_ns: int
    ) -> None:
        s = self.parser.parse(line)
        if s is None:
            return
        msg = NmeaSentence(s.text, s.valid, s.reason, s.talker, s.type, source)
        msg.t_mono_ns, msg.t_wall_ns = t_mono_ns, t_wall_ns
        self.pipe.write("/nmea/sentence", t, msg)
        if s.valid and s.data:
            handler = self.handlers.get(s.type)
            if handler is not None:
                self.conn = source
                handler(s, t)

    def name(self, s: Sentence) -> str:
        """The source of sentence ``s`` on the current port."""
        fp = nmea_fingerprint(s.text, s.type) if s.type in ("RMC", "GGA", "GLL") else ""
        return source_name(self.conn, s.talker, s.type, fp)

    # --- readings -----------------------------------------------------------------------------------

    def _reading(self, kind: str, t: float, value: tuple, s: Sentence) -> None:
        ref = s.data.get("reference") if s.type == "MWV" else None
        name = self.name(s) + (f" {ref}" if ref else "")
        if self.pipe.source_reading(QUANTITY[kind], name, t, value):
            self.pipe.assembler.reading(kind, t, value, name)

    def _depth(self, s: Sentence, t: float) -> None:
        if s.type == "DBS":
            depth = s.data.get("depth_m")
        else:
            depth = depth_below_surface(s, self.pipe.cal.depth_offset_m)
        if depth is None:
            return
        # DPT says where its transducer is: it ranks before DBT and DBS (sources.SENTENCE_ORDER)
        self._reading("depth", t, (depth,), s)
        msg = Depth(self.pipe.utc_s(t), depth, None, s.type, "nmea")
        self.pipe.write("/depth", t, msg)

    def _xdr(self, s: Sentence, t: float) -> None:
        """The hull's roll and pitch (a heel sensor alone gives roll)."""
        roll, pitch = s.data.get("roll"), s.data.get("pitch")
        if roll is not None or pitch is not None:
            self._reading("attitude", t, (roll, pitch), s)

    def _mtw(self, s: Sentence, t: float) -> None:
        temp = s.data["water_temp"]
        if temp is not None:
            self._reading("temp", t, (temp,), s)
            self.pipe.write("/depth", t, Depth(self.pipe.utc_s(t), None, temp, s.type, "nmea"))

    def _vhw(self, s: Sentence, t: float) -> None:
        if s.data["heading"] is not None:
            self._heading(t, s.data["heading"], s)
        stw = s.data["stw"]
        if stw is not None:
            self._reading("stw", t, (stw * (self.pipe.cal.stw_gain or 1.0),), s)
            self.pipe.write("/water/speed", t, WaterSpeed(self.pipe.utc_s(t), stw, s.type, "nmea"))

    def _mwv(self, s: Sentence, t: float) -> None:
        d = s.data
        if d["status"] != "A" or d["angle"] is None or d["speed"] is None:
            return
        if d["reference"] == "R":
            self._apparent(s, t, d["speed"], d["angle"])
        elif d["reference"] == "T":
            heading = self.pipe.assembler.state.at(t, edge=True).heading
            if heading is not None:
                self._instrument_wind(s, t, d["speed"], comp.wrap360(heading + d["angle"]))

    def _vwr(self, s: Sentence, t: float) -> None:
        d = s.data
        if d["angle"] is not None and d["speed"] is not None:
            self._apparent(s, t, d["speed"], d["angle"])

    def _mwd(self, s: Sentence, t: float) -> None:
        d = s.data
        if d["dir"] is not None and d["speed"] is not None:
            self._instrument_wind(s, t, d["speed"], d["dir"])
        elif d["dir_mag"] is not None and d["speed"] is not None and self.variation is not None:
            self._instrument_wind(s, t, d["speed"], comp.wrap360(d["dir_mag"] + self.variation))

    def _instrument_wind(self, s: Sentence, t: float, speed: float, direction: float) -> None:
        self._reading("true", t, (speed, direction), s)
        e, n = comp.velocity(speed, direction)
        msg = TrueWind(self.pipe.utc_s(t), speed, direction, -e, -n, source="nmea")
        msg.route, msg.sentence = "instrument", s.type
        self.pipe.write("/wind/true", t, msg)

    def _apparent(self, s: Sentence, t: float, speed: float, angle: float) -> None:
        pipe = self.pipe
        t_log = pipe.utc_s(t)
        pipe.write("/wind/apparent", t, ApparentWind(t_log, speed, angle, source="nmea"))
        self._reading("app", t, (speed, angle), s)
        st = pipe.assembler.state.at(t, edge=True)
        if st.heading is None or st.v_east is None or st.v_north is None:
            return
        we, wn = comp.true_wind(speed, angle, st.heading, st.v_east, st.v_north)
        msg = TrueWind(t_log, math.hypot(we, wn), comp.from_direction(we, wn), we, wn, speed, angle)
        msg.heading, msg.boat_east, msg.boat_north = st.heading, st.v_east, st.v_north
        msg.source, msg.sentence = "nmea", s.type
        pipe.write("/wind/true", t, msg)

    # --- navigation ---------------------------------------------------------------------------------

    def _nav_ok(self, s: Sentence) -> bool:
        if s.type in ("RMC", "HDG") and s.data.get("variation") is not None:
            if self.pipe.cal.magnetic_variation_deg is None:
                self.variation = s.data["variation"]
                self.log_variation = True
        return not self.pipe.mav_nav  # the autopilot is the navigation source when there is one

    def _receiver(self, s: Sentence) -> str:
        """The receiver (group) of a position sentence, remembered for the GSA that follows it."""
        receiver = receiver_name(self.conn, s.talker, nmea_fingerprint(s.text, s.type))
        self.receivers[(self.conn, s.talker)] = receiver
        return receiver

    def _quality(self, s: Sentence, t: float, fix: int | None, hdop: float | None = None) -> None:
        self.pipe.selector.report_fix(self._receiver(s), s.type, t, fix, hdop)

    def _rmc(self, s: Sentence, t: float) -> None:
        d = s.data
        if not self._nav_ok(s):
            return
        self._quality(s, t, fq.mode_fix(d["mode"]) if d["status"] == "A" else fq.NO_FIX)
        if d["status"] == "A" and d["lat"] is not None:
            self._fix(s, t, d["lat"], d["lon"], d["sog"], d["cog"])

    def _gga(self, s: Sentence, t: float) -> None:
        d = s.data
        if not self._nav_ok(s):
            return
        self._quality(s, t, fq.gga_fix(d["quality"]), d["hdop"] if d["quality"] else None)
        if d["lat"] is not None and d.get("quality"):
            self._fix(s, t, d["lat"], d["lon"], None, None, d.get("alt") or 0.0)

    def _gll(self, s: Sentence, t: float) -> None:
        d = s.data
        if not self._nav_ok(s):
            return
        self._quality(s, t, fq.mode_fix(d["mode"]) if d["status"] == "A" else fq.NO_FIX)
        if d["status"] == "A" and d["lat"] is not None:
            self._fix(s, t, d["lat"], d["lon"], None, None)

    def _gsa(self, s: Sentence, t: float) -> None:
        """A fix type and HDOP, for the receiver whose position came last on this port and talker
        (a receiver sends its GSA with its fix; a GSA of a talker with no position is not used)."""
        receiver = self.receivers.get((self.conn, s.talker))
        if receiver is not None and self._nav_ok(s):
            d = s.data
            self.pipe.selector.report_fix(
                receiver, "GSA", t, fq.gsa_fix(d["fix_type"]), d["hdop"] if d["fix_type"] else None
            )

    def _vtg(self, s: Sentence, t: float) -> None:
        d = s.data
        state = self.pipe.assembler.state
        if not self._nav_ok(s) or d["sog"] is None or not state.position.v:
            return
        sog, cog = d["sog"], d["cog"]
        # the ground velocity of the receiver that gives the position (between its fixes), or of
        # one VTG source for a position source without velocity of its own (GGA, GLL)
        chosen = self.pipe.selector.member.get("position", "")
        conn, talker, kind = split_name(chosen) if chosen else ("", "", "")
        same = (conn, talker) == (self.conn, s.talker)
        used = self.pipe.source_reading("velocity", self.name(s), t, (sog, cog))
        if not same and (kind in ("RMC", "GLOBAL_POSITION_INT", "GPS_RAW_INT") or not used):
            return
        last = state.position.v[-1]
        if cog is not None:
            ve, vn = comp.velocity(sog, cog)
        else:
            ve, vn = (0.0, 0.0) if sog == 0 else (None, None)
        state.add_position(t, last[0], last[1], ve, vn)
        self.pipe.assembler.nav["velocity"] = self.name(s)

    def _hdt(self, s: Sentence, t: float) -> None:
        if self._nav_ok(s) and s.data["heading"] is not None:
            self._heading(t, s.data["heading"], s)

    def _hdm(self, s: Sentence, t: float) -> None:
        d = s.data
        if not self._nav_ok(s) or d["heading_mag"] is None:
            return
        variation, suffix = self.variation, " +variation"
        if variation is None:
            variation, suffix = self._model_declination(t), " +IGRF-14"
        if variation is not None:
            true = d["heading_mag"] + (d.get("deviation") or 0.0) + variation
            self._heading(t, true, s, suffix)

    def _model_declination(self, t: float) -> float | None:
        """IGRF-14's declination at the boat's last position and the log's date (None before a fix
        or outside the model's years): forcemap.host.fuse.declination."""
        fix = self.pipe.last_fix
        if fix is None:
            return None
        value = self.declination.at(fix["lat"], fix["lon"], self.pipe.utc_s(t))
        if value is not None:
            self.declination.headings += 1
        return value

    def _rot(self, s: Sentence, t: float) -> None:
        d = s.data
        if not self._nav_ok(s) or d["yaw_rate"] is None or d["status"] == "V":
            return
        name = self.name(s)
        rate = d["yaw_rate"] * (60.0 if self.pipe.cal.rot_unit == "deg/s" else 1.0)
        if self.pipe.source_reading("yaw_rate", name, t, (rate,)):
            self.pipe.assembler.state.add_yaw_rate(t, rate)
            self.pipe.assembler.nav["yaw_rate"] = name

    def _heading(self, t: float, heading: float, s: Sentence, suffix: str = "") -> None:
        if self.pipe.mav_nav:
            return
        name = self.name(s) + suffix
        if self.pipe.source_reading("heading", name, t, (comp.wrap360(heading),)):
            self.pipe.assembler.state.add_heading(t, heading)
            self.pipe.assembler.nav["heading"] = name

    def _fix(
        self,
        s: Sentence,
        t: float,
        lat: float,
        lon: float,
        sog: float | None,
        cog: float | None,
        alt: float = 0.0,
    ) -> None:
        asm = self.pipe.assembler
        state = asm.state
        name = self.name(s)
        receiver = self._receiver(s)
        if self.jumps.is_jump(t, lat, lon, self.pipe.utc_s(t)):
            return  # counted and listed with its reason (position_jumps.py)
        tod = nav_model.time_of_day(s.text, s.type)
        stamp = None if tod is None else nav_model.on_day(self.pipe.utc_s(t), tod)
        if not self.pipe.source_reading("position", name, t, (lat, lon, sog, cog), receiver, stamp):
            return
        if sog is not None:
            state.add_position_sog_cog(t, lat, lon, sog, cog)
            asm.nav["velocity"] = name
        else:
            last = state.position.v[-1] if state.position.v else None
            state.add_position(t, lat, lon, last[2] if last else None, last[3] if last else None)
        asm.nav["position"] = name
        self.pipe.fix(t, lat, lon, alt, None)
        msg = BoatStateRecord(**state.at(t, edge=True).as_message(), source=name)
        self.pipe.write("/boat/state", t, msg)
