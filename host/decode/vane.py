"""Wind vane: turn the bridge's raw ``read_u16`` value into a wind direction relative to the bow.

The SparkFun/Argent vane has 8 reed switches and resistors; with the magnet between two switches both
close and the two resistors are in parallel, which gives 16 positions. The vane sits at the bottom of
a divider with a pull-up to ``vref``; the ADC reads that node against ``adc_ref``.

    >>> decode_vane(50294)          # 33 kOhm at 3.3 V with 10 kOhm pull-up: the 0 deg position
    0.0
    >>> decode_vane(65535) is None  # open circuit: far from every entry
    True

Directions are where the wind comes FROM, degrees clockwise from the bow, in (-180, 180]
(docs/CONVENTIONS.md).
"""

from __future__ import annotations

from forcemap.host.vessel.geodesy import wrap_to_180

# (vane direction in degrees, resistance in ohms), from the SparkFun SEN-15901 datasheet
DEFAULT_TABLE: tuple[tuple[float, float], ...] = (
    (0.0, 33_000.0),
    (22.5, 6_570.0),
    (45.0, 8_200.0),
    (67.5, 891.0),
    (90.0, 1_000.0),
    (112.5, 688.0),
    (135.0, 2_200.0),
    (157.5, 1_410.0),
    (180.0, 3_900.0),
    (202.5, 3_140.0),
    (225.0, 16_000.0),
    (247.5, 14_120.0),
    (270.0, 120_000.0),
    (292.5, 42_120.0),
    (315.0, 64_900.0),
    (337.5, 21_880.0),
)

ADC_FULL_SCALE = 65535
# Farther than this (read_u16 counts) from every table entry is not a vane reading: open circuit
# (full scale), short circuit (0) or a broken cable. Half the smallest gap between entries is 298.
DEFAULT_REJECT_COUNTS = 1500


def ideal_raw(
    resistance: float, vref: float = 3.3, pullup: float = 10_000.0, adc_ref: float = 3.3
) -> int:
    """The ideal ``read_u16`` value for a vane resistance in the divider."""
    volts = vref * resistance / (resistance + pullup)
    return max(0, min(ADC_FULL_SCALE, round(volts / adc_ref * ADC_FULL_SCALE)))


def raw_table(
    table=DEFAULT_TABLE, vref: float = 3.3, pullup: float = 10_000.0, adc_ref: float = 3.3
) -> list[tuple[int, float]]:
    """(ideal read_u16, direction) pairs sorted by raw value."""
    return sorted((ideal_raw(r, vref, pullup, adc_ref), deg) for deg, r in table)


def decode_vane(
    raw_u16: int,
    table=DEFAULT_TABLE,
    vref: float = 3.3,
    pullup: float = 10_000.0,
    *,
    adc_ref: float = 3.3,
    mounting_offset: float = 0.0,
    reject_counts: int = DEFAULT_REJECT_COUNTS,
) -> float | None:
    """Wind direction FROM, degrees clockwise from the bow in (-180, 180], or None if rejected.

    ``raw_u16`` is the bridge's SAMPLE ``vane_raw``. The nearest table entry wins (the same as
    classifying by midpoints between the sorted ideal values). A reading more than ``reject_counts``
    from every entry returns None. ``mounting_offset`` is the angle, clockwise from the bow, that
    the vane's 0 deg mark points to.
    """
    return VaneDecoder(
        table,
        vref,
        pullup,
        adc_ref=adc_ref,
        mounting_offset=mounting_offset,
        reject_counts=reject_counts,
    ).decode(raw_u16)


class VaneDecoder:
    """``decode_vane`` with its table precomputed, for decoding a stream of readings."""

    def __init__(
        self,
        table=DEFAULT_TABLE,
        vref: float = 3.3,
        pullup: float = 10_000.0,
        *,
        adc_ref: float = 3.3,
        mounting_offset: float = 0.0,
        reject_counts: int = DEFAULT_REJECT_COUNTS,
    ):
        self.entries = raw_table(table, vref, pullup, adc_ref)
        self.raws = [r for r, _ in self.entries]
        self.mounting_offset = mounting_offset
        self.reject_counts = reject_counts
        self.rejected = 0

    def nearest(self, raw_u16: int) -> tuple[int, float]:
        """(distance in counts, vane direction) of the nearest table entry."""
        best = min(self.entries, key=lambda e: abs(e[0] - raw_u16))
        return abs(best[0] - raw_u16), best[1]

    def decode(self, raw_u16: int) -> float | None:
        """Direction relative to the bow, or None (counted in ``rejected``)."""
        dist, deg = self.nearest(raw_u16)
        if dist > self.reject_counts:
            self.rejected += 1
            return None
        return wrap_to_180(deg + self.mounting_offset)
