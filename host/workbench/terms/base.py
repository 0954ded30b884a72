"""Model terms: each maps its inputs to fixed features with prior variances set by hyperparameters, or is a mean function.

A GP term over continuous inputs uses the Hilbert-space reduced-rank approximation (Solin & Sarkka 2020):
Laplacian eigenfunctions on a box around the data are the features and the kernel's spectral density
gives each feature's prior variance. The features do not depend on the hyperparameters, so the model's
sufficient statistics (Phi'Phi, Phi'y) are computed once and every marginal-likelihood evaluation costs
O(M^3) whatever the number of samples.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from forcemap.host.workbench.errors import WorkbenchError
from scipy.special import gammaln, ive

KERNELS = ("linear", "rbf", "matern12", "matern32", "matern52", "periodic")
KERNEL_ALIASES = {"expquad": "rbf", "exp_quad": "rbf", "se": "rbf", "exponential": "matern12"}
NU = {"matern12": 0.5, "matern32": 1.5, "matern52": 2.5}
DEFAULT_SPACE_BASIS = 400
DEFAULT_1D_BASIS = 32
# when the fitted lengthscale sits at the resolvable limit, the basis is doubled up to these
MAX_SPACE_BASIS = 2048
MAX_1D_BASIS = 128
DEFAULT_HARMONICS = 8
BOUNDARY = 1.6
# lengthscales below L_MIN_FACTOR / (highest basis frequency) are not represented well (Riutort-Mayol et al. 2023
# ask for about 3.4 c L / l functions per dimension for Matern 3/2)
L_MIN_FACTOR = 4.5
# a GP term's prior std at most this many times the target's std
MAX_STD_RATIO = 2.0


@dataclass
class Hyper:
    """One hyperparameter in log space, with bounds."""

    name: str
    init: float
    lo: float
    hi: float


class Term:
    """Base class. Feature terms return features and log prior variances; mean terms return a mean function."""

    inputs: tuple[str, ...] = ()
    is_mean = False

    def hyper_index(self, name: str) -> int:
        """Position of the hyperparameter `name` in this term's slice of the parameter vector."""
        return [h.name for h in self.hypers()].index(name)

    def describe(self) -> str:
        raise NotImplementedError

    def setup(self, Z: np.ndarray) -> None:
        """Fix anything that depends on the training inputs (domain, scaling)."""

    def features(self, Z: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def hypers(self) -> list[Hyper]:
        return []

    def log_prior_var(self, h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Log prior variance of each feature and its derivative by each log-hyperparameter (m, p)."""
        raise NotImplementedError

    def params(self, h: np.ndarray, w: np.ndarray) -> dict[str, float]:
        """Human-readable fitted parameters from hyperparameters `h` and posterior mean weights `w`."""
        return {hp.name: float(math.exp(v)) for hp, v in zip(self.hypers(), h, strict=True)}


class ConstTerm(Term):
    """A constant offset with a broad, fitted prior: the model's mean level."""

    def describe(self) -> str:
        return "const"

    def features(self, Z: np.ndarray) -> np.ndarray:
        return np.ones((len(Z), 1))

    def hypers(self) -> list[Hyper]:
        return [Hyper("variance", 0.0, -12.0, 8.0)]

    def log_prior_var(self, h):
        return np.array([h[0]]), np.ones((1, 1))

    def params(self, h, w):
        return {"value": float(w[0])}


class LinearTerm(Term):
    """Linear in standardized inputs: a fitted slope per input (kernel `linear`)."""

    def __init__(self, inputs: tuple[str, ...], label: str = "linear") -> None:
        self.inputs, self.label = inputs, label

    def describe(self) -> str:
        return (
            f"{self.label}({', '.join(self.inputs)})"
            if self.label == "linear"
            else f"gp({', '.join(self.inputs)}, linear)"
        )

    def setup(self, Z):
        self.mean, self.scale = Z.mean(axis=0), Z.std(axis=0) + 1e-12

    def features(self, Z):
        return (Z - self.mean) / self.scale

    def hypers(self):
        return [Hyper("variance", -2.0, -14.0, 6.0)]

    def log_prior_var(self, h):
        m = len(self.mean)
        return np.full(m, h[0]), np.ones((m, 1))

    def params(self, h, w):
        return {
            f"slope_{name}": float(wi / s)
            for name, wi, s in zip(self.inputs, w, self.scale, strict=True)
        }


class CosineTerm(Term):
    """a*cos(angle - phase): two features cos, sin of a compass angle in degrees."""

    def __init__(self, name: str) -> None:
        self.inputs = (name,)

    def describe(self) -> str:
        return f"cos({self.inputs[0]})"

    def features(self, Z):
        a = np.radians(Z[:, 0])
        return np.column_stack([np.cos(a), np.sin(a)])

    def hypers(self):
        return [Hyper("variance", -3.0, -14.0, 6.0)]

    def log_prior_var(self, h):
        return np.full(2, h[0]), np.ones((2, 1))

    def params(self, h, w):
        return {
            "amplitude": float(math.hypot(w[0], w[1])),
            "phase_deg": float(math.degrees(math.atan2(w[1], w[0]))),
        }


class PeriodicTerm(Term):
    """GP with the periodic kernel exp(-2 sin^2(d/2)/l^2) on a compass angle, as its exact Fourier series."""

    def __init__(self, name: str, harmonics: int = DEFAULT_HARMONICS) -> None:
        self.inputs, self.k = (name,), np.arange(1, harmonics + 1)

    def describe(self) -> str:
        return f"gp({self.inputs[0]}, periodic)"

    def features(self, Z):
        a = np.radians(Z[:, 0])[:, None] * self.k[None, :]
        return np.hstack([np.cos(a), np.sin(a)])

    def hypers(self):
        return [
            Hyper("variance", -3.0, -14.0, 6.0),
            Hyper("lengthscale", 0.0, math.log(0.15), math.log(8.0)),
        ]

    def log_prior_var(self, h):
        z = math.exp(-2.0 * h[1])
        iv = np.maximum(ive(self.k, z), 1e-300)
        div = 0.5 * (ive(self.k - 1, z) + ive(self.k + 1, z)) - iv
        dlog_dlogl = (div / iv) * (-2.0 * z)
        logq = h[0] + math.log(2.0) + np.log(iv)
        logq, dl = np.concatenate([logq, logq]), np.concatenate([dlog_dlogl, dlog_dlogl])
        return logq, np.column_stack([np.ones_like(logq), dl])

    def params(self, h, w):
        return {"variance": float(math.exp(h[0])), "lengthscale_rad": float(math.exp(h[1]))}


class HilbertGPTerm(Term):
    """A stationary GP (rbf or Matern) on 1-3 continuous inputs, as Laplacian eigenfunctions on a box."""

    def __init__(
        self, inputs: tuple[str, ...], kernel: str, n_basis: int | None = None, dims: int = 1
    ) -> None:
        self.inputs, self.kernel, self.dims = inputs, kernel, dims
        self.n_basis = n_basis or (DEFAULT_SPACE_BASIS if dims >= 2 else DEFAULT_1D_BASIS)
        self.max_basis = max(self.n_basis, MAX_SPACE_BASIS if dims >= 2 else MAX_1D_BASIS)

    def describe(self) -> str:
        return f"gp({', '.join(self.inputs)}, {self.kernel})"

    def setup(self, Z):
        D = Z.shape[1]
        self.center = 0.5 * (Z.min(axis=0) + Z.max(axis=0))
        Zc = Z - self.center
        # rotate to principal axes so a long thin survey gets a tight box (the kernel is isotropic)
        if D == 2:
            _, _, vt = np.linalg.svd(Zc - Zc.mean(axis=0), full_matrices=False)
            self.rot = vt.T
        else:
            self.rot = np.eye(D)
        Zr = Zc @ self.rot
        self.center = self.center + (0.5 * (Zr.min(axis=0) + Zr.max(axis=0))) @ self.rot.T
        Zr = (Z - self.center) @ self.rot
        half = np.maximum(np.abs(Zr).max(axis=0), 1e-9)
        self.half = half
        self.L = BOUNDARY * half
        # the n_basis eigenfunctions of lowest frequency
        vol = np.prod(2 * self.L / math.pi)
        unit_ball = math.pi ** (D / 2) / math.gamma(D / 2 + 1) / 2**D
        omega = (self.n_basis / (vol * unit_ball)) ** (1 / D)
        jmax = np.ceil(2 * self.L * omega * 1.3 / math.pi).astype(int) + 1
        grids = np.meshgrid(*[np.arange(1, j + 1) for j in jmax], indexing="ij")
        J = np.column_stack([g.ravel() for g in grids])
        w = math.pi * np.sqrt(((J / (2 * self.L)) ** 2).sum(axis=1))
        order = np.argsort(w, kind="stable")[: self.n_basis]
        self.J, self.omega = J[order], w[order]
        # shortest lengthscale the basis resolves well, and the longest worth considering
        self.l_min = L_MIN_FACTOR / self.omega.max()
        self.l_max = 4.0 * float(self.L.max())

    def angles(self, Z) -> list[np.ndarray]:
        """u_d = (z_d + L_d) pi / 2 L_d per rotated input axis: feature j is prod_d sin(J_jd u_d) / sqrt(L_d)."""
        Zr = (Z - self.center) @ self.rot
        return [(Zr[:, d] + self.L[d]) * (math.pi / (2 * self.L[d])) for d in range(Zr.shape[1])]

    def features(self, Z):
        out = None
        for d, arg in enumerate(self.angles(Z)):
            # one sine per distinct frequency index, then gathered: a few hundred sines, not n x M; the table is
            # (index, sample) so that the gather copies whole rows, and the features come out column-major
            k = np.arange(1, self.J[:, d].max() + 1)
            table = np.sin(k[:, None] * arg[None, :]) / math.sqrt(self.L[d])
            rows = table[self.J[:, d] - 1]
            out = rows if out is None else np.multiply(out, rows, out=out)
        return out.T

    def hypers(self):
        l0 = max(0.3 * float(self.half.max()), 1.5 * self.l_min)
        return [
            # a GP's std beyond MAX_STD_RATIO x the data's, or a lengthscale beyond a few box widths, is a spline in disguise
            # that extrapolates wildly into unseen blocks; the bounds keep type-II ML away from those optima
            Hyper("variance", -0.5, -14.0, math.log(MAX_STD_RATIO**2)),
            Hyper("lengthscale", math.log(l0), math.log(self.l_min), math.log(self.l_max)),
        ]

    def log_prior_var(self, h):
        D = self.L.size
        logl = h[1]
        ell = math.exp(logl)
        w2 = self.omega**2
        if self.kernel == "rbf":
            logS = h[0] + 0.5 * D * math.log(2 * math.pi) + D * logl - 0.5 * ell**2 * w2
            dl = D - ell**2 * w2
        else:
            nu = NU[self.kernel]
            c = (
                D * math.log(2)
                + 0.5 * D * math.log(math.pi)
                + gammaln(nu + D / 2)
                + nu * math.log(2 * nu)
                - gammaln(nu)
            )
            a = 2 * nu / ell**2
            logS = h[0] + c - 2 * nu * logl - (nu + D / 2) * np.log(a + w2)
            dl = -2 * nu + (nu + D / 2) * (2 * a) / (a + w2)
        return logS, np.column_stack([np.ones_like(logS), dl])


# the water level changes over tens of minutes at the fastest (a tide, a flood wave): a shorter lengthscale
# would let it take the bed's detail along the track
WATER_LEVEL_MIN_LENGTHSCALE_S = 600.0


class WaterLevelTerm(HilbertGPTerm):
    """The water surface's level as a smooth function of time (`water_level`): an RBF GP in `t` whose
    lengthscale is at least WATER_LEVEL_MIN_LENGTHSCALE_S. Every sounding is deeper by the level at its time;
    the survey tells the level from the bed where the track crosses or revisits itself."""

    def __init__(self, n_basis: int | None = None) -> None:
        super().__init__(("t",), "rbf", n_basis, dims=1)

    def describe(self) -> str:
        return "water_level"

    def setup(self, Z):
        super().setup(Z)
        self.l_min = max(self.l_min, min(WATER_LEVEL_MIN_LENGTHSCALE_S, 0.25 * self.l_max))


class PowerTerm(Term):
    """Mean function a * (z / z_ref)^b for a positive covariate (a power law, e.g. Manning's depth^(2/3))."""

    is_mean = True

    def __init__(self, name: str) -> None:
        self.inputs = (name,)

    def describe(self) -> str:
        return f"power({self.inputs[0]})"

    def setup(self, Z):
        if (Z[:, 0] <= 0).any():
            raise WorkbenchError(
                f"power({self.inputs[0]}) needs a positive covariate; it has values <= 0"
            )
        self.ref = float(np.median(Z[:, 0]))

    def theta_init(self) -> np.ndarray:
        return np.array([0.0, 1.0])

    def theta_bounds(self) -> list[tuple[float, float]]:
        return [(-1e3, 1e3), (-4.0, 4.0)]

    def mean(self, Z, theta):
        return theta[0] * (Z[:, 0] / self.ref) ** theta[1]

    def params(self, h, w):
        return {"a": float(h[0]), "b": float(h[1]), "z_ref": self.ref}


@dataclass
class TermSpec:
    """A term as written by a user: kind, inputs and options, before it meets data."""

    kind: str
    inputs: tuple[str, ...]
    kernel: str = ""
    function: str = ""
    options: dict = field(default_factory=dict)

    def __str__(self) -> str:
        if "text" in self.options:  # a term whose string is not its inputs (tide, seiche)
            return self.options["text"]
        args = ", ".join(self.inputs)
        if self.kind == "gp":
            return f"gp({args}, {self.kernel})"
        if self.kind == "user":
            return f"user({args}, {self.function})"
        if self.kind in ("const", "water_level"):
            return self.kind
        return f"{self.kind}({args})"
