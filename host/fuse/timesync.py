"""Device clocks to the host timeline: robust offset+drift fits per boot, and GPS UTC on top."""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from statistics import median
from typing import Any


@dataclass(frozen=True)
class ClockMap:
    """host_s = device_s + offset_s + drift * (device_s - ref_device_s), valid for one epoch."""

    source: str
    epoch: str
    offset_s: float
    drift: float
    ref_device_s: float
    points: int
    span_s: float

    def to_host(self, device_s: float) -> float:
        return device_s + self.offset_s + self.drift * (device_s - self.ref_device_s)

    def as_message(self) -> dict[str, Any]:
        return {
            "source": self.source,
            "epoch": self.epoch,
            "offset_s": self.offset_s,
            "drift_ppm": self.drift * 1e6,
            "ref_device_s": self.ref_device_s,
            "points": self.points,
            "span_s": self.span_s,
        }


class ClockFit:
    """Lower-envelope line through (device, host - device) points of one epoch.

    Transport latency is never negative, so the mapping is the line under the points: the minimum of
    host - device in each ``bin_s`` of device time, least squares through those minima over the last
    ``window_s``, then lowered to touch the lowest one. Drift is fitted once the minima span
    ``min_drift_span_s`` and clamped to ``max_drift`` (1 %: far beyond any crystal, but an accelerated
    simulator's virtual clock can run that far off).
    """

    def __init__(
        self,
        bin_s: float = 5.0,
        window_s: float = 600.0,
        min_drift_span_s: float = 60.0,
        max_drift: float = 1e-2,
    ) -> None:
        self.bin_s = bin_s
        self.window_s = window_s
        self.min_drift_span_s = min_drift_span_s
        self.max_drift = max_drift
        self.bins: deque[tuple[float, float]] = deque()  # closed bins: (device_s, min host-device)
        self._open: tuple[float, float] | None = None
        self._open_start = 0.0
        self.offset = 0.0
        self.drift = 0.0
        self.ref = 0.0
        self.points = 0
        self.first: float | None = None
        self.last: float | None = None

    def residual(self, device_s: float, host_s: float) -> float:
        """How far above the current line a point lies (the latency, if the fit is right)."""
        return host_s - device_s - self.offset - self.drift * (device_s - self.ref)

    def add(self, device_s: float, host_s: float) -> bool:
        """Add a point; True if the mapping changed."""
        y = host_s - device_s
        self.points += 1
        if self.first is None:
            self.first = device_s
            self.ref = device_s
            self.offset = y
            self._open, self._open_start = (device_s, y), device_s
            self.last = device_s
            return True
        self.last = device_s
        changed = False
        if device_s - self._open_start >= self.bin_s:
            self.bins.append(self._open)
            while self.bins and device_s - self.bins[0][0] > self.window_s:
                self.bins.popleft()
            self._open, self._open_start = (device_s, y), device_s
            changed = self._refit()
        elif y < self._open[1]:
            self._open = (device_s, y)
        if self.residual(device_s, host_s) < -1e-6:
            changed = self._refit() or changed
        return changed

    def _refit(self) -> bool:
        pts = list(self.bins)
        if self._open is not None:
            pts.append(self._open)
        n = len(pts)
        if n == 0:
            return False
        if n < 3 or pts[-1][0] - pts[0][0] < self.min_drift_span_s:
            drift, ref, off = 0.0, pts[-1][0], min(p[1] for p in pts)
        else:
            mx = sum(p[0] for p in pts) / n
            my = sum(p[1] for p in pts) / n
            sxx = sum((p[0] - mx) ** 2 for p in pts)
            sxy = sum((p[0] - mx) * (p[1] - my) for p in pts)
            drift = max(-self.max_drift, min(self.max_drift, sxy / sxx if sxx > 0 else 0.0))
            ref = pts[-1][0]
            off = min(p[1] - drift * (p[0] - ref) for p in pts)
        changed = (
            abs(off - self.offset - self.drift * (ref - self.ref)) > 1e-5 or drift != self.drift
        )
        self.offset, self.drift, self.ref = off, drift, ref
        return changed

    def to_host(self, device_s: float) -> float:
        return device_s + self.offset + self.drift * (device_s - self.ref)


class SourceClock:
    """One source's device clock across epochs (boots, reboots, clock jumps).

    A new epoch starts when the epoch key changes (a bridge boot id), when device time goes back by
    more than ``back_s`` (an autopilot reboot restarts ``time_boot_ms``), or when points arrive more
    than ``jump_s`` before a settled line for ``jump_points`` in a row (the device clock stepped
    ahead); fewer such points are outliers and left out of the fit. Points more than ``jump_s``
    after the line are left out: a reader that stalled (a busy host, an accelerated simulator on a
    loaded machine) makes them, and its backlog drains; only if they stay late for ``late_s`` of
    device time does a new epoch start. A young fit takes every point (its line only comes down).
    ``observe`` reports the mapping (for logging) at a new epoch, when it moved by more than
    ``report_s`` at the current time since the last report (at most every ``report_min_s``), and at
    least every ``report_every_s`` of device time.
    """

    def __init__(
        self,
        name: str,
        back_s: float = 1.0,
        jump_s: float = 1.0,
        jump_points: int = 20,
        late_s: float = 120.0,
        report_s: float = 1e-3,
        report_every_s: float = 60.0,
        report_min_s: float = 5.0,
        **fit_kw: float,
    ) -> None:
        self.name = name
        self.back_s = back_s
        self.jump_s = jump_s
        self.jump_points = jump_points
        self.late_s = late_s
        self._late_since: float | None = None
        self.fit_kw = fit_kw
        self.fit: ClockFit | None = None
        self.key: Any = None
        self.epochs = 0
        self._off_line = 0
        self.resets = 0
        self.report_s = report_s
        self.report_every_s = report_every_s
        self.report_min_s = report_min_s
        self._reported: ClockMap | None = None
        self._reported_at = 0.0

    @property
    def epoch(self) -> str:
        return f"{self.key}#{self.epochs}" if self.key is not None else f"#{self.epochs}"

    def _new(self, key: Any) -> None:
        if self.fit is not None:
            self.resets += 1
        self.key = key
        self.epochs += 1
        self.fit = ClockFit(**self.fit_kw)
        self._off_line = 0
        self._late_since = None

    def observe(
        self, device_s: float, host_s: float, key: Any = None
    ) -> tuple[float, ClockMap | None]:
        """Add a point; returns (host time of ``device_s``, the ClockMap if it is to be reported)."""
        fit = self.fit
        if (
            fit is None
            or key != self.key
            or (fit.last is not None and device_s < fit.last - self.back_s)
        ):
            self._new(key)
        elif fit.points >= 2 * self.jump_points:
            r = fit.residual(device_s, host_s)
            if r > self.jump_s:
                # late by more than jump_s: a stalled reader, whose backlog drains. A device clock
                # that steps back is caught above and the host side is monotonic, so only a
                # device clock that runs slow beyond max_drift keeps points late for long.
                self._off_line = 0
                if self._late_since is None:
                    self._late_since = device_s
                if device_s - self._late_since < self.late_s:
                    return fit.to_host(device_s), None
                self._new(key)
            elif r < -self.jump_s:
                # early by more than jump_s: impossible for latency, so the device clock stepped
                # ahead; an outlier (a glitch) until jump_points of them in a row
                self._off_line += 1
                if self._off_line < self.jump_points:
                    return fit.to_host(device_s), None
                self._new(key)
            else:
                self._off_line = 0
                self._late_since = None
        changed = self.fit.add(device_s, host_s)
        return self.fit.to_host(device_s), self._report(device_s) if changed else None

    def _report(self, device_s: float) -> ClockMap | None:
        """The mapping if it is new, moved by more than ``report_s`` here, or is due."""
        m = self.mapping()
        last = self._reported
        since = device_s - self._reported_at
        if (
            last is None
            or last.epoch != m.epoch
            or (
                abs(last.to_host(device_s) - m.to_host(device_s)) > self.report_s
                and since >= self.report_min_s
            )
            or since >= self.report_every_s
        ):
            self._reported, self._reported_at = m, device_s
            return m
        return None

    def to_host(self, device_s: float) -> float | None:
        return None if self.fit is None else self.fit.to_host(device_s)

    def mapping(self) -> ClockMap | None:
        f = self.fit
        if f is None:
            return None
        span = (f.last or 0.0) - (f.first or 0.0)
        return ClockMap(self.name, self.epoch, f.offset, f.drift, f.ref, f.points, span)


class UtcFix:
    """GPS UTC versus the host timeline, from SYSTEM_TIME once ``time_unix_usec`` is set.

    ``correction`` (seconds) is added to host wall times to get UTC: the median of the last ``n``
    differences between GPS UTC and the host time of the same autopilot instant.
    """

    def __init__(self, n: int = 31, report_s: float = 5e-3) -> None:
        self.diffs: deque[float] = deque(maxlen=n)
        self.report_s = report_s
        self.correction: float | None = None
        self._reported: float | None = None
        self._far = 0

    def observe(self, utc_s: float, host_wall_s: float) -> bool:
        """Add one pair; True when the correction moved by more than ``report_s`` (to log it)."""
        d = utc_s - host_wall_s
        if self.diffs and abs(d - median(self.diffs)) > 1.0:
            self._far += 1
            if self._far < 3:
                return False  # one odd SYSTEM_TIME
            self.diffs.clear()  # three in a row: the host clock was stepped meanwhile
        self._far = 0
        self.diffs.append(d)
        new = median(self.diffs)
        moved = self._reported is None or abs(new - self._reported) > self.report_s
        self.correction = new
        if moved:
            self._reported = new
        return moved

    def to_utc(self, host_wall_s: float) -> float:
        return host_wall_s + (self.correction or 0.0)


class WallClock:
    """Host monotonic to host wall time: the latest (wall - monotonic) seen on arriving chunks."""

    def __init__(self) -> None:
        self.offset: float | None = None

    def observe(self, mono_s: float, wall_s: float) -> None:
        self.offset = wall_s - mono_s

    def to_wall(self, mono_s: float) -> float:
        return mono_s + (self.offset or 0.0)
