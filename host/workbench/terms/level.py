"""The water level as a term (`water_level`): the water surface's level as a smooth function of time,
seen where the track crosses or revisits itself. Reading a gauge and reducing soundings to its datum are
`depth/water_level.py`'s."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.terms.base import TermSpec
from forcemap.host.workbench.terms.gp import HilbertGPTerm

# the water level changes over tens of minutes at the fastest (a tide, a flood wave): a shorter lengthscale
# would let it take the bed's detail along the track
WATER_LEVEL_MIN_LENGTHSCALE_S = 600.0


class WaterLevelTerm(HilbertGPTerm):
    """The water surface's level as a smooth function of time (`water_level`): an RBF GP in `t` whose
    lengthscale is at least WATER_LEVEL_MIN_LENGTHSCALE_S. Every sounding is deeper by the level at its time;
    the survey tells the level from the bed where the track crosses or revisits itself."""

    kind = "water_level"
    in_time = True
    is_level = True

    def __init__(self, n_basis: int | None = None) -> None:
        super().__init__(("t",), "rbf", n_basis, dims=1)

    def describe(self) -> str:
        return "water_level"

    def setup(self, Z):
        super().setup(Z)
        self.l_min = max(self.l_min, min(WATER_LEVEL_MIN_LENGTHSCALE_S, 0.25 * self.l_max))

    def level_features(self, t: np.ndarray, t0: float | None) -> np.ndarray:
        return self.features(np.asarray(t, float)[:, None])


def parse_water_level(args: list[str] | None, text: str, is_circular: Callable[[str], bool]) -> TermSpec:
    """`water_level`, alone."""
    if args is not None:
        raise WorkbenchError(f"'{text}': write water_level alone (or --water-level GAUGE.csv for a gauge)")
    return TermSpec("water_level", ("t",), text="water_level")
