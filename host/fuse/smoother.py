"""A robust Rauch-Tung-Striebel smoother: one constant-velocity state per axis over a whole log.

Every source is a ``Channel``: its readings of the state's value (a position, a heading) or of its
rate (a ground velocity, a rate of turn), at its own time stamps less its latency. The smoother finds
the track that is most probable under a constant-velocity prior (white acceleration of spectral
density ``q``) and every reading, each with its source's noise. That is the RTS smoother's answer,
solved here as the one banded least-squares system it is (block-tridiagonal, 2 states per node), in
O(n) with ``scipy.linalg.solveh_banded``: no Python loop over readings, so a 90-minute log with a
dozen sources takes a fraction of a second.

Errors are heavy-tailed: the solve is iterated with Huber weights from each source's robust scale
(the MAD of its residuals), and a reading beyond ``reject`` scales (a jump, a spliced sentence, a
stale fix) gets weight 0 and is counted as an outlier, never taken as the state. Each source's
constant bias against the reference source (the one of least noise) is estimated on the way. Angles
(``wrap=360``) are unwrapped against the current estimate at each iteration.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import solveh_banded

MIN_DT = 1e-3  # s: nodes closer than this are one node
HUBER = 2.0  # residuals beyond this many scales are down-weighted ...
REJECT = 5.0  # ... and beyond this many, outliers (weight 0)
ITERATIONS = 5


@dataclass
class Channel:
    """One source's readings: ``kind`` "value" (the state) or "rate" (its derivative)."""

    source: str
    kind: str
    t: np.ndarray  # time stamps (s), as logged
    z: np.ndarray  # (n, d) readings
    latency: float = 0.0  # s: a reading stamped t describes t - latency
    sigma0: float = 1.0  # the noise to start from (the data then decide)
    floor: float = 0.0  # the least noise a source is granted
    bias_free: bool = False  # rates: no bias estimated
    prior_sigma: float | None = None  # the noise the source states (a fix's HDOP): weights by it
    active: np.ndarray | None = None  # readings the fit may use (a cross-validation holds some out)
    # fitted
    sigma_: float = math.nan
    bias_: np.ndarray = field(default_factory=lambda: np.zeros(0))
    outliers_: int = 0
    weights_: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def n(self) -> int:
        return len(self.t)


def _wrap(x: np.ndarray, period: float) -> np.ndarray:
    return (x + period / 2) % period - period / 2


class CvSmoother:
    """Fit ``channels`` with a constant-velocity model; ``at(t)`` gives value and rate there.

    ``q``: the white acceleration's spectral density (units²/s³); ``wrap``: the period of an angle.
    """

    def __init__(
        self,
        q: float,
        *,
        wrap: float | None = None,
        iterations: int = ITERATIONS,
        huber: float = HUBER,
        reject: float = REJECT,
    ) -> None:
        self.q = q
        self.wrap = wrap
        self.iterations = iterations
        self.huber = huber
        self.reject = reject

    # --- the system ---------------------------------------------------------------------------------

    def _nodes(self, channels: list[Channel], query: np.ndarray) -> np.ndarray:
        times = [c.t - c.latency for c in channels] + [np.asarray(query, float)]
        t = np.sort(np.concatenate(times))
        keep = np.concatenate([[True], np.diff(t) > MIN_DT])
        return t[keep]

    def _prior(self, t: np.ndarray) -> np.ndarray:
        """The banded normal matrix (upper form, 4 rows) of the constant-velocity prior."""
        n = len(t)
        ab = np.zeros((4, 2 * n))
        dt = np.maximum(np.diff(t), MIN_DT)
        q = self.q
        w = np.empty((len(dt), 2, 2))
        w[:, 0, 0] = 12 / dt**3 / q
        w[:, 0, 1] = w[:, 1, 0] = -6 / dt**2 / q
        w[:, 1, 1] = 4 / dt / q
        a = np.zeros((len(dt), 2, 4))
        a[:, 0, 0], a[:, 0, 1], a[:, 0, 2] = -1.0, -dt, 1.0
        a[:, 1, 1], a[:, 1, 3] = -1.0, 1.0
        m = np.einsum("kia,kij,kjb->kab", a, w, a)
        base = 2 * np.arange(len(dt))
        for i in range(4):
            for j in range(i, 4):
                np.add.at(ab[3 + i - j], base + j, m[:, i, j])
        ab[3] += 1e-9  # a weak prior on every state: a node no reading reaches is still defined
        return ab

    def _solve(
        self,
        t: np.ndarray,
        channels: list[Channel],
        est: np.ndarray | None,
        prior: np.ndarray | None = None,
    ) -> np.ndarray:
        ab = self._prior(t) if prior is None else prior.copy()  # the readings are added in place
        d = channels[0].z.shape[1]
        rhs = np.zeros((2 * len(t), d))
        for c in channels:
            if not c.n:
                continue
            idx = self._node_of(t, c)
            col = 2 * idx + (0 if c.kind == "value" else 1)
            z = c.z - (c.bias_ if c.bias_.size else 0.0)
            if self.wrap and c.kind == "value" and est is not None:
                ref = est[col]
                z = ref + _wrap(z - ref, self.wrap)
            sigma = c.prior_sigma if c.prior_sigma else c.sigma_
            w = c.weights_ / max(sigma, 1e-9) ** 2
            if c.active is not None:
                w = w * c.active
            np.add.at(ab[3], col, w)
            np.add.at(rhs, col, w[:, None] * z)
        return solveh_banded(ab, rhs, check_finite=False)

    def _node_of(self, t: np.ndarray, c: Channel) -> np.ndarray:
        """``_index``, kept for the fit's nodes: every iteration asks the same."""
        cache = self._nodes_of
        got = cache.get(id(c))
        if got is None or got[0] is not t or got[1] != c.latency or got[2] is not c.t:
            got = cache[id(c)] = (t, c.latency, c.t, self._index(t, c))
        return got[3]

    @staticmethod
    def _index(t: np.ndarray, c: Channel) -> np.ndarray:
        ts = c.t - c.latency
        i = np.clip(np.searchsorted(t, ts), 0, len(t) - 1)
        j = np.clip(i - 1, 0, len(t) - 1)
        return np.where(np.abs(t[j] - ts) < np.abs(t[i] - ts), j, i)

    # --- fitting --------------------------------------------------------------------------------------

    def fit(
        self,
        channels: list[Channel],
        query: np.ndarray,
        init: Callable[[np.ndarray], np.ndarray] | None = None,
    ) -> CvSmoother:
        """Smooth ``channels``, with a node at every ``query`` time; ``init(t)``: a first estimate of
        the value at times ``t`` (angles are unwrapped against it)."""
        channels = [c for c in channels if c.n]
        if not channels:
            raise ValueError("no readings to smooth")
        t = self._nodes(channels, query)
        self.t_ = t
        self._nodes_of: dict[int, tuple] = {}
        d = channels[0].z.shape[1]
        for c in channels:
            c.sigma_ = c.sigma0
            c.bias_ = np.zeros(d)
            if not c.weights_.size or len(c.weights_) != c.n:
                c.weights_ = np.ones(c.n)
        est = None
        if init is not None:
            est = np.zeros((2 * len(t), d))
            est[0::2] = init(t)
        prior = self._prior(t)  # the same at every iteration: only the readings' weights change
        for it in range(self.iterations):
            est = self._solve(t, channels, est, prior)
            self._reweight(t, channels, est, last=it == self.iterations - 1)
        self.x_ = est
        self.channels_ = channels
        return self

    def residuals(self, c: Channel) -> np.ndarray:
        """``c``'s readings less the fitted state (its bias removed), shape (n, d)."""
        r = self._residuals(self.t_, c, self.x_) - (c.bias_ if c.bias_.size else 0.0)
        return _wrap(r, self.wrap) if self.wrap and c.kind == "value" else r

    def _residuals(self, t: np.ndarray, c: Channel, est: np.ndarray) -> np.ndarray:
        col = 2 * self._node_of(t, c) + (0 if c.kind == "value" else 1)
        r = c.z - est[col]
        if self.wrap and c.kind == "value":
            r = _wrap(r, self.wrap)
        return r

    def _reweight(self, t: np.ndarray, channels: list[Channel], est: np.ndarray, last: bool):
        """Each source's bias, robust scale and Huber weights from its residuals."""
        values = [c for c in channels if c.kind == "value"]
        ref = min(values, key=lambda c: c.sigma_ / math.sqrt(max(c.n, 1)), default=None)
        for c in channels:
            r = self._residuals(t, c, est)
            ok = c.weights_ > 0
            if c.active is not None:
                ok &= c.active
            if ok.sum() < 3:
                continue
            if not c.bias_free and c is not ref and c.kind == "value":
                c.bias_ = np.median(r[ok], axis=0)
                r = r - c.bias_
                if self.wrap:
                    r = _wrap(r, self.wrap)
            else:
                c.bias_ = np.zeros(r.shape[1])
            size = np.sqrt((r**2).sum(axis=1))
            # the median radius of a d-dimensional Gaussian: 0.674 sigma (d=1), 1.177 sigma (d=2)
            k = 0.6745 if r.shape[1] == 1 else 1.1774
            sigma = max(float(np.median(size[ok])) / k, c.floor, 1e-6)
            c.sigma_ = sigma
            u = size / sigma
            w = np.where(u <= self.huber, 1.0, self.huber / np.maximum(u, 1e-12))
            w[u > self.reject] = 0.0
            c.weights_ = w
            c.outliers_ = int((w == 0).sum())

    # --- the answer -----------------------------------------------------------------------------------

    def at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(value, rate) at ``t``: exact at nodes, cubic Hermite between (the model's own curve)."""
        t = np.asarray(t, float)
        nodes = self.t_
        p, v = self.x_[0::2], self.x_[1::2]
        i = np.clip(np.searchsorted(nodes, t) - 1, 0, len(nodes) - 2)
        if len(nodes) < 2:
            return np.repeat(p[:1], len(t), axis=0), np.repeat(v[:1], len(t), axis=0)
        h = (nodes[i + 1] - nodes[i])[:, None]
        s = np.clip((t - nodes[i])[:, None] / h, 0.0, 1.0)
        p0, p1, v0, v1 = p[i], p[i + 1], v[i] * h, v[i + 1] * h
        h00, h10 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s
        h01, h11 = -2 * s**3 + 3 * s**2, s**3 - s**2
        val = h00 * p0 + h10 * v0 + h01 * p1 + h11 * v1
        d00, d10 = 6 * s**2 - 6 * s, 3 * s**2 - 4 * s + 1
        d01, d11 = -6 * s**2 + 6 * s, 3 * s**2 - 2 * s
        rate = (d00 * p0 + d10 * v0 + d01 * p1 + d11 * v1) / h
        return val, rate
