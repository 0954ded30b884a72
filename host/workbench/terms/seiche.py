"""A periodic term whose period the data give (`seiche`, `seiche(4440 s)`, `seiche(74 min, 2)`): a lake's
standing wave, or any oscillation that is not a tidal constituent.

The term is a cos/sin pair at the period (and at its harmonics, if asked), one fitted prior variance per
harmonic. Without a period, `resolve` estimates it: the Lomb-Scargle periodogram of the residual of the
model without the term finds the peak, and the model's own marginal likelihood, profiled over the period
(the features depend on it; the term's variance is maximised out at each period, the other hyperparameters
kept), refines it on the rows that set the hyperparameters (samples 5 s apart, close to independent); the
period's sd is that profile's curvature. The term is then recorded with its period, `seiche(4437 s)`, like
`clock_offset(+1.45 s)`.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np
from forcemap.host.workbench.engine.evidence import evidence
from forcemap.host.workbench.engine.periodogram import (
    chi2,
    curvature_sd,
    fap_baluev,
    frequencies,
    search_range,
)
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.terms.base import Hyper, Term, TermSpec
from forcemap.host.workbench.terms.gp import MAX_STD_RATIO
from scipy import linalg
from scipy.optimize import minimize_scalar

G = 9.81
_UNITS = {"s": 1.0, "sec": 1.0, "min": 60.0, "h": 3600.0, "hr": 3600.0}
_PERIOD = re.compile(r"^([0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*([A-Za-z]*)$")


def parse_seiche(args: list[str] | None, text: str, is_circular=None) -> TermSpec:
    """`seiche`, `seiche(4440 s)`, `seiche(74 min)`, `seiche(4440 s, 2)` (2 harmonics)."""
    args = args or []
    if len(args) > 2:
        raise WorkbenchError(
            f"'{text}': write seiche, seiche(PERIOD s) or seiche(PERIOD s, HARMONICS)"
        )
    period = None
    if args:
        m = _PERIOD.match(args[0])
        if not m or m.group(2).lower() not in {**_UNITS, "": 1.0}:
            raise WorkbenchError(
                f"'{text}': the period must be a number of s, min or h, e.g. 4440 s"
            )
        period = float(m.group(1)) * _UNITS.get(m.group(2).lower(), 1.0)
        if not (math.isfinite(period) and period > 0):
            raise WorkbenchError(f"'{text}': the period must be above 0 s")
    harmonics = 1
    if len(args) == 2:
        if not args[1].isdigit() or not 1 <= int(args[1]) <= 4:
            raise WorkbenchError(f"'{text}': the number of harmonics is 1 to 4")
        harmonics = int(args[1])
    options = {"period_s": period, "harmonics": harmonics}
    return TermSpec("seiche", ("t",), options=options, text=seiche_text(period, harmonics))


def seiche_text(period_s: float | None, harmonics: int = 1) -> str:
    if period_s is None:
        return "seiche" if harmonics == 1 else f"seiche(auto, {harmonics})"
    return f"seiche({period_s:.6g} s" + (f", {harmonics})" if harmonics > 1 else ")")


class SeicheTerm(Term):
    """cos/sin pairs at a period (s) and its first `harmonics` multiples, in the survey's time `t`."""

    kind = "seiche"
    in_time = predicts_in_time = on_flow_axis = estimates_period = True

    def __init__(self, period_s: float | None, harmonics: int = 1) -> None:
        self.period_s, self.harmonics = period_s, harmonics
        self.inputs = ("t",)

    def describe(self) -> str:
        return seiche_text(self.period_s, self.harmonics)

    def periods_s(self) -> list[float]:
        return [float(self.period_s)] if self.period_s else []

    def note_at(self, h: np.ndarray, away_s: float, when: str) -> str | None:
        return (
            f"{self.describe()}: {when} ({away_s / self.period_s:.0f} periods): its phase is carried on "
            "as fitted, but a real seiche decays over hours to days and is set off again by the wind"
        )

    def setup(self, Z: np.ndarray) -> None:
        if self.period_s is None:
            raise WorkbenchError(
                "seiche without a period needs the survey's data to estimate it (fit, diagnose); "
                "give seiche(PERIOD s) to a bare Model, or call seiche.resolve"
            )

    def features(self, Z: np.ndarray) -> np.ndarray:
        return harmonic_features(Z[:, 0], self.period_s, self.harmonics)

    def hypers(self) -> list[Hyper]:
        hi = math.log(MAX_STD_RATIO**2)
        return [Hyper(f"variance_{k}", -1.0, -14.0, hi) for k in range(1, self.harmonics + 1)]

    def log_prior_var(self, h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        d = np.zeros((2 * self.harmonics, self.harmonics))
        d[np.arange(2 * self.harmonics), np.repeat(np.arange(self.harmonics), 2)] = 1.0
        return np.repeat(h, 2), d

    def params(self, h: np.ndarray, w: np.ndarray) -> dict[str, float]:
        out = {"period_s": float(self.period_s)}
        for k in range(self.harmonics):
            a, b = w[2 * k], w[2 * k + 1]
            sfx = "" if k == 0 else f"_{k + 1}"
            out[f"amplitude{sfx}"] = float(math.hypot(a, b))
            out[f"phase_deg{sfx}"] = float(math.degrees(math.atan2(b, a)) % 360.0)
        return out


def harmonic_features(t: np.ndarray, period_s: float, harmonics: int = 1) -> np.ndarray:
    arg = 2 * np.pi * np.outer(t, np.arange(1, harmonics + 1)) / period_s
    out = np.empty((len(t), 2 * harmonics))
    out[:, 0::2], out[:, 1::2] = np.cos(arg), np.sin(arg)
    return out


@dataclass
class SeicheEstimate:
    """A period estimated from a survey, how, and the plausibility check a depth allows."""

    period_s: float
    period_sd_s: float
    power: float
    fap: float
    periodogram_s: float  # the periodogram's peak, before the likelihood refined it
    merian: str = ""

    def describe(self) -> str:
        return (
            f"seiche: period {self.period_s:.0f} +- {self.period_sd_s:.0f} s "
            f"({self.period_s / 60:.1f} min), estimated from the data: the residual's Lomb-Scargle peak "
            f"at {self.periodogram_s:.0f} s (power {self.power:.2f}, false-alarm probability "
            f"{self.fap:.2g}), refined by the model's marginal likelihood on the rows 5 s apart; sd from "
            f"its curvature{'. ' + self.merian if self.merian else ''}"
        )


def merian(period_s: float, depth_m: float | None, extent_m: float) -> str:
    """Merian's formula T = 2 L / (n sqrt(g h)) read backwards: the basin length a fundamental mode of this
    period needs in the survey's mean depth, beside the survey's own extent."""
    if depth_m is None or not depth_m > 0:
        return ""
    length = period_s * math.sqrt(G * depth_m) / 2.0
    return (
        f"Merian: a fundamental seiche of this period in {depth_m:.1f} m of water (the soundings' mean) "
        f"needs a basin {length / 1000:.2g} km long (the survey spans {extent_m / 1000:.2g} km); "
        "a shallower basin, or a higher mode, needs less"
    )


def _hyper_block(model, t: np.ndarray, rows: np.ndarray | None) -> dict:
    """What the profile needs of a fitted base model on its hyperparameter rows (`rows`; None: all): their
    features, residual, posterior and noise."""
    rows = np.arange(len(t)) if rows is None else rows
    Phi = model.design_.rows(rows)
    r = model.scaled_residual_[rows]
    G, b = Phi.T @ Phi, Phi.T @ r
    _, _, _, post = evidence(
        G, b, float(r @ r), len(rows), model.loglam_, model.theta_[0], grad=False
    )
    resid = r - Phi @ post["mu"]
    return {"rows": rows, "Phi": Phi, "post": post, "resid": resid, "t": t[rows]}


def _profile_gain(block: dict, period: float, harmonics: int) -> float:
    """The base model's log evidence gained by adding the term at `period`, its variance maximised out:
    -1/2 log det(I + lam A) + 1/2 c' (I/lam + A)^-1 c with A = S'K^-1 S, c = S'K^-1 y (Woodbury)."""
    S = harmonic_features(block["t"], period, harmonics)
    post, sn2 = block["post"], block["post"]["sn2"]
    V = linalg.solve_triangular(
        post["L"], (block["Phi"].T @ S) * post["s"][:, None], lower=True, check_finite=False
    )
    A = (S.T @ S - V.T @ V / sn2) / sn2
    c = S.T @ block["resid"] / sn2
    eye = np.eye(len(c))

    def neg(loglam: float) -> float:
        lam = math.exp(loglam)
        sign, logdet = np.linalg.slogdet(eye + lam * A)
        return 0.5 * logdet - 0.5 * float(c @ np.linalg.solve(eye / lam + A, c))

    res = minimize_scalar(neg, bounds=(-14.0, math.log(MAX_STD_RATIO**2)), method="bounded")
    return -float(res.fun)


def resolve(
    models: list, t: np.ndarray, harmonics: int = 1, rows: np.ndarray | None = None
) -> SeicheEstimate:
    """The period of a seiche in fitted base models (one per component: a scalar's, or a vector's east and
    north) on times `t`: the periodogram of their hyperparameter rows' (`rows`) residuals, then the profile
    of their summed marginal likelihood over the period, its sd from the profile's curvature."""
    blocks = [_hyper_block(m, t, rows) for m in models]
    th = blocks[0]["t"]
    try:
        lo, hi = search_range(th, None, None)
    except ValueError as exc:
        raise WorkbenchError(f"seiche: {exc}") from None
    Y = np.column_stack([b["resid"] for b in blocks])
    freqs = frequencies(th, lo, hi)
    c2 = chi2(th, Y, np.ones(len(th)), freqs)
    k = int(np.argmin(c2))
    c0 = float(((Y - Y.mean(axis=0)) ** 2).sum()) / len(th)
    power = 1.0 - float(c2[k]) / c0 if c0 > 0 else 0.0
    span = float(np.ptp(th))
    grid = np.linspace(freqs[k] - 1.0 / span, freqs[k] + 1.0 / span, 61)
    grid = grid[grid > 1.0 / (span * 2)]
    gain = np.array([sum(_profile_gain(b, 1 / f, harmonics) for b in blocks) for f in grid])
    best = float(grid[int(np.argmax(gain))])
    sd_f = curvature_sd(grid, gain)
    fap = fap_baluev(power, len(th), 1 / lo, th)
    return SeicheEstimate(1.0 / best, sd_f / best**2, power, fap, 1.0 / freqs[k])


def spec_periods(spec: TermSpec) -> list[float]:
    """The shortest period (s) a `seiche` spec oscillates at (its highest harmonic's), if it has one yet."""
    period = spec.options.get("period_s")
    return [float(period) / spec.options.get("harmonics", 1)] if period else []


def with_period(spec: TermSpec, period_s: float) -> TermSpec:
    """A `seiche` spec with the period the data gave it, recorded as `seiche(P s)`."""
    options = dict(spec.options, period_s=period_s)
    text = seiche_text(period_s, spec.options.get("harmonics", 1))
    return TermSpec(spec.kind, spec.inputs, options=options, text=text)


def seiche_block(model) -> int | None:
    """The index of a fitted model's seiche term among its feature terms, or None."""
    return next((i for i, t in enumerate(model.feat_terms_) if isinstance(t, SeicheTerm)), None)
