"""The finding rule's null, built from the survey at hand: what a covariate with the candidate's structure, but no
link to the target, gains.

The candidate's series is shifted circularly in time (sample k takes the value of sample k + s, wrapping at
the end). The shifted series keeps the candidate's values, their autocorrelation along the track and their
steps at the turns, but sits at other places and times, so whatever it gains is what the model's extra
flexibility buys by chance on this survey. A candidate is a finding only if it gains more than every shift.

Cost: a null refit keeps the candidate's fitted hyperparameters (only the new features' cross products, the
fold solves and the weights are computed), a fraction of the candidate's own evaluation.
"""

from __future__ import annotations

import numpy as np

# the shifts, as fractions of the survey: far from 0 and from each other, so each is a different null
SHIFTS = (0.2, 0.4, 0.6, 0.8)


def null_gains(ev, name: str, values: np.ndarray, theta: np.ndarray) -> list[float]:
    """Blocked-CV gains of the candidate's term on circularly time-shifted copies of its series."""
    n = len(values)
    gains = []
    for frac in SHIFTS:
        shifted = np.roll(values, int(round(frac * n)))
        model = ev.with_fixed_hypers(name, shifted, theta)
        gains.append(float(ev.blocked(model)[1]))
    return gains
