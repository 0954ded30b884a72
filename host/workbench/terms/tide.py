"""The tidal term (`tide`, `tide(M2, K1)`, `tide(position)`): harmonic analysis as a Bayesian linear term.

Each constituent is a pair of features `f cos(2 pi (V + u))`, `f sin(...)` at the sample's UTC time, with the
nodal corrections f, u and the equilibrium argument V of `host/vessel/tides.py`, and one fitted prior
variance per constituent (an unneeded constituent shrinks to zero). The weights' posterior gives each
constituent's amplitude and Greenwich phase lag with their sd; for a vector, the east and north weights give
the tidal ellipse. Which constituents: the Rayleigh criterion over the record's span (`tides.select`), or
those named. `tide(position)` lets amplitude and phase vary smoothly over the survey: each constituent's
pair is multiplied by a small reduced-rank GP basis in position (its own variance ratio and lengthscale),
beside the uniform pair.
"""

from __future__ import annotations

import math
import re

import numpy as np
from forcemap.host.vessel import tides
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.terms.base import Hyper, Term, TermSpec, span_words
from forcemap.host.workbench.terms.gp import MAX_STD_RATIO, HilbertGPTerm

# the spatial form's basis in position: a tidal ellipse changes over the reach, not from line to line
SPACE_BASIS = 16
_NAME = re.compile(r"^[A-Za-z0-9]+$")


def parse_tide(args: list[str] | None, text: str, is_circular=None) -> TermSpec:
    """`tide`, or `tide(...)` with `position` (the spatial form) and constituent names, in any order."""
    args = args or []
    if any(a.lower() == "reference" for a in args):  # the tide on a reference current
        from forcemap.host.workbench.terms import reference_tide

        return reference_tide.parse(args, text)
    spatial = any(a.lower() == "position" for a in args)
    names = [a for a in args if a.lower() != "position"]
    for a in names:
        if not _NAME.match(a):
            raise WorkbenchError(
                f"'{text}': '{a}' is not a tidal constituent name (M2, S2, K1, ...)"
            )
        try:
            tides.constituent(a)
        except ValueError as exc:
            raise WorkbenchError(f"'{text}': {exc}") from None
    names = [tides.constituent(a).name for a in names]
    inputs = ("utc", "lat", "position") if spatial else ("utc", "lat")
    canonical = (
        "tide" if not args else f"tide({', '.join((['position'] if spatial else []) + names)})"
    )
    return TermSpec("tide", inputs, options={"constituents": tuple(names)}, text=canonical)


class TideTerm(Term):
    """Tidal constituents at the samples' UTC times (inputs `utc` and `lat`, and `position` for the spatial
    form). The constituents are fixed at `setup` from the record's span, or as named."""

    kind = "tide"
    in_time = predicts_in_time = on_flow_axis = is_level = True

    def __init__(
        self, constituents: tuple[str, ...] = (), spatial: bool = False, rayleigh: float = 1.0
    ) -> None:
        self.requested = tuple(constituents)
        self.spatial, self.rayleigh = spatial, rayleigh
        self.inputs = ("utc", "lat", "position") if spatial else ("utc", "lat")

    def describe(self) -> str:
        args = (["position"] if self.spatial else []) + list(self.requested)
        return f"tide({', '.join(args)})" if args else "tide"

    def setup(self, Z: np.ndarray) -> None:
        utc = Z[:, 0]
        self.lat = float(np.mean(Z[:, 1]))
        self.t_first, self.t_last = float(utc.min()), float(utc.max())
        span_h = (self.t_last - self.t_first) / 3600.0
        self.selection = tides.select(span_h, self.rayleigh, list(self.requested) or None)
        self.names = tuple(self.selection.names)
        if self.spatial:
            self.space = HilbertGPTerm(("position",), "matern32", SPACE_BASIS, dims=2)
            self.space.setup(Z[:, 2:4])

    def periods_s(self) -> list[float]:
        return [tides.constituent(n).period_h * 3600.0 for n in self.names]

    def note_at(self, h: np.ndarray, away_s: float, when: str) -> str | None:
        return (
            f"{self.describe()}: {when}: the tidal prediction from {', '.join(self.names)} "
            f"fitted over {span_words(self.t_last - self.t_first)}"
        )

    def level_features(self, t: np.ndarray, t0: float | None) -> np.ndarray:
        utc = (self.t_first if t0 is None else t0) + np.asarray(t, float)
        return tides.basis(utc, self.names, self.lat)

    @property
    def n_uniform(self) -> int:
        return 2 * len(self.names)

    def features(self, Z: np.ndarray) -> np.ndarray:
        base = tides.basis(Z[:, 0], self.names, self.lat)
        if not self.spatial:
            return base
        phi = self.space.features(Z[:, 2:4])
        return np.hstack([base, (base[:, :, None] * phi[:, None, :]).reshape(len(Z), -1)])

    def hypers(self) -> list[Hyper]:
        out = [Hyper(f"variance_{n}", -1.0, -14.0, math.log(MAX_STD_RATIO**2)) for n in self.names]
        if self.spatial:
            sv, sl = self.space.hypers()
            out += [Hyper("space_ratio", -2.0, -14.0, math.log(4.0)), sl]
        return out

    def log_prior_var(self, h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        k = len(self.names)
        n_h = len(h)
        lv = np.repeat(h[:k], 2)
        d = np.zeros((2 * k, n_h))
        d[np.arange(2 * k), np.repeat(np.arange(k), 2)] = 1.0
        if not self.spatial:
            return lv, d
        logS, dS = self.space.log_prior_var(h[k : k + 2])
        m = len(logS)
        lv_sp = (lv[:, None] + logS[None, :]).ravel()
        d_sp = np.zeros((2 * k * m, n_h))
        d_sp[:, :k] = np.repeat(d[:, :k], m, axis=0)
        d_sp[:, k : k + 2] = np.tile(dS, (2 * k, 1))
        return np.concatenate([lv, lv_sp]), np.vstack([d, d_sp])

    def params(self, h: np.ndarray, w: np.ndarray) -> dict[str, float]:
        out: dict[str, float] = {}
        for i, n in enumerate(self.names):
            a, b = w[2 * i], w[2 * i + 1]
            out[f"{n}_amplitude"] = float(math.hypot(a, b))
            out[f"{n}_phase_deg"] = float(math.degrees(math.atan2(b, a)) % 360.0)
        if self.spatial:
            out["space_lengthscale"] = float(math.exp(h[len(self.names) + 1]))
        return out

    def level(self, utc: np.ndarray, w: np.ndarray) -> np.ndarray:
        """The uniform part's value at UTC times `utc` for weights `w` (the term's block)."""
        return tides.basis(np.asarray(utc, float), self.names, self.lat) @ w[: self.n_uniform]


def term_block(model, cls) -> int | None:
    """The index of a fitted `Model`'s first feature term of class `cls`, or None."""
    return next((i for i, t in enumerate(model.feat_terms_) if isinstance(t, cls)), None)


def weight_posterior(model, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Posterior mean and covariance of feature term `k`'s weights, in the target's units."""
    from scipy import linalg

    start = int(sum(model.design_.sizes[:k]))
    m = model.design_.sizes[k]
    post = model.posterior_
    E = np.zeros((len(post["mu"]), m))
    E[start : start + m] = np.eye(m)
    V = linalg.solve_triangular(post["L"], E * post["s"][:, None], lower=True, check_finite=False)
    return post["mu"][start : start + m] * model.y_scale_, (V.T @ V) * model.y_scale_**2


def constituents(model) -> list[dict]:
    """Amplitude (target units) and Greenwich phase lag (deg) of each constituent of the model's tide term,
    with their sd from the weights' posterior (linearised); [] without a tide term."""
    k = term_block(model, TideTerm)
    if k is None:
        return []
    term = model.feat_terms_[k]
    mu, cov = weight_posterior(model, k)
    out = []
    for i, name in enumerate(term.names):
        a, b = mu[2 * i], mu[2 * i + 1]
        C = cov[2 * i : 2 * i + 2, 2 * i : 2 * i + 2]
        amp = math.hypot(a, b)
        g_a = np.array([a, b]) / max(amp, 1e-300)
        g_p = np.array([-b, a]) / max(amp * amp, 1e-300)
        amp_sd = float(math.sqrt(max(g_a @ C @ g_a, 0.0)))
        # a phase is only a phase where the amplitude stands clear of zero
        phase_sd = math.degrees(math.sqrt(max(g_p @ C @ g_p, 0.0))) if amp > 2 * amp_sd else 180.0
        out.append(
            {
                "name": name,
                "period_h": tides.constituent(name).period_h,
                "amplitude": amp,
                "amplitude_sd": amp_sd,
                "phase_deg": math.degrees(math.atan2(b, a)) % 360.0,
                "phase_sd_deg": min(phase_sd, 180.0),
            }
        )
    return out


def ellipses(east_model, north_model, draws: int = 400, seed: int = 0) -> list[dict]:
    """Each constituent's tidal ellipse from the east and north components' tide weights: semi-major and
    semi-minor axis (m/s; the minor positive when the current turns anticlockwise), the major axis's
    direction (deg clockwise from true north, 0-360: where the current flows TO at the phase; half a cycle
    later it flows the opposite way) and that phase (deg, Greenwich); each with its sd from posterior
    draws of the weights (each draw's axis taken on the estimate's side)."""
    ke, kn = term_block(east_model, TideTerm), term_block(north_model, TideTerm)
    if ke is None or kn is None:
        return []
    names = east_model.feat_terms_[ke].names
    (me, ce), (mn, cn) = weight_posterior(east_model, ke), weight_posterior(north_model, kn)
    rng = np.random.default_rng(seed)
    out = []
    for i, name in enumerate(names):
        s = slice(2 * i, 2 * i + 2)
        best = _ellipse(me[s], mn[s])
        axis = np.radians(best[2])
        ref = np.array([math.sin(axis), math.cos(axis)])
        de = rng.multivariate_normal(me[s], ce[s, s], draws, method="eigh")
        dn = rng.multivariate_normal(mn[s], cn[s, s], draws, method="eigh")
        samples = np.array([_ellipse(a, b, ref) for a, b in zip(de, dn, strict=True)])
        keys = ("major", "minor", "direction_deg", "phase_deg")
        row = {"name": name, **dict(zip(keys, best, strict=True))}
        row["major_sd"], row["minor_sd"] = float(samples[:, 0].std()), float(samples[:, 1].std())
        row["direction_sd_deg"] = _circular_sd(samples[:, 2], best[2], 360.0)
        row["phase_sd_deg"] = _circular_sd(samples[:, 3], best[3], 360.0)
        out.append(row)
    return out


def _ellipse(
    we: np.ndarray, wn: np.ndarray, ref: np.ndarray | None = None
) -> tuple[float, float, float, float]:
    """(major, minor, direction, phase) of one constituent; the major axis (east, north) points within 90
    degrees of `ref` (a draw's, the estimate's axis), else to a bearing in [0, 180)."""
    M = np.array([[we[0], we[1]], [wn[0], wn[1]]])
    U, S, Vt = np.linalg.svd(M)
    major = U[:, 0]
    if ref is None:
        sign = 1.0 if math.degrees(math.atan2(major[0], major[1])) % 360.0 < 180.0 else -1.0
    else:
        sign = 1.0 if major @ ref >= 0 else -1.0
    major, v = sign * major, sign * Vt[0]
    minor = float(S[1]) * (1.0 if np.linalg.det(M) >= 0 else -1.0)
    direction = math.degrees(math.atan2(major[0], major[1])) % 360.0
    return float(S[0]), minor, direction, math.degrees(math.atan2(v[1], v[0])) % 360.0


def _circular_sd(values: np.ndarray, centre: float, period: float) -> float:
    d = (values - centre + period / 2) % period - period / 2
    return float(np.sqrt(np.mean(d**2)))


def describe_fit(model) -> list[str]:
    """The tide term of a fitted model in words: which constituents and why, each with its amplitude and
    Greenwich phase and their sd."""
    k = term_block(model, TideTerm)
    if k is None:
        return []
    term = model.feat_terms_[k]
    lines = [f"tide: {term.selection.describe()}"]
    for c in constituents(model):
        phase = (
            f"Greenwich phase {c['phase_deg']:.1f} +- {c['phase_sd_deg']:.1f} deg"
            if c["phase_sd_deg"] < 180.0
            else "phase undetermined (the amplitude is within 2 sd of zero)"
        )
        lines.append(
            f"  {c['name']} ({c['period_h']:.2f} h): amplitude {c['amplitude']:.4g} +- "
            f"{c['amplitude_sd']:.2g}, {phase}"
        )
    return lines


def spec_periods(spec: TermSpec) -> list[float]:
    """The periods (s) a `tide` spec may oscillate at before it meets data: its named constituents', or
    down to M4's, the fastest the Rayleigh criterion may pick."""
    names = spec.options.get("constituents") or ("M4",)
    return [tides.constituent(n).period_h * 3600.0 for n in names]


def uniform_text(spec: TermSpec) -> str:
    """The uniform form of a tide (one ellipse over the reach): what the vector's flow frame needs."""
    args = list(spec.options.get("constituents") or ())
    return f"tide({', '.join(args)})" if args else "tide"


def tide_block(model) -> int | None:
    """The index of a fitted model's tidal term among its feature terms, or None."""
    return term_block(model, TideTerm)
