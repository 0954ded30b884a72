"""ArduPilot DataFlash logs (``.BIN``, a Pixhawk's SD card) through the sample assembler.

Read with pymavlink's ``DFReader``. Values are taken in the log's own units: the format's built-in
scales (``c``, ``C``, ``e``, ``E``, ``L``) are applied by DFReader, and a field's FMTU multiplier
(from MULT) where the format has none. Used: GPS (position, ground speed and course), ATT (yaw; roll and pitch),
RFND (echo sounder, distance below the transducer), WNDV (a sailboat's wind vane: its true wind,
``DrTru``/``SpdTru``). Every record is also logged raw on ``/dataflash/<NAME>``. Times are the
log's GPS-based UTC when it has GPS, else seconds since boot.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

from forcemap.host.log.messages import DataflashMessage
from pymavlink import DFReader

if TYPE_CHECKING:
    from forcemap.host.fuse.feed import FeedContext
    from forcemap.host.fuse.mavlink_feed import MavDecoder

FORMAT_SCALED = set("cCeEL")  # DFReader applies these formats' own scale
GPS_FIX_2D = 2  # GPS.Status: 0 no GPS, 1 no fix, 2 2-D fix, 3 3-D fix, more with corrections
RFND_DOWNWARD = 25


class DataflashDecoder:
    """DataFlash records to the MAVLink decoder's SI values (``MavDecoder.values``)."""

    def __init__(self, pipe: FeedContext, mav: MavDecoder) -> None:
        self.pipe = pipe
        self.mav = mav  # its SI values go where the autopilot's would
        self.mults: dict[str, str] = {}  # message name -> FMTU MultIds
        self.records = 0
        self.used: dict[str, int] = {}

    def read(self, path: str) -> None:
        """Every record of the file, in order."""
        reader = DFReader.DFReader_binary(path, zero_time_base=False)
        self.mult_lookup = reader.mult_lookup
        while True:
            m = reader.recv_msg()
            if m is None:
                break
            self.records += 1
            try:
                self.message(m, reader)
            except Exception:
                self.pipe.internal("dataflash")

    def message(self, m: Any, reader: Any) -> None:
        ty = m.get_type()
        if ty == "FMTU":
            name = reader.id_to_name.get(int(m.FmtType))
            if name:
                self.mults[name] = str(m.MultIds)
            return
        t = float(getattr(m, "_timestamp", 0.0) or 0.0)
        pipe = self.pipe
        pipe.write("/dataflash/" + ty, t, DataflashMessage(_fields(m)))
        values = self._values(ty, m)
        if values is not None:
            self.used[ty] = self.used.get(ty, 0) + 1
            self.mav.values(values[0], values[1], t, label="dataflash " + ty)
        pipe.advance(t)

    def value(self, m: Any, field: str) -> float:
        """A field in the log's unit: with its FMTU multiplier where the format has no scale."""
        v = float(getattr(m, field))
        fmt = m.fmt
        i = fmt.colhash[field]
        ids = self.mults.get(fmt.name, "")
        if fmt.format[i] not in FORMAT_SCALED and i < len(ids):
            mult = self.mult_lookup.get(ids[i])
            if mult not in (None, 0, 1):
                v *= mult
        return v

    def _values(self, ty: str, m: Any) -> tuple[str, dict[str, Any]] | None:
        v = self.value
        if ty == "GPS" and int(m.Status) >= GPS_FIX_2D:
            lat, lon, alt = v(m, "Lat"), v(m, "Lng"), v(m, "Alt")
            gps = {"fix_type": int(m.Status), "lat": lat, "lon": lon, "alt": alt, "eph": None}
            return "GPS_RAW_INT", gps | {"sog": v(m, "Spd"), "cog": v(m, "GCrs")}
        if ty == "ATT":
            att = {"roll_deg": v(m, "Roll"), "pitch_deg": v(m, "Pitch")}
            return "ATTITUDE", {"heading": v(m, "Yaw") % 360.0, "yaw_rate": None, **att}
        if ty == "RFND":
            orient = int(getattr(m, "Orient", RFND_DOWNWARD))
            if orient != RFND_DOWNWARD:
                return None
            return "RANGEFINDER", {"distance": v(m, "Dist")}
        if ty == "WNDV":
            d, s = v(m, "DrTru"), v(m, "SpdTru")
            if math.isfinite(d) and math.isfinite(s):
                return "WIND", {"dir": d % 360.0, "speed": s}
        return None


def _fields(m: Any) -> dict[str, Any]:
    d = m.to_dict()
    for k, v in d.items():
        if isinstance(v, float) and not math.isfinite(v):
            d[k] = None
        elif isinstance(v, bytes | bytearray):
            d[k] = bytes(v).hex()
    return d
