"""The tide as a subordinate station of a reference current (`tide(reference)`, `tide(reference, position)`).

With a reference current (`--reference-current FILE`: a station's harmonic constants or predicted series,
host/vessel/reference_current.py) every place is a subordinate station of its reference station: the
current there is `ratio(x) r(t - offset(x))` along the station's flood axis, with r the station's
prediction. For offsets short beside the tide's period that is linear in two features,

    ratio r(t - offset) = a r(t) + b r'(t) / w,   ratio = hypot(a, b),   offset = -atan2(b, a) / w

(w: M2's angular frequency; exact for one constituent, whatever the offset below half its period). The
term's features are r and r'/w (in units of r's spread over the survey), uniform and, in the spatial form,
times a small reduced-rank GP basis in position: a and b are smooth maps, and beyond the data's box the
spatial part is zero (the place keeps the survey's relation). Where the record holds enough of both the
flood and the ebb (`supports_split`), both features again signed by the tide's sense give the two their
own relations (flood c + d, ebb c - d, the difference with its own prior variance); a record of one flood,
or of a neap's brief one, relates both alike. Every prior sd is bounded (MAX_DEPARTURE_SD): the weights
are departures from the station (targets/reference_part.py), not a free fit.

The term carries no reference of its own: its input `reference` is each row's station prediction and rate
(`survey/reference.py`), so it predicts at any time the reference predicts, carrying the reference's
spring and neap, its diurnal inequality and every constituent a short record cannot separate (they are
inferred from the reference, as the ratio and offset say). A vector with it is modelled along each
place's station's flood axis (`along_reference`); targets/reference_part.py fits the relation first and
the map of what is left after it.
"""

from __future__ import annotations

import math

import numpy as np
from forcemap.host.vessel import tides
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.terms.base import Hyper, Term, TermSpec, span_words
from forcemap.host.workbench.terms.gp import HilbertGPTerm

# the ratio and offset maps need no detail finer than the reach's bends
SPACE_BASIS = 24
# M2's angular frequency (rad/s): the rate's scale, and the offset's from the phase
OMEGA = 2 * math.pi / (tides.constituent("M2").period_h * 3600.0)
KIND = "tide_reference"
# flood and ebb get relations of their own where each holds this share of the rows beyond this share
# of the largest |r| (a record of one flood, or a neap's brief flood, relates both alike)
SPLIT_SHARE, SPLIT_LEVEL = 0.25, 0.3
# a departure's prior sd (in the features' and the target's standard units) at most this
MAX_DEPARTURE_SD = 0.5


def parse(args: list[str] | None, text: str, is_circular=None) -> TermSpec:
    """`tide(reference)` (one relation over the reach) or `tide(reference, position)` (a map of it)."""
    args = [a.lower() for a in (args or [])]
    extra = [a for a in args if a not in ("reference", "position")]
    if extra:
        raise WorkbenchError(
            f"'{text}': a tide on a reference current takes its constituents from the reference; "
            f"write tide(reference) or tide(reference, position), not {', '.join(extra)}"
        )
    spatial = "position" in args
    inputs = ("position", "reference") if spatial else ("reference",)
    canonical = "tide(reference, position)" if spatial else "tide(reference)"
    return TermSpec(KIND, inputs, options={"spatial": spatial}, text=canonical)


def referenced(spec: TermSpec) -> TermSpec:
    """What a harmonic `tide` becomes on a survey with a reference current: the map of its relation to
    the reference (named constituents stay the harmonic fit asked for)."""
    if spec.options.get("constituents"):
        return spec
    return parse(["reference", "position"], "tide(reference, position)")


def uniform_text(spec: TermSpec) -> str:
    return "tide(reference)"


def spec_periods(spec: TermSpec) -> list[float]:
    """The periods (s) the reference's prediction is gridded for before it meets data: M2's and M4's."""
    return [tides.constituent(n).period_h * 3600.0 for n in ("M2", "M4")]


def ref_features(R: np.ndarray, split: bool = True) -> np.ndarray:
    """(n, 2) or, `split`, (n, 4): the station's prediction r and its rate r'/w, then both signed by
    the tide's sense (+ on the flood, - on the ebb): weights (c, d) on the pairs are the flood's c + d
    and the ebb's c - d."""
    r, q = R[:, 0], R[:, 1] / OMEGA
    if not split:
        return np.column_stack([r, q])
    sense = np.where(r < 0, -1.0, 1.0)
    return np.column_stack([r, q, sense * r, sense * q])


def flood_ebb(w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The flood's and the ebb's (a, b) weights on (r, r'/w) from `ref_features`' (last axis: 2 when
    flood and ebb are one relation, 4 when split)."""
    if w.shape[-1] == 2:
        return w, w
    return w[..., :2] + w[..., 2:4], w[..., :2] - w[..., 2:4]


def supports_split(r: np.ndarray) -> bool:
    """Whether a record holds enough of both the flood and the ebb to tell their relations apart: each
    sense at least SPLIT_SHARE of the rows, beyond SPLIT_LEVEL of the largest |r|."""
    top = float(np.abs(r).max()) if len(r) else 0.0
    if top <= 0:
        return False
    share = min(np.mean(r > SPLIT_LEVEL * top), np.mean(r < -SPLIT_LEVEL * top))
    return bool(share >= SPLIT_SHARE)


def relation(a: float, b: float) -> tuple[float, float]:
    """(ratio, offset in s: the place later than the station by it) of the weights on r and r'/w."""
    return math.hypot(a, b), -math.atan2(b, a) / OMEGA


class ReferenceTideTerm(Term):
    """The place's relation to its reference station (inputs `reference` and, spatial, `position`)."""

    kind = KIND
    in_time = predicts_in_time = on_flow_axis = along_reference = True

    def __init__(self, spatial: bool = True) -> None:
        self.spatial = spatial
        self.inputs = ("position", "reference") if spatial else ("reference",)

    def describe(self) -> str:
        return "tide(reference, position)" if self.spatial else "tide(reference)"

    def setup(self, Z: np.ndarray) -> None:
        R = Z[:, -2:]
        if not np.all(np.isfinite(R)):
            raise WorkbenchError(
                f"{self.describe()}: the reference current has no prediction for "
                f"{int((~np.isfinite(R).all(axis=1)).sum())} rows (a time series that ends before them)"
            )
        # the features in units of the station's own spread over the survey: a weight of 1 is a
        # departure of the ratio by about the target's spread where the tide is most of it
        self.scale = float(np.sqrt(np.mean(R[:, 0] ** 2))) or 1.0
        self.split = supports_split(R[:, 0])
        if self.spatial:
            self.space = HilbertGPTerm(("position",), "matern32", SPACE_BASIS, dims=2)
            self.space.setup(Z[:, :2])

    @property
    def width(self) -> int:
        """Features per block: (r, r'/w), and their flood-ebb difference when split."""
        return 4 if self.split else 2

    def periods_s(self) -> list[float]:
        return spec_periods(TermSpec(KIND, self.inputs))

    def note_at(self, h: np.ndarray, away_s: float, when: str) -> str | None:
        return (
            f"{self.describe()}: {when}: the reference's prediction there, times each place's ratio and "
            f"later by its offset ({span_words(away_s)} from the survey: the reference carries its "
            "spring and neap)"
        )

    def _space(self, Z: np.ndarray) -> np.ndarray:
        """The spatial basis at the rows' positions (zero beyond its box: `HilbertGPTerm.angles`)."""
        return self.space.features(Z[:, :2])

    def features(self, Z: np.ndarray) -> np.ndarray:
        U = ref_features(Z[:, -2:], self.split) / self.scale
        if not self.spatial:
            return U
        sp = (U[:, :, None] * self._space(Z)[:, None, :]).reshape(len(Z), -1)
        return np.hstack([U, sp])

    def hypers(self) -> list[Hyper]:
        top = 2 * math.log(MAX_DEPARTURE_SD)
        out = [Hyper("variance", -3.0, -14.0, top)]
        if self.split:
            out.append(Hyper("flood_ebb", -2.0, -14.0, 0.0))
        if self.spatial:
            _, sl = self.space.hypers()
            out += [Hyper("space_variance", -3.0, -14.0, top), sl]
        return out

    def log_prior_var(self, h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        n_h, wd = len(h), self.width
        diff = np.array([0.0, 0.0, 1.0, 1.0])[:wd]  # the flood-ebb difference's pair
        lv = np.full(wd, h[0]) + (h[1] * diff if self.split else 0.0)
        d = np.zeros((wd, n_h))
        d[:, 0] = 1.0
        if self.split:
            d[:, 1] = diff
        if not self.spatial:
            return lv, d
        k = 2 if self.split else 1
        logS, dS = self.space.log_prior_var(h[k : k + 2])
        m = len(logS)
        lv_sp = ((lv - h[0])[:, None] + logS[None, :]).ravel()  # the spatial variance is its own
        d_sp = np.zeros((wd * m, n_h))
        if self.split:
            d_sp[:, 1] = np.repeat(diff, m)
        d_sp[:, k : k + 2] = np.tile(dS, (wd, 1))
        return np.concatenate([lv, lv_sp]), np.vstack([d, d_sp])

    def params(self, h: np.ndarray, w: np.ndarray) -> dict[str, float]:
        (fa, fb), (ea, eb) = flood_ebb(np.asarray(w[: self.width]) / self.scale)
        ratio, offset = relation(fa, fb)
        eratio, eoffset = relation(ea, eb)
        out = {"ratio": ratio, "offset_s": offset, "ebb_ratio": eratio, "ebb_offset_s": eoffset}
        if self.spatial:
            out["space_lengthscale"] = float(math.exp(h[-1]))
        return out

    def weights_at(self, xy: np.ndarray, w: np.ndarray) -> np.ndarray:
        """(n, width) weights on `ref_features` at positions `xy`, from the term's weights `w` (a
        posterior draw or mean, in the target's units)."""
        w = np.asarray(w, float) / self.scale
        wd = self.width
        out = np.zeros((len(xy), wd)) + w[:wd]
        if self.spatial:
            out += self._space(np.asarray(xy, float)) @ w[wd:].reshape(wd, -1).T
        return out


def build(spec: TermSpec, is_circular=None) -> ReferenceTideTerm:
    return ReferenceTideTerm(spatial=bool(spec.options.get("spatial", "position" in spec.inputs)))
