"""The magnetic declination where a log gives a magnetic heading and no variation: IGRF-14.

A compass that sends HDG or HDM with empty variation fields, on a bus whose RMC carries none either,
leaves nothing in the log to turn its heading into a true one. As OpenCPN and Signal K do, the
declination then comes from a model of the main field: IGRF-14 (IAGA's International Geomagnetic
Reference Field, 14th generation, definitive 1945-2020, valid 1900-2030), evaluated by the
pure-Python ``pyIGRF14`` at the boat's position and the log's date. It is evaluated again only when
the boat has moved RECOMPUTE_KM or the date RECOMPUTE_DAYS (the declination changes by about 0.1
deg a year and 0.1 deg over tens of km). The log's own variation wins from the first sentence that
carries one, and ``[compass] variation_deg`` in the boat file wins over both.

The result is said once, as a ``QaFinding`` (``qa.heading.declination``): its value, where and when.
"""

from __future__ import annotations

import calendar
import math
import time

from forcemap.host.log.qa_records import QaFinding

MODEL = "IGRF-14"
FIRST_YEAR, LAST_YEAR = 1900.0, 2030.0
RECOMPUTE_KM = 50.0
RECOMPUTE_DAYS = 30.0
EARTH_KM = 6371.0
INSTALL = (
    'pip install pyigrf14 (a dependency of forcemap: reinstall it with pip install "forcemap")'
)


def decimal_year(utc_s: float) -> float:
    """The calendar year with its fraction at UNIX time ``utc_s``."""
    tm = time.gmtime(utc_s)
    start = calendar.timegm((tm.tm_year, 1, 1, 0, 0, 0))
    end = calendar.timegm((tm.tm_year + 1, 1, 1, 0, 0, 0))
    return tm.tm_year + (utc_s - start) / (end - start)


def igrf_declination(lat: float, lon: float, utc_s: float) -> float:
    """IGRF-14's declination (deg, east positive) at sea level at ``lat``, ``lon`` (deg) and UNIX
    time ``utc_s``. ValueError outside 1900-2030; ImportError without pyIGRF14."""
    year = decimal_year(utc_s)
    if not FIRST_YEAR <= year <= LAST_YEAR:
        raise ValueError(f"{year:.0f} is outside {MODEL}'s {FIRST_YEAR:.0f}-{LAST_YEAR:.0f}")
    from pyIGRF14 import igrf_value

    return float(igrf_value(lat, lon % 360.0, 0.0, year)[0])


def _km(a: tuple[float, float], b: tuple[float, float]) -> float:
    dlat = math.radians(b[0] - a[0])
    dlon = math.radians(b[1] - a[1]) * math.cos(math.radians(0.5 * (a[0] + b[0])))
    return EARTH_KM * math.hypot(dlat, dlon)


def _place(lat: float, lon: float) -> str:
    return f"{abs(lat):.1f} {'N' if lat >= 0 else 'S'} {abs(lon):.1f} {'E' if lon >= 0 else 'W'}"


class DeclinationModel:
    """The model's declination for a log without variation, evaluated once per place and month."""

    def __init__(self) -> None:
        self.value: float | None = None
        self.where: tuple[float, float, float] | None = None  # lat, lon, utc_s of the evaluation
        self.first: tuple[float, float, float, float] | None = None  # lat, lon, utc_s, value
        self.evaluations = 0
        self.headings = 0  # magnetic headings turned true with it
        self.failure = ""  # why the model gave nothing ("" while it works)

    def at(self, lat: float, lon: float, utc_s: float) -> float | None:
        """The declination at the boat's position and time, or None (``failure`` says why)."""
        w = self.where
        if w is not None and self.value is not None:
            near = _km((w[0], w[1]), (lat, lon)) < RECOMPUTE_KM
            if near and abs(utc_s - w[2]) < RECOMPUTE_DAYS * 86400.0:
                return self.value
        try:
            self.value = igrf_declination(lat, lon, utc_s)
        except ValueError as e:
            self.failure, self.value = f"the log's date: {e}", None
            return None
        except ImportError:
            self.failure, self.value = f"pyIGRF14 is not installed ({INSTALL})", None
            return None
        self.where = (lat, lon, utc_s)
        self.evaluations += 1
        if self.first is None:
            self.first = (lat, lon, utc_s, self.value)
        return self.value

    def message(self) -> str:
        """The one line that says it: "magnetic heading without variation: IGRF-14 declination
        +1.3° at 46.2 N 6.2 E on 2014-08-22"."""
        if self.first is None:
            return f"magnetic heading without variation, and no declination: {self.failure}"
        lat, lon, t, value = self.first
        day = time.strftime("%Y-%m-%d", time.gmtime(t))
        more = f" ({self.evaluations} evaluations along the track)" if self.evaluations > 1 else ""
        return (
            f"magnetic heading without variation: {MODEL} declination {value:+.1f}° at "
            f"{_place(lat, lon)} on {day}{more}"
        )

    def finding(self) -> QaFinding | None:
        """The finding for the log's metadata (None when no magnetic heading needed it)."""
        if self.first is None and not self.failure:
            return None
        lat, lon, t, value = self.first if self.first is not None else (0.0, 0.0, 0.0, math.nan)
        ok = self.first is not None
        return QaFinding(
            "heading",
            "declination",
            "yellow" if ok else "red",
            self.message(),
            value=value,
            unit="deg",
            threshold=f"{MODEL}: typically within 0.5° of the true declination away from "
            "magnetic anomalies; a variation in the log or the boat file wins",
            evidence=f"no variation in HDG/HDM or RMC; {MODEL} at the boat's position and date",
            fix=(
                "applied: true heading = magnetic + deviation + declination; pin "
                "[compass] variation_deg in the boat file to override"
                if ok
                else "pin [compass] variation_deg in the boat file: the heading was dropped"
            ),
            applied=ok,
            extra={
                "model": MODEL,
                "lat": f"{lat:.5f}",
                "lon": f"{lon:.5f}",
                "utc_s": f"{t:.0f}",
                "headings": str(self.headings),
            }
            if ok
            else {"headings": "0"},
        )
