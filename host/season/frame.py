"""The season's common frame: which logs belong to one river (their tracks overlap), the shared reference
point, and the fixed bases of the maps, chosen from the logs' footprints before the statistics pass."""

from __future__ import annotations

import numpy as np
from forcemap.host.season.tasks import Footprint, Frame, Rejected
from forcemap.host.vessel.geodesy import LocalFrame
from forcemap.host.workbench.terms.gp import HilbertGPTerm

# boxes closer than this still count as the same reach (GPS scatter, a survey of the bank next door)
OVERLAP_SLACK_M = 50.0


def _boxes(fps: list[Footprint], lat0: float, lon0: float) -> np.ndarray:
    out = []
    for f in fps:
        x, y = LocalFrame(lat0, lon0).to_local(np.array(f.lat), np.array(f.lon))
        out.append((x.min(), x.max(), y.min(), y.max()))
    return np.array(out)


def _components(boxes: np.ndarray) -> list[list[int]]:
    """Groups of boxes linked by overlaps (union-find)."""
    parent = list(range(len(boxes)))

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    s = OVERLAP_SLACK_M
    for i in range(len(boxes)):
        for j in range(i + 1, len(boxes)):
            a, b = boxes[i], boxes[j]
            if a[0] - s <= b[1] and b[0] - s <= a[1] and a[2] - s <= b[3] and b[2] - s <= a[3]:
                parent[root(i)] = root(j)
    groups: dict[int, list[int]] = {}
    for i in range(len(boxes)):
        groups.setdefault(root(i), []).append(i)
    return sorted(groups.values(), key=lambda g: (-len(g), g[0]))


def choose_frame(
    fps: list[Footprint], n_basis: int, wind_basis: int
) -> tuple[Frame, list[Footprint], list[Rejected]]:
    """The largest group of overlapping logs is the season; the others are refused, one line each."""
    lat0 = float(np.median([0.5 * sum(f.lat) for f in fps]))
    lon0 = float(np.median([0.5 * sum(f.lon) for f in fps]))
    groups = _components(_boxes(fps, lat0, lon0))
    keep = sorted(groups[0])
    rejected = []
    for g in groups[1:]:
        for i in g:
            f = fps[i]
            x, y = LocalFrame(lat0, lon0).to_local(
                np.array([0.5 * sum(f.lat)]), np.array([0.5 * sum(f.lon)])
            )
            rejected.append(
                Rejected(
                    f.path,
                    f"{f.path}: its track does not overlap the season's other surveys "
                    f"({np.hypot(x[0], y[0]) / 1000:.1f} km from their centre): another river? left out",
                )
            )
    acc = [fps[i] for i in keep]
    lat0 = float(np.median([0.5 * sum(f.lat) for f in acc]))
    lon0 = float(np.median([0.5 * sum(f.lon) for f in acc]))
    b = _boxes(acc, lat0, lon0)
    corners = np.array([(x, y) for x0, x1, y0, y1 in b for x in (x0, x1) for y in (y0, y1)])
    space = HilbertGPTerm(("position",), "matern32", n_basis=n_basis, dims=2)
    wind = HilbertGPTerm(("position",), "matern32", n_basis=wind_basis, dims=2)
    for term in (space, wind):
        term.setup(corners)
    extent = (
        float(b[:, 0].min()),
        float(b[:, 1].max()),
        float(b[:, 2].min()),
        float(b[:, 3].max()),
    )
    return Frame(lat0, lon0, space, wind, extent), acc, rejected
