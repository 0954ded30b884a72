"""The forms a change in time can take, fitted to revisit differences: the shares of their sum of squares
that a drift and a periodic change at each period explain, for the observed times and for any permutation of
the stretches' times (host/workbench/timejudge/judge.py judges with them).

A pair's difference owes something to other than time: the displacement between its two samples (the
field's gradient across the revisit radius) and the heading of each pass (an instrument that reads
differently with the bow's direction). Those columns are taken out of the differences and of every form's
columns alike (Frisch, Waugh and Lovell: the share is then what the form adds to them).
"""

from __future__ import annotations

import numpy as np
from forcemap.host.workbench.timejudge.revisits import RevisitPairs

# periods of the ladder: from this many stretches (a change faster than the paired unit cannot be judged)
MIN_PERIOD_STRETCHES = 4.0
MIN_PERIOD_S = 600.0
LADDER = 24
M2_S = 44714.16
K1_S = 86164.09
# pair differences beyond this many robust sd are clipped (a lost bottom, a spike the flags missed)
CLIP_SD = 4.0


class Projector:
    """Takes the span of the nuisance columns out of any columns."""

    def __init__(self, N: np.ndarray | None) -> None:
        self.Q = np.linalg.qr(N)[0] if N is not None and N.size else None

    def __call__(self, A: np.ndarray) -> np.ndarray:
        return A if self.Q is None else A - self.Q @ (self.Q.T @ A)


def nuisance(rp: RevisitPairs, xy: np.ndarray, heading: np.ndarray | None) -> np.ndarray:
    """The displacement between each pair's two samples and two harmonics of the heading, differenced."""
    a, b = rp.pairs[:, 0], rp.pairs[:, 1]
    cols = [xy[b, 0] - xy[a, 0], xy[b, 1] - xy[a, 1]]
    if heading is not None and np.isfinite(heading).all():
        h = np.radians(heading)
        cols += [f(k * h[b]) - f(k * h[a]) for k in (1, 2) for f in (np.cos, np.sin)]
    return np.column_stack(cols)


def clipped(d: np.ndarray) -> np.ndarray:
    """Each component clipped at CLIP_SD robust sd from zero."""
    out = d.copy()
    for c in range(d.shape[1]):
        s = 1.4826 * np.median(np.abs(d[:, c] - np.median(d[:, c])))
        if s > 0:
            out[:, c] = np.clip(d[:, c], -CLIP_SD * s, CLIP_SD * s)
    return out


def pair_shares(d: np.ndarray, C: np.ndarray, S: np.ndarray) -> np.ndarray:
    """Share of the differences' sum of squares explained by each cos/sin column pair (a separate pair of
    coefficients per vector component), vectorised over the pairs of columns."""
    cc, ss, cs = (C * C).sum(0), (S * S).sum(0), (C * S).sum(0)
    q = quadratic_shares(cc, ss, cs, d.T @ C, d.T @ S)
    return q / max(float((d * d).sum()), 1e-300)


def quadratic_shares(cc, ss, cs, cd: np.ndarray, sd: np.ndarray) -> np.ndarray:
    """The sum of squares a cos/sin column pair explains of each component, summed, from the columns' products
    cc = C'C, ss = S'S, cs = C'S (one per column pair) and with the components cd = C'd, sd = S'd (components x
    column pairs); zero where the two columns are collinear."""
    det = cc * ss - cs**2
    det = np.where(det > 1e-9 * (cc * ss) + 1e-300, det, np.inf)
    cd, sd = np.atleast_2d(cd), np.atleast_2d(sd)
    return ((ss * cd**2 - 2 * cs * cd * sd + cc * sd**2) / det).sum(axis=0)


def periodic_columns(ta, tb, omega: np.ndarray, proj: Projector) -> tuple[np.ndarray, np.ndarray]:
    """cos and sin at each frequency, differenced over each pair, the nuisance taken out."""
    C = np.cos(np.outer(tb, omega)) - np.cos(np.outer(ta, omega))
    S = np.sin(np.outer(tb, omega)) - np.sin(np.outer(ta, omega))
    return proj(C), proj(S)


def form_basis(t: np.ndarray, span: float, period_s: float | None = None) -> np.ndarray:
    """A form's functions of time, undifferenced: a drift's quadratic in t / span, or the cosine and sine
    of a period."""
    if period_s is None:
        u = t / span
        return np.column_stack([u, u**2])
    omega = 2.0 * np.pi / period_s
    return np.column_stack([np.cos(omega * t), np.sin(omega * t)])


def drift_columns(ta, tb, span: float, proj: Projector) -> np.ndarray:
    """A quadratic in time, differenced over each pair, the nuisance taken out."""
    return proj(form_basis(tb, span) - form_basis(ta, span))


def share_of(d: np.ndarray, A: np.ndarray) -> float:
    """Share of the differences' sum of squares explained by the columns A (least squares)."""
    w, *_ = np.linalg.lstsq(A, d, rcond=None)
    if not np.isfinite(w).all():
        return 0.0
    return float(((A @ w) ** 2).sum() / max(float((d * d).sum()), 1e-300))


class FormLadder:
    """The forms tried: a drift, then a periodic change at each period of the ladder and at M2 and K1."""

    def __init__(self, span_s: float, stretch_s: float) -> None:
        lo = max(MIN_PERIOD_STRETCHES * stretch_s, MIN_PERIOD_S)
        hi = max(2.0 * span_s, 2.0 * lo)
        self.periods = np.concatenate([np.geomspace(lo, hi, LADDER), [M2_S, K1_S]])
        self.omega = 2.0 * np.pi / self.periods
        self.span = span_s

    def shares(self, d: np.ndarray, ta, tb, proj: Projector) -> np.ndarray:
        """[drift, each period...] shares of the differences explained."""
        C, S = periodic_columns(ta, tb, self.omega, proj)
        drift = share_of(d, drift_columns(ta, tb, self.span, proj))
        return np.concatenate([[drift], pair_shares(d, C, S)])

    def columns(self, i: int, ta, tb, proj: Projector) -> np.ndarray:
        """Form i's columns, differenced over each pair, the nuisance taken out."""
        if i == 0:
            return drift_columns(ta, tb, self.span, proj)
        C, S = periodic_columns(ta, tb, self.omega[i - 1 : i], proj)
        return np.column_stack([C, S])


class PermutedTimes:
    """The ladder's shares with the stretches' times permuted, many permutations at once.

    Moving stretch s by Delta_s turns a pair's cos(w t) into cos(w t) cos(w Delta_s) - sin(w t) sin(w Delta_s):
    at each frequency the differenced columns are C = B [c; -s] and S = B [s; c], with c, s the cosines and
    sines of w Delta over the stretches and B (pairs x 2 stretches, four entries a row) fixed. The shares need
    only C'C, S'S, C'S (quadratic forms in B' P B, P the projector off the nuisance: a sparse part less a
    low-rank one) and C'd, S'd (B'd: d is already projected), so a permutation costs stretches, not pairs,
    per frequency; the numbers are those of the columns formed in full, to rounding."""

    def __init__(self, rp: RevisitPairs, ladder: FormLadder, proj: Projector) -> None:
        self.rp, self.ladder, self.proj = rp, ladder, proj
        self.ta, self.tb = rp.times()
        self.sa, self.sb = rp.stretch[rp.pairs[:, 0]], rp.stretch[rp.pairs[:, 1]]

    def _stretch_columns(self, w: float):
        """B at frequency w: the pairs' cos and sin columns per stretch of each end, later end minus earlier."""
        from scipy import sparse

        ns, p = self.rp.n_stretches, len(self.ta)
        rows = np.concatenate([np.arange(p)] * 4)
        cols = np.concatenate([self.sb, self.sa, self.sb + ns, self.sa + ns])
        vals = np.concatenate(
            [np.cos(w * self.tb), -np.cos(w * self.ta), np.sin(w * self.tb), -np.sin(w * self.ta)]
        )
        return sparse.csr_matrix((vals, (rows, cols)), shape=(p, 2 * ns))

    def _drift_null(self, d: np.ndarray, shifts: np.ndarray) -> np.ndarray:
        """The drift's share for each permutation (a column of `shifts`, stretches x permutations).

        With u = t / span and each stretch moved by delta = Delta / span, a pair's differenced columns are
        u_b - u_a + delta_sb - delta_sa and u_b^2 - u_a^2 + 2 (u_b delta_sb - u_a delta_sa) + delta_sb^2 -
        delta_sa^2: F z for a fixed F (pairs x 2 + 2 stretches: the pair's own u difference and u^2 difference,
        +-1 at its two stretches, +-u at its two stretches) and z1 = [1, 0, delta, 0], z2 = [0, 1, delta^2,
        2 delta]. The products the share needs are quadratic forms in F' P F (P the projector off the
        nuisance) and F'd, as the periods'; the numbers are those of the columns formed in full, to rounding."""
        from scipy import sparse

        ns, span = self.rp.n_stretches, self.ladder.span
        ua, ub = self.ta / span, self.tb / span
        p = len(ua)
        rows = np.concatenate([np.arange(p)] * 6)
        sa, sb = 2 + self.sa, 2 + self.sb
        cols = np.concatenate([np.zeros(p, int), np.ones(p, int), sb, sa, ns + sb, ns + sa])
        vals = np.concatenate([ub - ua, ub * ub - ua * ua, np.ones(p), -np.ones(p), ub, -ua])
        F = sparse.csr_matrix((vals, (rows, cols)), shape=(p, 2 + 2 * ns))
        G = (F.T @ F).toarray()
        if self.proj.Q is not None:
            FQ = F.T @ self.proj.Q
            G -= FQ @ FQ.T
        g = F.T @ d
        delta = shifts / span
        ones, zeros = np.ones((1, delta.shape[1])), np.zeros((1, delta.shape[1]))
        Z1 = np.vstack([ones, zeros, delta, np.zeros_like(delta)])
        Z2 = np.vstack([zeros, ones, delta * delta, 2.0 * delta])
        GZ1, GZ2 = G @ Z1, G @ Z2
        cc, ss, cs = (Z1 * GZ1).sum(0), (Z2 * GZ2).sum(0), (Z1 * GZ2).sum(0)
        return quadratic_shares(cc, ss, cs, g.T @ Z1, g.T @ Z2) / max(float((d * d).sum()), 1e-300)

    def null(self, d: np.ndarray, orders: np.ndarray) -> np.ndarray:
        """[drift, each period...] shares for each permutation of the stretches (a row of `orders`)."""
        out = np.empty((len(orders), 1 + len(self.ladder.omega)))
        shifts = self.rp.shifts(orders).T  # stretches x permutations
        out[:, 0] = self._drift_null(d, shifts)
        dd = max(float((d * d).sum()), 1e-300)
        Q = self.proj.Q
        for i, w in enumerate(self.ladder.omega):
            B = self._stretch_columns(w)
            H = (B.T @ B).tocsr()
            R = None if Q is None else (B.T @ Q).T
            g = B.T @ d
            c, s = np.cos(w * shifts), np.sin(w * shifts)
            X, Y = np.vstack([c, -s]), np.vstack([s, c])
            HX, HY = H @ X, H @ Y
            if R is not None:
                HX -= R.T @ (R @ X)
                HY -= R.T @ (R @ Y)
            cc, ss, cs = (X * HX).sum(0), (Y * HY).sum(0), (X * HY).sum(0)
            out[:, 1 + i] = quadratic_shares(cc, ss, cs, g.T @ X, g.T @ Y) / dd
        return out


class FittedChange:
    """The size of a form's change in time, in the target's unit, over the times `span` (s) that the revisits
    compare, their first pass to their last: a drift's (a period longer than the record included) from the
    span's start to its end, signed for one component and a vector's length for two; a period's amplitude
    (a vector's largest component's). The differences fix the change up to a constant, and neither needs
    one. A drift is judged over the span, not the survey: the revisits pin it where their first passes meet
    their last, and neither a quadratic's turn between them nor its course outside the passes they compare.
    `kind` is the form's ("drift", "tide", "periodic"); `scale_s` the one the ladder formed the drift's
    columns with (the survey's duration)."""

    def __init__(
        self, kind: str, period_s: float | None, scale_s: float, span: tuple[float, float], basis=None
    ) -> None:
        self.amplitude = kind != "drift"
        grid = np.linspace(span[0], span[1], 200)
        # `basis`: the form's own functions of time, where the ladder's do not give them (a reference's)
        self.basis = form_basis(grid, max(scale_s, 1e-9), period_s) if basis is None else basis(grid)

    def __call__(self, d: np.ndarray, A: np.ndarray) -> float:
        """The change the columns `A` fit to the differences `d` (least squares)."""
        w, *_ = np.linalg.lstsq(A, d, rcond=None)
        return self.of(w)

    def of(self, w: np.ndarray) -> float:
        """The change of the form with coefficients `w` (columns x components)."""
        change = self.basis @ w
        if not np.isfinite(change).all():
            return 0.0
        if self.amplitude:
            return float(np.ptp(change, axis=0).max() / 2.0)
        step = change[-1] - change[0]
        return float(step[0]) if len(step) == 1 else float(np.hypot(*step))

    def departure(self, d: np.ndarray, A: np.ndarray) -> float:
        """The largest departure from its value at the span's start of the change the columns `A` fit."""
        w, *_ = np.linalg.lstsq(A, d, rcond=None)
        return self.departure_of(w)

    def departure_of(self, w: np.ndarray) -> float:
        """The largest departure of the form with coefficients `w` from its value at the span's start (a
        vector's length): the start-to-end change where the form rises or falls steadily, more where it
        turns between them."""
        change = self.basis @ w
        if not np.isfinite(change).all():
            return 0.0
        return float(np.sqrt(((change - change[0]) ** 2).sum(axis=1)).max())

    def turns(self, d: np.ndarray, A: np.ndarray, rp: RevisitPairs, seed: int = 0) -> bool:
        """Whether the change the columns `A` fit turns between the span's ends: its largest departure from
        its start exceeds its start-to-end change by more than twice that excess's sd (the stretches
        resampled). Meant for a part of a cycle; a quadratic fitted to a smooth step overshoots it by its
        form alone (on the fjord's injected level, a departure of 0.99 m for a 0.59 m rise)."""
        def excess(w: np.ndarray) -> float:
            return self.departure_of(w) - abs(self.of(w))

        w, *_ = np.linalg.lstsq(A, d, rcond=None)
        return excess(w) > 2.0 * self.sd(d, A, rp, seed, of=excess)

    def sd(
        self, d: np.ndarray, A: np.ndarray, rp: RevisitPairs, seed: int = 0, n: int = 200, of=None
    ) -> float:
        """The change's sd (or that of the measure `of` of the coefficients: `departure_of`) over the
        stretches resampled with replacement, a pair weighted by the product of its two stretches' counts
        (as the period's: time_judge.bootstrap_period_sd)."""
        of = of or self.of
        sa, sb = rp.stretch[rp.pairs[:, 0]], rp.stretch[rp.pairs[:, 1]]
        rng, ns = np.random.default_rng(seed), rp.n_stretches
        out = np.empty(n)
        for i in range(n):
            counts = np.bincount(rng.integers(0, ns, ns), minlength=ns)
            wt = np.sqrt(counts[sa] * counts[sb])[:, None]
            coef, *_ = np.linalg.lstsq(A * wt, d * wt, rcond=None)
            out[i] = of(coef)
        return float(np.std(out))
