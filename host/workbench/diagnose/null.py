"""The finding rule's null, built from the survey at hand: what a covariate with the candidate's structure, but no
link to the target, gains.

A covariate's series is shifted circularly in time (sample k takes the value of sample k + s, wrapping at the
end). The shifted series keeps the candidate's values, their autocorrelation along the track and their steps
at the turns, but sits at other places and times, so whatever it gains is what the model's extra flexibility
buys by chance on this survey. Time itself cannot be shifted that way (a shifted clock is the same clock plus
a constant, split at one point, and a GP in it fits the same time effect), so for `t` whole spatial blocks
swap their stretches of the series instead: each block gets another block's times, in their order.

Cost: a null refit keeps the candidate's fitted hyperparameters (only the new features' cross products, the
fold solves and the weights are computed), a fraction of the candidate's own evaluation.
"""

from __future__ import annotations

import numpy as np

# a finding's blocked-CV error must be at least this much below its best null's
NULL_MARGIN = 0.05
# the shifts, as fractions of the survey: far from 0 and from each other, so each is a different null
SHIFTS = (0.2, 0.4, 0.6, 0.8)


def time_shifted(values: np.ndarray, frac: float) -> np.ndarray:
    return np.roll(values, int(round(frac * len(values))))


def block_swapped(values: np.ndarray, blocks: np.ndarray, seed: int) -> np.ndarray:
    """Each spatial block takes another block's stretch of the series (repeated or cut to its length)."""
    rng = np.random.default_rng(seed)
    nb = int(blocks.max()) + 1
    members = [np.flatnonzero(blocks == b) for b in range(nb)]
    order = rng.permutation(nb)
    out = values.copy()
    for b, src in zip(range(nb), order, strict=True):
        idx, take = members[b], members[src]
        if len(idx) and len(take):
            out[idx] = values[take[np.arange(len(idx)) % len(take)]]
    return out


def null_series(name: str, values: np.ndarray, blocks: np.ndarray) -> list[np.ndarray]:
    if name == "t":
        return [block_swapped(values, blocks, seed) for seed in range(len(SHIFTS))]
    return [time_shifted(values, frac) for frac in SHIFTS]


def null_gains(ev, name: str, values: np.ndarray, theta: np.ndarray) -> list[float]:
    """Blocked-CV gains of the candidate's term on its null copies, its hyperparameters kept."""
    gains = []
    for copy in null_series(name, values, ev.blocks):
        model = ev.with_fixed_hypers(name, copy, theta)
        gains.append(float(ev.blocked(model)[1]))
    return gains


def beats_null(gain: float, nulls: list[float]) -> bool:
    """The candidate's error must be at least NULL_MARGIN below the best null's: beating chance by a hair is
    chance."""
    return (1.0 - gain) <= (1.0 - NULL_MARGIN) * (1.0 - max(nulls, default=0.0))
