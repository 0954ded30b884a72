"""The real logs with a known effect that tests and benches share (tests/real_cases.py builds them).

Each injected case is a real log of tests/data/real with one effect put in by
``bench/inject_nmea.py``, and names the clean log it is compared with. The parameters are physically
plausible for the place (and are issue 36's):

- ``geneva_seiche``: Lake Geneva off Geneva (Irene, 2014-06-27, 2.4 h, the longer Geneva race), the
  lake's first longitudinal seiche (Merian: about 74 min) as a current of +-0.15 m/s along the Petit
  Lac's axis (030/210 deg);
- ``lake_drift``: Lake Geneva off Lausanne (Irene, 2008-08-20, 1.7 h), a wind drift that builds
  steadily to 0.2 m/s over the race, along the Grand Lac's axis toward 250 deg (a bise);
- ``fjord_tide``: the Flensburg Fjord race (Irene, 2013-08-03, 3.9 h), an M2 tidal stream of +-0.26
  m/s along the fjord's axis there (050/230 deg), phase 30 deg so that it turns mid-race;
- ``fjord_level``: the same race, the water rising 0.6 m (a smooth step, 45 min wide, mid-race: a
  Baltic wind set-up);
- ``plaka_level``: the western Gulf of Finland (Plaka, 60 05 N 23 32 E, 4.1 h, a sounder in shallow
  water, no heading), the water rising 0.6 m as in ``fjord_level`` (the Gulf's wind set-ups are the
  Baltic's largest). The fjord's rise is seen at one harbour passed at the start and at the end; this
  boat comes back over the same water while the water rises, where revisits can show a level;
- ``fjord_seiche``: the same race, a seiche of the inner fjord (Merian for a basin open at one end, 12 km
  long and 12 m deep: 4 L / sqrt(g h), about 74 min) as a current of +-0.25 m/s along its axis (050/230
  deg). Stronger than the lake's: on Geneva's 85 crossings the revisits cannot see a +-0.15 m/s seiche
  beside the race's own changes (bench/RESULTS.md, "What the revisits see of an injected current"); the
  fjord race's 363 crossings at +-0.25 m/s test that the judge names a period where the track can show one.

The ``UNSEEN`` cases put the same kinds of effect into the real logs that no test case and no threshold
was built on (``python bench/bench_inject.py --unseen --diagnose``; bench/RESULTS.md, "On logs no case
was built on"):

- ``flensburg31_tide``, ``flensburg31_level``: Irene's other Flensburg day (2013-07-31, 1.1 h, the log
  whose bus sums its checksums over the address only), the fjord's M2 stream as ``fjord_tide`` and the
  water rising 0.6 m in a 15-min-wide step mid-log;
- ``paccup_ebb``: the start of the 2008 Pacific Cup off San Francisco (37 min), an ebb building steadily
  to 0.3 m/s toward 250 deg (out through the Golden Gate) over the log;
- ``neuse_level``: Neutron Dance on the Neuse River, North Carolina (1.7 h, no heading), the water rising
  0.6 m in a 20-min-wide step (a wind set-up of that estuary's size); its track comes back at two places.

A current is uniform in space (bench/inject_effects.py). The ``clean`` cases are the repository's
real NMEA logs as they are (the null cases); ``sfbay`` is a real flood tide, not injected.
"""

from __future__ import annotations

from dataclasses import dataclass

from bench.inject_effects import Current, Effect, Shape

GENEVA = "nmea/irene/irene_2014-06-27_geneva.nmea"
GENEVA_2008 = "nmea/irene/irene_2008-08-20_geneva.nmea"
FJORD = "nmea/irene/irene_2013-08-03_flensburg.nmea"
SFBAY = "nmea/sfbay/swift-day1.nmea.gz"
PLAKA = "nmea/plaka.log"
# the one log whose bus computes its checksums over the address only (its PROVENANCE.md)
LENIENT = ("nmea/irene/irene_2013-07-31_flensburg_checksums.nmea",)


@dataclass(frozen=True)
class Case:
    """A real log (a path under tests/data/real), the effect put into it (None: as recorded) and
    the clean log it is compared with."""

    source: str
    effect: Effect | None = None
    checksum: str = "strict"

    @property
    def clean(self) -> str:
        return self.source

    @property
    def toward_deg(self) -> float | None:
        if self.effect is None or self.effect.current is None:
            return None
        return self.effect.current.toward_deg


INJECTED = {
    "geneva_seiche": Case(GENEVA, Effect(Current(Shape("periodic", 0.15, period_s=4440.0), 30.0))),
    "lake_drift": Case(GENEVA_2008, Effect(Current(Shape("ramp", 0.2), 250.0))),
    "fjord_tide": Case(FJORD, Effect(Current(Shape("tidal", 0.26, phase_deg=30.0), 50.0))),
    "fjord_level": Case(FJORD, Effect(level=Shape("step", 0.6, width_s=2700.0))),
    "plaka_level": Case(PLAKA, Effect(level=Shape("step", 0.6, width_s=2700.0))),
    "fjord_seiche": Case(FJORD, Effect(Current(Shape("periodic", 0.25, period_s=4440.0), 50.0))),
}

FLENSBURG_31 = LENIENT[0]
UNSEEN = {
    "flensburg31_tide": Case(
        FLENSBURG_31, Effect(Current(Shape("tidal", 0.26, phase_deg=30.0), 50.0)), "lenient"
    ),
    "flensburg31_level": Case(FLENSBURG_31, Effect(level=Shape("step", 0.6, width_s=900.0)), "lenient"),
    "paccup_ebb": Case("nmea/PacCupStartNMEA.txt", Effect(Current(Shape("ramp", 0.3), 250.0))),
    "neuse_level": Case("nmea/NeutronDance.log", Effect(level=Shape("step", 0.6, width_s=1200.0))),
}


def case(name: str) -> Case:
    """An injected case by name, or a real log as recorded by its path under tests/data/real."""
    known = {**INJECTED, **UNSEEN}
    if name in known:
        return known[name]
    return Case(name, None, "lenient" if name in LENIENT else "strict")
