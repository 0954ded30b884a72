"""A single-beam sounder that locks and unlocks on the bottom, with the truth of every ping (issue 61).

Past its range, and in rough water, a sounder does not lose the bottom cleanly: it locks and unlocks.
Its pings come in episodes, a Markov chain of the sounder's state, each episode a run of pings of one
kind:

- **held**: the bottom, with the sounder's noise and the heave of a rough sea;
- **scatter**: returns from anywhere in the water column, uniform from SCATTER_MIN_M to its range;
- **false bottom**: a return from a layer at a fraction of the depth (a thermocline, a school of
  fish, aerated water under the hull), the fraction drawn once per episode from FALSE_FRACTION, the
  episode FALSE_RUN pings long on average;
- **second echo**: the pulse reflected by the bottom, the surface and the bottom again, at twice the
  depth.

Past its range (the bed deeper than ``range_m``) the sounder holds the bottom in short runs (HELD_PAST
pings long on average) between longer unlocked episodes (UNLOCKED_PAST), most of them scatter, some a
false bottom: plausible readings come in short runs between the scatter. Within its range, a rough sea
(``sea``, 0 calm to 1 rough) now and then makes it lose the bottom for a few pings (ROUGH_EPISODES per
ping at sea 1, UNLOCKED_ROUGH long): a second echo, a false bottom, or a spike of scatter.

Each ping's truth is kept: its time, the true depth below the transducer, the reading sent, its kind,
and whether the bed was past the sounder's range (the stretch where it lost lock).
"""

from __future__ import annotations

import random
from dataclasses import dataclass, field

HELD, SCATTER, FALSE_BOTTOM, SECOND_ECHO = "held", "scatter", "false_bottom", "second_echo"
KINDS = (HELD, SCATTER, FALSE_BOTTOM, SECOND_ECHO)
SCATTER_MIN_M = 4.0
FALSE_FRACTION = (0.3, 0.7)
HELD_PAST = 4.0  # pings: the mean run of the bottom held past the range
UNLOCKED_PAST = 8.0  # pings: the mean episode without it
PAST_KINDS = ((SCATTER, 0.75), (FALSE_BOTTOM, 0.25))
ROUGH_EPISODES = 0.015  # episodes started per ping within range, at sea 1
UNLOCKED_ROUGH = 4.0  # pings: their mean length
ROUGH_KINDS = ((SECOND_ECHO, 0.5), (FALSE_BOTTOM, 0.3), (SCATTER, 0.2))
FALSE_RUN = 10.0  # pings: a false bottom's mean episode (a layer holds the sound a while)
HEAVE_M = 0.15  # the heave's sd at sea 1


@dataclass
class Ping:
    """One ping's truth."""

    t: float  # s since the run's start
    depth: float  # the true depth below the transducer
    reading: float  # what the sounder sent (below the transducer)
    kind: str
    past: bool  # the bed deeper than the sounder's range


@dataclass
class LockModel:
    """The sounder's lock on the bottom: ``range_m`` (its range), ``sea`` (0 calm to 1 rough)."""

    range_m: float = 90.0
    sea: float = 1.0
    seed: int = 0
    pings: list[Ping] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.rng = random.Random(self.seed)
        self.kind = HELD
        self.left = 0  # pings left in the current episode
        self.fraction = 0.5

    def _episode(self, past: bool) -> None:
        """The next episode, its kind and length, given where the bed is."""
        r = self.rng
        if past:
            if self.kind == HELD:
                self.kind = _draw(r, PAST_KINDS)
                self.left = _length(r, UNLOCKED_PAST)
            else:
                self.kind, self.left = HELD, _length(r, HELD_PAST)
        elif self.kind != HELD or r.random() >= ROUGH_EPISODES * self.sea:
            self.kind, self.left = HELD, 1
        else:
            self.kind, self.left = _draw(r, ROUGH_KINDS), _length(r, UNLOCKED_ROUGH)
        if self.kind == FALSE_BOTTOM:
            self.fraction = r.uniform(*FALSE_FRACTION)
            self.left = _length(r, FALSE_RUN)

    def reading(self, depth: float, noisy: float, t: float) -> tuple[float, str]:
        """The reading (m below the transducer) for a bed ``depth`` below it that a held sounder would
        read as ``noisy`` (its own noise, its tilt), and its kind."""
        past = depth > self.range_m
        if self.pings and self.pings[-1].past != past:
            # past the range it loses the bottom at once; back within it, it locks at once
            self.kind, self.left = HELD, 0 if past else 1
        if self.left <= 0:
            self._episode(past)
        self.left -= 1
        r = self.rng
        heave = r.gauss(0.0, HEAVE_M * self.sea)
        if self.kind == SCATTER:
            d = r.uniform(SCATTER_MIN_M, self.range_m)
        elif self.kind == FALSE_BOTTOM:
            d = self.fraction * depth + heave
        elif self.kind == SECOND_ECHO:
            d = 2.0 * noisy + 2.0 * heave
        else:
            d = noisy + heave
        d = max(d, 0.1)
        self.pings.append(Ping(t, depth, d, self.kind, past))
        return d, self.kind

    def counts(self) -> dict[str, int]:
        """Pings of each kind."""
        return {k: sum(p.kind == k for p in self.pings) for k in KINDS}


def _draw(r: random.Random, kinds: tuple[tuple[str, float], ...]) -> str:
    x, acc = r.random(), 0.0
    for kind, share in kinds:
        acc += share
        if x < acc:
            return kind
    return kinds[-1][0]


def _length(r: random.Random, mean: float) -> int:
    """A geometric run of pings with this mean (at least one)."""
    n = 1
    while r.random() > 1.0 / mean:
        n += 1
    return n
