"""The known effects ``bench/inject_nmea.py`` puts into a real log: a current c(t), a water level
L(t).

Each is a shape in time, measured from the log's start (tau = t - t0, seconds):

- ``tidal``: ``A cos(2 pi tau / P + phase)``, P = 44714.2 s (M2, 12.42 h) unless given;
- ``periodic``: the same with a period that must be given (a seiche: Lake Geneva's first
  longitudinal mode is about 74 min);
- ``ramp``: ``A min(tau / ramp_s, 1)``, a drift or stage that grows at a steady rate (``ramp_s``
  defaults to the whole log);
- ``step``: ``A (1 + tanh((tau - at_s) / width_s)) / 2``, a smooth change of state (a wind set-up, a
  release from a dam) around ``at_s`` (default: the middle of the log).

A current is a shape along a direction it sets TO (compass degrees, clockwise from true north): its
velocity is ``shape(tau) * (sin toward, cos toward)``, and a negative value sets the other way. It
is uniform in space (the same everywhere at one time): a tide or seiche varies over kilometres, a
race area is one place, and what a test needs is a known function of time. Its displacement is the
exact integral of the shape from the log's start, so ``d(t0) = 0``.

An effect is written ``SHAPE key=value ...`` on the command line, e.g.
``"periodic amplitude=0.15 period_s=4440 toward=30"`` or ``"step amplitude=0.6 width_s=2700"``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

import numpy as np

M2_PERIOD_S = 44714.2  # the principal lunar semidiurnal constituent, 12.4206 h
SHAPES = ("tidal", "periodic", "ramp", "step")
DEFAULT_WIDTH_S = 1800.0


@dataclass(frozen=True)
class Shape:
    """A function of time since the log's start: ``value`` (m/s or m) and its integral from 0."""

    kind: str
    amplitude: float
    period_s: float | None = None
    phase_deg: float = 0.0
    ramp_s: float | None = None
    at_s: float | None = None
    width_s: float = DEFAULT_WIDTH_S

    def __post_init__(self) -> None:
        if self.kind not in SHAPES:
            raise ValueError(f"unknown shape {self.kind!r}: expected one of {', '.join(SHAPES)}")
        if self.kind == "periodic" and self.period_s is None:
            raise ValueError("a periodic effect needs period_s (a seiche's period, in seconds)")
        if self.kind == "tidal" and self.period_s is None:
            object.__setattr__(self, "period_s", M2_PERIOD_S)
        for name in ("period_s", "ramp_s", "width_s"):
            v = getattr(self, name)
            if v is not None and not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a positive number of seconds, not {v}")
        if not math.isfinite(self.amplitude):
            raise ValueError(f"amplitude must be a number, not {self.amplitude}")

    def resolved(self, span_s: float) -> Shape:
        """The shape with the defaults that depend on the log filled in (its span)."""
        ramp = self.ramp_s if self.ramp_s is not None else max(span_s, 1.0)
        at = self.at_s if self.at_s is not None else 0.5 * span_s
        return replace(self, ramp_s=ramp, at_s=at)

    def value(self, tau: np.ndarray | float) -> np.ndarray:
        """The effect at ``tau`` seconds after the log's start (of a resolved shape)."""
        tau = np.asarray(tau, dtype=float)
        a = self.amplitude
        if self.kind in ("tidal", "periodic"):
            w = 2.0 * math.pi / self.period_s
            return a * np.cos(w * tau + math.radians(self.phase_deg))
        if self.kind == "ramp":
            return a * np.clip(tau / self.ramp_s, 0.0, 1.0)
        return a * 0.5 * (1.0 + np.tanh((tau - self.at_s) / self.width_s))

    def integral(self, tau: np.ndarray | float) -> np.ndarray:
        """The exact integral of ``value`` from 0 to ``tau`` (a current's displacement, m)."""
        tau = np.asarray(tau, dtype=float)
        a = self.amplitude
        if self.kind in ("tidal", "periodic"):
            w = 2.0 * math.pi / self.period_s
            p = math.radians(self.phase_deg)
            return a / w * (np.sin(w * tau + p) - math.sin(p))
        if self.kind == "ramp":
            r = self.ramp_s
            inside = np.clip(tau, 0.0, r)
            return a * (inside**2 / (2.0 * r) + np.clip(tau - r, 0.0, None))
        w = self.width_s

        def log_cosh(x: np.ndarray | float) -> np.ndarray:
            x = np.asarray(x, dtype=float)
            return np.logaddexp(x, -x) - math.log(2.0)

        return 0.5 * a * (tau + w * (log_cosh((tau - self.at_s) / w) - log_cosh(-self.at_s / w)))

    def describe(self) -> str:
        """The shape in words with its parameters (for reports and truth files)."""
        if self.kind in ("tidal", "periodic"):
            p = self.period_s
            return (
                f"{self.kind} {self.amplitude:+g}, period {p:g} s ({p / 60:.1f} min), "
                f"phase {self.phase_deg:g} deg"
            )
        if self.kind == "ramp":
            over = "the whole log" if self.ramp_s is None else f"{self.ramp_s:g} s"
            return f"ramp to {self.amplitude:+g} over {over}"
        at = "the middle of the log" if self.at_s is None else f"{self.at_s:g} s"
        return f"step of {self.amplitude:+g} at {at}, width {self.width_s:g} s"


@dataclass(frozen=True)
class Current:
    """A current uniform in space: a shape (m/s) along the direction it sets TO (deg true)."""

    shape: Shape
    toward_deg: float

    def resolved(self, span_s: float) -> Current:
        return replace(self, shape=self.shape.resolved(span_s))

    def unit(self) -> tuple[float, float]:
        t = math.radians(self.toward_deg)
        return math.sin(t), math.cos(t)

    def velocity(self, tau: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """(east, north) m/s at ``tau``."""
        v = self.shape.value(tau)
        ue, un = self.unit()
        return v * ue, v * un

    def offset(self, tau: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """(east, north) m the water has carried the boat since the log's start."""
        d = self.shape.integral(tau)
        ue, un = self.unit()
        return d * ue, d * un


@dataclass(frozen=True)
class Effect:
    """What to inject: a current, a water level, or both."""

    current: Current | None = None
    level: Shape | None = None

    def resolved(self, span_s: float) -> Effect:
        return Effect(
            self.current.resolved(span_s) if self.current else None,
            self.level.resolved(span_s) if self.level else None,
        )

    def is_null(self) -> bool:
        return (self.current is None or self.current.shape.amplitude == 0.0) and (
            self.level is None or self.level.amplitude == 0.0
        )


_KEYS = {f.name for f in fields(Shape)} - {"kind"}


def parse_shape(text: str, allow: tuple[str, ...] = ()) -> tuple[Shape, dict[str, float]]:
    """``"SHAPE key=value ..."`` into a Shape, and the keys in ``allow`` (e.g. ``toward``) apart.
    ValueError, in one line, on anything else."""
    words = text.replace(",", " ").split()
    if not words:
        raise ValueError("an effect needs a shape: " + ", ".join(SHAPES))
    kind, params, extra = words[0], {}, {}
    for w in words[1:]:
        key, eq, val = w.partition("=")
        if not eq:
            raise ValueError(f"{w!r}: write key=value (e.g. amplitude=0.15)")
        try:
            num = float(val)
        except ValueError:
            raise ValueError(f"{key}={val!r}: not a number") from None
        if key in allow:
            extra[key] = num
        elif key in _KEYS:
            params[key] = num
        else:
            raise ValueError(
                f"unknown key {key!r}: expected {', '.join(sorted(_KEYS | set(allow)))}"
            )
    if "amplitude" not in params:
        raise ValueError(f"{text!r}: give amplitude=VALUE")
    return Shape(kind, **params), extra


def parse_current(text: str) -> Current:
    """``"SHAPE amplitude=A toward=DEG ..."`` into a Current (``toward`` is required)."""
    shape, extra = parse_shape(text, ("toward",))
    if "toward" not in extra:
        raise ValueError(f"{text!r}: a current needs toward=DEG, the direction it sets to")
    return Current(shape, extra["toward"] % 360.0)
