"""Bytes from the instruments in, timed and compensated messages out: the daemon's core.

    pipe = Pipeline(calibration, sink)            # sink: .write(topic, log_time_ns, record), .metadata(name, data)
    pipe.feed("bridge", t_mono_ns, t_wall_ns, chunk)   # "bridge", "nmea..." (or "depth"), "mavlink"
    pipe.gap("bridge", t_wall_ns, "port closed")
    pipe.flush(); pipe.close()

One decoder per source (decode_bridge, decode_nmea, decode_mavlink) and one assembler
(forcemap.host.fuse.assembler) that makes the samples. One timeline: host wall time, from device clocks
by fitted mappings (forcemap.host.fuse.timesync), corrected to GPS UTC once the autopilot reports it.

Topics (records in forcemap.host.log.messages; log time = best estimate of the event's UTC):
raw ``/bridge/frame``, ``/bridge/hello``, ``/bridge/status``, ``/nmea/sentence``, ``/mavlink/<MSGNAME>``;
derived ``/boat/state``, ``/wind/apparent``, ``/wind/true`` (computed and instrument routes),
``/current`` (paddle wheels, both estimators), ``/current/stw`` (set and drift), ``/water/speed``,
``/depth`` (also water temperature), ``/fix`` (foxglove.LocationFix), ``/timesync``,
``/source/reading`` (every source's readings of each quantity, used or not: sources.py),
``/diagnostics`` and ``/samples`` (samples-table rows, docs/CONVENTIONS.md). Metadata:
``calibration``, ``config``, ``hello``, ``columns`` (which source fed each column), ``sources``
(per quantity: the sources, the one used and why, their disagreement and latency; at close),
``qa.*`` (quality findings: an NMEA checksum variant, the declination model, position jumps).
"""

from __future__ import annotations

import traceback
from collections import Counter
from typing import Any, Protocol

from forcemap.host.fuse import compensation as comp
from forcemap.host.fuse.assembler import SampleAssembler
from forcemap.host.fuse.bridge_feed import BridgeDecoder
from forcemap.host.fuse.calibration import Calibration
from forcemap.host.fuse.live_nav import LiveNavigation
from forcemap.host.fuse.mavlink_feed import MavDecoder
from forcemap.host.fuse.nmea_feed import NmeaDecoder
from forcemap.host.fuse.source_stats import sources_metadata
from forcemap.host.fuse.sources import SourceSelector
from forcemap.host.fuse.timesync import ClockMap, UtcFix, WallClock
from forcemap.host.log.messages import (
    ClockMapping,
    Diagnostics,
    LocationFix,
    Record,
    SourceReading,
    as_json,
)
from forcemap.host.log.qa_records import QaFinding

# longest a sample waits for the navigation streams before it goes out with what is known
HOLD_S = 3.0
DIAG_PERIOD_S = 1.0


class Sink(Protocol):
    def write(self, topic: str, log_time_ns: int, message: Record) -> None: ...

    def metadata(self, name: str, data: dict[str, str]) -> None: ...


class NullSink:
    """Discards everything; counts messages per topic (for benchmarks and tests)."""

    def __init__(self) -> None:
        self.counts: Counter[str] = Counter()

    def write(self, topic: str, log_time_ns: int, message: Record) -> None:
        self.counts[topic] += 1

    def metadata(self, name: str, data: dict[str, str]) -> None:
        self.counts["metadata:" + name] += 1


class ListSink:
    """Keeps everything in memory as JSON dicts: ``messages`` as (topic, log_time_ns, message), ``meta``."""

    def __init__(self) -> None:
        self.messages: list[tuple[str, int, dict]] = []
        self.meta: list[tuple[str, dict[str, str]]] = []

    def write(self, topic: str, log_time_ns: int, message: Record) -> None:
        self.messages.append((topic, log_time_ns, as_json(message)))

    def metadata(self, name: str, data: dict[str, str]) -> None:
        self.meta.append((name, data))

    def topic(self, name: str) -> list[dict]:
        return [m for t, _, m in self.messages if t == name]


def source_kind(source: str) -> str:
    """Which decoder reads a connection: ``bridge``, ``mavlink`` or ``nmea`` (``nmea``, ``nmea2``,
    ... and, for the sounder's port of old, ``depth``)."""
    if source == "bridge" or source.startswith("mavlink"):
        return "mavlink" if source.startswith("mavlink") else "bridge"
    if source.startswith(("nmea", "depth")):
        return "nmea"
    return ""


class Pipeline:
    """Parsing, clock alignment and compensation for the bridge, NMEA instruments and the autopilot."""

    def __init__(
        self,
        calibration: Calibration | None = None,
        sink: Sink | None = None,
        *,
        sync: str | None = None,
        config: dict[str, str] | None = None,
        diagnostics_period_s: float = DIAG_PERIOD_S,
        rate_window_s: float | None = None,
        rate_lag: bool = True,
        hold_s: float = HOLD_S,
        sample_rate_hz: float | None = None,
        sources_period_s: float | None = None,
        nmea_checksum: str = "strict",
        live_filter: bool = False,
    ) -> None:
        self.cal = cal = calibration if calibration is not None else Calibration()
        self.hold_s = hold_s
        self.sink = sink if sink is not None else NullSink()
        self.sync = sync or cal.sync
        comp.LsqGeometry([w.angle_deg for w in cal.wheels])  # fail now on a degenerate geometry
        rate_window_s = cal.rate_window_s if rate_window_s is None else rate_window_s
        self.assembler = SampleAssembler(
            cal,
            self,
            sync=self.sync,
            rate_lag_s=rate_window_s / 2 if rate_lag else 0.0,
            hold_s=hold_s,
            rate_hz=sample_rate_hz,
        )
        self.utc = UtcFix()
        self.wall = WallClock()
        self.mav_nav = False
        self.selector = SourceSelector(cal.source_priorities, cal.source_timeouts)
        # `forcemap run`: the rows' navigation from every source, causally (live_nav.py)
        self.live_nav: LiveNavigation | None = None
        if live_filter and cal.navigation == "smoothed":
            self.live_nav = LiveNavigation(
                cal.live_lag_s, remove_latency=cal.latency != "keep", quality=self.selector.quality
            )
            self.assembler.live = self.live_nav
        self.bridge = BridgeDecoder(self, rate_window_s)
        self.nmea = NmeaDecoder(self, nmea_checksum)
        self.mav = MavDecoder(self)
        self.decoders = {"bridge": self.bridge, "nmea": self.nmea, "mavlink": self.mav}
        self.last_fix: dict[str, Any] | None = None
        self.now = 0.0  # latest host wall time seen on any source
        self.counts: Counter[str] = Counter()
        self.errors: Counter[str] = Counter()
        self.last_error = ""
        self.gaps: list[dict[str, Any]] = []
        self._diag_t: float | None = None
        self._rate_ref: tuple[float, dict[str, int]] | None = None
        self.rates: dict[str, float] = {}
        self.diag_period_s = diagnostics_period_s
        # a long run records its sources every period (each rotated file gets the latest)
        self.sources_period_s = sources_period_s
        self._sources_t: float | None = None
        self.sources_report: dict[str, str] = {}  # the last ``sources`` metadata written
        self.findings: list[QaFinding] = []  # the quality findings written at close (qa.*)
        self.closed = False

        self.sink.metadata("calibration", cal.as_metadata())
        meta = {"sync": self.sync, "current_estimator": cal.current_estimator}
        meta["sample_rate_hz"] = str(sample_rate_hz or "paced by the fastest measurement")
        if self.live_nav is not None:
            meta["navigation"] = (
                f"fixed-lag filter: every source over {self.live_nav.window_s:g} s, "
                f"rows {self.live_nav.lag_s:g} s late"
            )
        if config:
            meta.update({str(k): str(v) for k, v in config.items()})
        self.sink.metadata("config", meta)

    # --- the contract ------------------------------------------------------------------------------

    def feed(self, source: str, t_mono_ns: int, t_wall_ns: int, data: bytes) -> None:
        """Bytes as read from ``source``, stamped on arrival. Never raises."""
        try:
            mono, wall = t_mono_ns * 1e-9, t_wall_ns * 1e-9
            self.wall.observe(mono, wall)
            if wall > self.now:
                self.now = wall
            decoder = self.decoders.get(source_kind(source))
            if decoder is None:
                self.errors["unknown_source"] += 1
                return
            if decoder is self.bridge:
                self.counts["bridge_bytes"] += len(data)
            decoder.feed(source, t_mono_ns, t_wall_ns, data)
            self.assembler.drain(self.now, final=False)
            self._maybe_diagnostics()
        except Exception:
            self.internal(source)

    def advance(self, t_wall: float) -> None:
        """Time has reached ``t_wall`` on a source read without bytes (a DataFlash log)."""
        if t_wall > self.now:
            self.now = t_wall
        self.assembler.drain(self.now, final=False)
        self._maybe_diagnostics()

    def gap(self, source: str, t_wall_ns: int, reason: str) -> None:
        """A source disconnected or reconnected: logged; partial frames and lines are dropped."""
        try:
            t = t_wall_ns * 1e-9
            kind = source_kind(source)
            decoder = self.decoders.get(kind)
            if decoder is not None:
                decoder.gap(source)
            event = {"t": t, "source": source, "reason": str(reason)}
            self.gaps.append(event)
            self.counts[(kind or source) + "_gaps"] += 1
            self.write("/diagnostics", t, Diagnostics(t, self.counters(), event))
        except Exception:
            self.internal(source)

    def counters(self) -> dict[str, Any]:
        """Per-source counts and rates, rejections by reason, bad CRCs, the last fix, clock fits."""
        mb = self.bridge.clock.mapping()
        mm = self.mav.clock.mapping()
        asm = self.assembler
        return {
            "bridge": {
                "bytes": self.counts["bridge_bytes"],
                **self.bridge.counters(),
                "rate_hz": self.rates.get("bridge", 0.0),
                "gaps": self.counts["bridge_gaps"],
            },
            "nmea": {
                **self.nmea.counters(),
                "rate_hz": self.rates.get("nmea", 0.0),
                "gaps": self.counts["nmea_gaps"],
            },
            "mavlink": {
                **self.mav.counters(),
                "rate_hz": self.rates.get("mavlink", 0.0),
                "gaps": self.counts["mavlink_gaps"],
            },
            "samples": {
                "emitted": asm.counts["samples"],
                "pending": len(asm.pending),
                "without_state": asm.counts["samples_without_state"],
                "without_position": asm.counts["ticks_without_position"],
                "paced_by": "bridge" if asm.bridge else (asm.pace or ""),
            },
            "sources": {
                q: {"chosen": v["chosen"], "switches": v["switches"], "n": len(v["sources"])}
                for q, v in self.selector.summary().items()
            },
            "live_filter": dict(self.live_nav.counts) if self.live_nav is not None else None,
            "last_fix": self.last_fix,
            "timesync": {
                "bridge": mb.as_message() if mb else None,
                "mavlink": mm.as_message() if mm else None,
                "utc_correction_s": self.utc.correction,
            },
            "errors": dict(self.errors),
        }

    def flush(self) -> None:
        """Emit what is complete, and samples that waited longer than ``hold_s`` for navigation."""
        try:
            self.assembler.drain(self.now, final=False)
        except Exception:
            self.internal("flush")

    def close(self) -> None:
        """Emit everything still queued with what is known, and a last /diagnostics."""
        if self.closed:
            return
        self.closed = True
        try:
            self.nmea.flush(self.now)
            self.assembler.drain(self.now, final=True)
            self._diagnostics(self.now)
            self._sources()
            self._findings()
        except Exception:
            self.internal("close")

    def _findings(self) -> None:
        """The decoders' quality findings (checksum variant, declination, position jumps) as
        ``qa.*`` metadata records (forcemap.host.log.qa_records)."""
        self.findings = self.nmea.findings()
        for f in self.findings:
            self.sink.metadata(f.name, f.to_metadata())

    # --- for the decoders and the assembler --------------------------------------------------------

    def internal(self, source: str) -> None:
        """Count a bug met on ``source`` (the traceback is kept in ``last_error``)."""
        self.errors[source + "_internal"] += 1
        self.last_error = traceback.format_exc(limit=3)

    def _log_ns(self, wall_s: float) -> int:
        return max(0, int(round(self.utc.to_utc(wall_s) * 1e9)))

    def utc_s(self, wall_s: float) -> float:
        """The log time of host wall time ``wall_s``, in UNIX seconds."""
        return self._log_ns(wall_s) * 1e-9

    def write(self, topic: str, wall_s: float, record: Record) -> None:
        """Log ``record`` on ``topic`` at the UTC of host wall time ``wall_s``."""
        self.sink.write(topic, self._log_ns(wall_s), record)

    def metadata(self, name: str, data: dict[str, str]) -> None:
        self.sink.metadata(name, data)

    def source_reading(
        self,
        quantity: str,
        source: str,
        t: float,
        value: tuple,
        group: str | None = None,
        stamp: float | None = None,
    ) -> bool:
        """Log a reading of ``quantity`` from ``source``; True if it is the chosen source's
        (``group``: the instrument it belongs to, see SourceSelector.accept; ``stamp``: the UTC
        its own time field names, for the live filter)."""
        sel = self.selector
        used = sel.accept(quantity, source, t, value, group)
        self.write("/source/reading", t, SourceReading(quantity, source, list(value), used))
        if self.live_nav is not None:
            t_fix = None if stamp is None else t + (stamp - self.utc_s(t))
            self.live_nav.add(quantity, source, t, value, used, group, t_fix)
        if used and quantity in ("position", "heading"):
            self.assembler.state.source_interval(quantity, sel.tracks[quantity][source].interval)
        return used

    def emit_mapping(self, mapping: ClockMap | None) -> None:
        if mapping is not None:
            self.write("/timesync", self.now, ClockMapping(**mapping.as_message(), kind="device"))

    def take_nav(self) -> None:
        """The autopilot gives navigation: NMEA's is dropped and ignored from now on."""
        if not self.mav_nav:
            self.mav_nav = True
            self.assembler.state.reset()
            if self.live_nav is not None:
                self.live_nav.autopilot = True

    def fix(self, t: float, lat: float, lon: float, alt: float, h_acc: float | None) -> None:
        log_ns = self._log_ns(t)
        self.last_fix = {"t": log_ns * 1e-9, "lat": lat, "lon": lon}
        self.sink.write("/fix", log_ns, LocationFix.at(log_ns, lat, lon, alt, h_acc))

    # --- diagnostics -------------------------------------------------------------------------------

    def _maybe_diagnostics(self) -> None:
        if self._diag_t is None:
            self._diag_t = self.now
            self._rate_ref = (self.now, self._totals())
            return
        if self.now - self._diag_t >= self.diag_period_s:
            self._diagnostics(self.now)

    def _totals(self) -> dict[str, int]:
        return {
            "bridge": self.bridge.n_frames,
            "nmea": self.nmea.parser.lines,
            "mavlink": sum(self.mav.packets.messages.values()),
        }

    def _diagnostics(self, t: float) -> None:
        tot = self._totals()
        if self._rate_ref is not None:
            t0, ref = self._rate_ref
            if t > t0:
                self.rates = {k: (tot[k] - ref[k]) / (t - t0) for k in tot}
        self._rate_ref = (t, tot)
        self._diag_t = t
        self.write("/diagnostics", t, Diagnostics(t, self.counters()))
        if self.sources_period_s is not None:
            if self._sources_t is None:
                self._sources_t = t
            elif t - self._sources_t >= self.sources_period_s:
                self._sources_t = t
                self._sources()

    def _sources(self) -> None:
        """The ``sources`` metadata: each source's disagreement with the one used, and latency."""
        if self.selector.chosen:
            self.sources_report = sources_metadata(self.selector)
            self.sink.metadata("sources", self.sources_report)
