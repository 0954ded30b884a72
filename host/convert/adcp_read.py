"""A TRDI PD0 file (WinRiver, WinRiver II) read through MHKiT's dolfyn into plain arrays.

The reading is dolfyn's (``mhkit.dolfyn``, the maintained home of dolfyn), needed only by the
``forcemap[adcp]`` extra; nothing here touches the boat's motion. What comes out is what the file
says, in SI and UNIX seconds on the instrument's own clock: the velocities as recorded (``vel_raw``,
``vel_bt_raw``, in the file's coordinate system, for comparison with dolfyn), the same rotated to
earth with the instrument's own heading (``vel``, ``vel_bt``: east, north, up, the water's and the
bottom's velocity relative to the instrument), the bottom-track ranges, attitude, temperature and
every GPS fix the file carries. TRDI's no-data value (-32.768 m/s) and a zero bottom range are NaN
in the earth arrays.
"""

from __future__ import annotations

import math
import struct
import warnings
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any

import numpy as np
from forcemap.host.extras import install_hint

PD0_ID = b"\x7f\x7f"
BAD_VEL = -32.768  # TRDI's no-data velocity, as dolfyn scales it (-32768 mm/s)


class AdcpUnavailable(ImportError):
    """The ADCP extra is not installed: the message names the pip install."""


@dataclass
class AdcpRaw:
    """One PD0 file's ensembles (n), cells (m) and GPS fixes (g), as recorded."""

    path: str
    model: str
    coord_sys: str  # the file's: beam, inst, ship or earth
    beam_angle: float  # deg
    cell_size: float  # m
    range: np.ndarray  # (m,) distance of each cell's centre from the transducer, m
    t_inst: np.ndarray  # (n,) UNIX s on the instrument's clock
    number: np.ndarray  # (n,) ensemble numbers
    heading: np.ndarray  # (n,) deg, the instrument's compass
    pitch: np.ndarray
    roll: np.ndarray
    temp: np.ndarray  # (n,) deg C
    draft: np.ndarray  # (n,) transducer depth, m
    vel_raw: np.ndarray  # (4, m, n) as dolfyn reads it (file coordinates)
    vel_bt_raw: np.ndarray  # (4, n)
    dist_bt: np.ndarray  # (4, n) vertical range of each beam to the bed, m; NaN where no lock
    vel: np.ndarray  # (3, m, n) water relative to the instrument, east/north/up
    vel_bt: np.ndarray  # (3, n) bed relative to the instrument, east/north/up
    t_gps: np.ndarray  # (g,) UNIX s, GPS UTC
    t_gps_inst: np.ndarray  # (g,) the instrument's time of the ensemble that carried each fix
    lat: np.ndarray
    lon: np.ndarray
    fix: np.ndarray  # GGA fix quality
    hdop: np.ndarray
    n_sat: np.ndarray
    vtg_speed: np.ndarray | None  # (g,) m/s, where the file has VTG
    vtg_course: np.ndarray | None  # (g,) deg
    skipped_bytes: int = 0  # bytes outside ensembles whose checksum holds, left out before reading

    @property
    def n(self) -> int:
        return int(self.t_inst.size)

    @property
    def has_gps(self) -> bool:
        return bool(np.isfinite(self.lat).any())

    def head(self, k: int) -> AdcpRaw:
        """The first ``k`` ensembles (and the fixes they carried), as dolfyn's ``nens=k`` reads them."""
        last = self.t_inst[min(k, self.n) - 1] if k else -math.inf
        g = self.t_gps_inst <= last if self.t_gps_inst.size else slice(None)
        ens = {
            f.name: getattr(self, f.name)[..., :k]
            for f in fields(self)
            if f.name in ("t_inst", "number", "heading", "pitch", "roll", "temp", "draft")
            or f.name in ("vel_raw", "vel_bt_raw", "dist_bt", "vel", "vel_bt")
        }
        gps = {
            f.name: getattr(self, f.name)[g]
            for f in fields(self)
            if f.name in ("t_gps", "t_gps_inst", "lat", "lon", "fix", "hdop", "n_sat")
            or (f.name in ("vtg_speed", "vtg_course") and getattr(self, f.name) is not None)
        }
        return replace(self, **ens, **gps)


def is_pd0(head: bytes) -> bool:
    """True when ``head`` starts a PD0 ensemble: 0x7F7F, a byte count, and data-type offsets."""
    if len(head) < 8 or not head.startswith(PD0_ID):
        return False
    (nbytes,) = struct.unpack_from("<H", head, 2)
    ndat = head[5]
    if not (0 < ndat < 64 and nbytes > 6 + 2 * ndat) or len(head) < 6 + 2 * ndat:
        return False
    first = struct.unpack_from("<H", head, 6)[0]
    return first == 6 + 2 * ndat and head[first : first + 2] in (b"\x00\x00", b"\x01\x00", b"")


def _ensembles(data: bytes) -> list[tuple[int, int]]:
    """(start, end) of every ensemble whose PD0 checksum holds, its checksum word included."""
    out = []
    i = 0
    while True:
        i = data.find(PD0_ID, i)
        if i < 0 or i + 4 > len(data):
            return out
        (nbytes,) = struct.unpack_from("<H", data, i + 2)
        end = i + nbytes
        if nbytes > 4 and end + 2 <= len(data):
            (check,) = struct.unpack_from("<H", data, end)
            if sum(data[i:end]) & 0xFFFF == check:
                out.append((i, end + 2))
                i = end + 2
                continue
        i += 1


def count_ensembles(path: str | Path) -> int:
    """Ensembles whose PD0 checksum holds, counted from the bytes alone (dolfyn's count checked)."""
    return len(_ensembles(Path(path).read_bytes()))


def dolfyn() -> Any:
    """MHKiT's dolfyn, or AdcpUnavailable naming the pip install."""
    try:
        from mhkit import dolfyn as dol
    except ImportError:
        raise AdcpUnavailable(
            f"reading an ADCP file needs MHKiT's dolfyn: {install_hint('adcp')}"
        ) from None
    return dol


def _seconds(values: Any) -> np.ndarray:
    return np.asarray(values).astype("datetime64[ns]").astype(np.int64) / 1e9


def _f(ds: Any, name: str) -> np.ndarray:
    if name in ds:
        return np.asarray(ds[name].values, dtype=float)
    return np.full(ds["time_gps"].size if "time_gps" in ds.dims else 0, math.nan)


def read_dataset(path: str | Path) -> Any:
    """dolfyn's xarray Dataset of the file, quietly (it prints and warns)."""
    dol = dolfyn()
    import contextlib
    import io
    import logging

    logging.disable(logging.WARNING)  # dolfyn logs each bad checksum on the root logger
    try:
        with warnings.catch_warnings(), contextlib.redirect_stdout(io.StringIO()):
            warnings.simplefilter("ignore")
            return dol.read(str(path))
    finally:
        logging.disable(logging.NOTSET)


def _earth(ds: Any) -> tuple[np.ndarray, np.ndarray]:
    """(vel, vel_bt) east/north/up with the instrument's heading; no-data masked before rotating."""
    dol = dolfyn()
    ds = ds.copy(deep=True)
    for name in ("vel", "vel_bt"):
        v = ds[name].values
        ds[name].values = np.where(v <= BAD_VEL + 1e-6, np.nan, v)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if ds.attrs.get("coord_sys") != "earth":
            ds = dol.rotate2(ds, "earth", inplace=False)
    vel = np.asarray(ds["vel"].values[:3], dtype=float)
    bt = np.asarray(ds["vel_bt"].values[:3], dtype=float)
    return vel, bt


def read_pd0(path: str | Path) -> AdcpRaw:
    """Every ensemble and fix of a PD0 file (AdcpUnavailable without the extra).

    Bytes outside ensembles whose checksum holds (damage, a cut end) are left out before dolfyn
    reads the rest, and counted in ``skipped_bytes``."""
    dolfyn()
    data = Path(path).read_bytes()
    spans = _ensembles(data)
    # damage: bytes outside the good ensembles anywhere but after the last one (a cut file)
    damaged = bool(spans) and (
        spans[0][0] != 0 or any(b != a2 for (_, b), (a2, _) in zip(spans, spans[1:], strict=False))
    )
    if damaged:
        import tempfile

        kept = b"".join(data[a:b] for a, b in spans)
        with tempfile.TemporaryDirectory() as tmp:
            clean = Path(tmp) / Path(path).name
            clean.write_bytes(kept)
            ds = read_dataset(clean)
    else:
        ds = read_dataset(path)
    raw = _from_dataset(ds, path)
    raw.skipped_bytes = len(data) - sum(b - a for a, b in spans) if damaged else 0
    return raw


def _from_dataset(ds: Any, path: str | Path) -> AdcpRaw:
    vel, bt = _earth(ds)
    dist = np.asarray(ds["dist_bt"].values, dtype=float)[:4]
    dist = np.where(dist > 0, dist, np.nan)
    has_gps = "time_gps" in ds.dims and ds["time_gps"].size > 0
    empty = np.zeros(0)
    gps = {
        "t_gps": _seconds(ds["time_gps"].values) if has_gps else empty,
        "t_gps_inst": _seconds(ds["hdwtime_gps"].values) if "hdwtime_gps" in ds else empty,
        "lat": _f(ds, "latitude_gps") if has_gps else empty,
        "lon": _f(ds, "longitude_gps") if has_gps else empty,
        "fix": _f(ds, "fix_gps") if has_gps else empty,
        "hdop": _f(ds, "hdop_gps") if has_gps else empty,
        "n_sat": _f(ds, "n_sat_gps") if has_gps else empty,
    }
    vtg = "speed_over_grnd_gps" in ds
    return AdcpRaw(
        path=str(path),
        model=str(ds.attrs.get("inst_model", "TRDI")),
        coord_sys=str(ds.attrs.get("coord_sys", "")),
        beam_angle=float(ds.attrs.get("beam_angle", 20.0)),
        cell_size=float(ds.attrs.get("cell_size", math.nan)),
        range=np.asarray(ds["range"].values, dtype=float),
        t_inst=_seconds(ds["time"].values),
        number=np.asarray(ds["number"].values, dtype=float),
        heading=np.asarray(ds["heading"].values, dtype=float),
        pitch=np.asarray(ds["pitch"].values, dtype=float),
        roll=np.asarray(ds["roll"].values, dtype=float),
        temp=np.asarray(ds["temp"].values, dtype=float),
        draft=np.asarray(ds["depth"].values, dtype=float),
        vel_raw=np.asarray(ds["vel"].values, dtype=float),
        vel_bt_raw=np.asarray(ds["vel_bt"].values, dtype=float),
        dist_bt=dist,
        vel=vel,
        vel_bt=bt,
        vtg_speed=_f(ds, "speed_over_grnd_gps") if vtg else None,
        vtg_course=_f(ds, "dir_over_grnd_gps") if vtg else None,
        **gps,
    )
