"""What a decoder sees of the pipeline: one narrow interface, so decoders never import the pipeline.

Every decoder takes bytes through the same ``feed(source, t_mono_ns, t_wall_ns, data)`` and hands
what it decodes to a ``FeedContext``: logged records (``write``), navigation and readings (through
``assembler`` and ``selector``), clock mappings, fixes and its own internal errors.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol

if TYPE_CHECKING:
    from forcemap.host.fuse.assembler import SampleAssembler
    from forcemap.host.fuse.calibration import Calibration
    from forcemap.host.fuse.sources import SourceSelector
    from forcemap.host.fuse.timesync import ClockMap, UtcFix, WallClock
    from forcemap.host.log.messages import Record


class Decoder(Protocol):
    def feed(self, source: str, t_mono_ns: int, t_wall_ns: int, data: bytes) -> None: ...

    def gap(self, source: str) -> None: ...


class FeedContext(Protocol):
    """The pipeline's services a decoder may use (forcemap.host.fuse.pipeline.Pipeline has them)."""

    cal: Calibration
    assembler: SampleAssembler
    selector: SourceSelector
    wall: WallClock
    utc: UtcFix
    mav_nav: bool
    last_fix: dict[str, Any] | None

    def write(self, topic: str, wall_s: float, record: Record) -> None: ...

    def metadata(self, name: str, data: dict[str, str]) -> None: ...

    def utc_s(self, wall_s: float) -> float: ...

    def internal(self, source: str) -> None: ...

    def emit_mapping(self, mapping: ClockMap | None) -> None: ...

    def take_nav(self) -> None: ...

    def fix(self, t: float, lat: float, lon: float, alt: float, h_acc: float | None) -> None: ...

    def advance(self, t_wall: float) -> None: ...

    def source_reading(
        self,
        quantity: str,
        source: str,
        t: float,
        value: tuple,
        group: str | None = None,
        stamp: float | None = None,
    ) -> bool: ...
