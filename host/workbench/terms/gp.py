"""The Gaussian-process kinds: `gp(INPUTS, KERNEL)` and a bare covariate name.

A GP term over continuous inputs uses the Hilbert-space reduced-rank approximation (Solin & Sarkka 2020):
Laplacian eigenfunctions on a box around the data are the features and the kernel's spectral density
gives each feature's prior variance. The features do not depend on the hyperparameters, so the model's
sufficient statistics (Phi'Phi, Phi'y) are computed once and every marginal-likelihood evaluation costs
O(M^3) whatever the number of samples. An angle takes the periodic kernel, as its exact Fourier series;
the `linear` kernel is a slope per standardized input.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable

import numpy as np
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.terms.base import Hyper, Term, TermSpec, span_words
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


class LinearTerm(Term):
    """Linear in standardized inputs: a fitted slope per input (kernel `linear`)."""

    kind = "linear"

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


class PeriodicTerm(Term):
    """GP with the periodic kernel exp(-2 sin^2(d/2)/l^2) on a compass angle, as its exact Fourier series."""

    kind = "gp"

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

    kind = "gp"
    grows_basis = True

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
        """u_d = (z_d + L_d) pi / 2 L_d per rotated input axis: feature j is prod_d sin(J_jd u_d) / sqrt(L_d).
        Beyond the box every feature vanishes, as on its edge (an input is held there): the sines'
        periodic continuation would mirror the map into places no data saw; the GP reverts to its mean."""
        Zr = np.clip((Z - self.center) @ self.rot, -self.L, self.L)
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

    def note_at(self, h: np.ndarray, away_s: float, when: str) -> str | None:
        if "t" not in self.inputs:
            return None
        ell = math.exp(h[self.hyper_index("lengthscale")])
        if away_s <= ell:
            return None
        return (
            f"{self.describe()}: {when}, {away_s / ell:.0f} times its lengthscale ({span_words(ell)}): "
            "it has reverted to its mean there, and the map is the survey's average for it, not a "
            "forecast (a tide term predicts: --effects tide)"
        )

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


TIME_INPUTS = frozenset({"t", "utc"})
_NAME = re.compile(r"[A-Za-z_]\w*")
# a last gp argument that reads like a kernel name is one, even when it is misspelt
_KERNEL_LIKE = re.compile(
    r"(?i)(matern|rbf|periodic|linear|exp|se$|gauss|laplace|cos|sin|poly|white)"
)


def default_gp(name: str, is_circular: Callable[[str], bool]) -> TermSpec:
    """A bare covariate name's term: a periodic GP for an angle, a Matern 3/2 GP otherwise."""
    if not _NAME.fullmatch(name):
        raise WorkbenchError(
            f"cannot read term '{name}'; write e.g. depth, gp(depth, matern32) or power(depth)"
        )
    kernel = "periodic" if is_circular(name) else "matern32"
    return TermSpec("gp", (name,), kernel, text=f"gp({name}, {kernel})")


def parse_gp(args: list[str] | None, text: str, is_circular: Callable[[str], bool]) -> TermSpec:
    """`gp(depth)`, `gp(position, matern32)`, `gp(depth, t, rbf)`: inputs, then an optional kernel."""
    if not args:
        raise WorkbenchError(f"'{text}': a gp term needs inputs, e.g. gp(position, matern32)")
    kernel = "matern32"
    if args[-1].lower() in KERNELS or args[-1].lower() in KERNEL_ALIASES:
        kernel = KERNEL_ALIASES.get(args[-1].lower(), args[-1].lower())
        args = args[:-1]
    elif len(args) > 1 and _KERNEL_LIKE.match(args[-1]):
        raise WorkbenchError(f"'{text}': unknown kernel '{args[-1]}'; kernels are {', '.join(KERNELS)}")
    for a in args:
        if not _NAME.fullmatch(a):
            raise WorkbenchError(f"'{text}': '{a}' is not a column name")
    if not args:
        raise WorkbenchError(f"'{text}': a gp term needs at least one input")
    if len(args) == 1 and is_circular(args[0]) and kernel != "linear":
        kernel = "periodic"
    return TermSpec("gp", tuple(args), kernel, text=f"gp({', '.join(args)}, {kernel})")


def build_gp(spec: TermSpec, is_circular: Callable[[str], bool]) -> Term:
    """The GP term for a spec: a slope for `linear`, a Fourier series for an angle, else a Hilbert GP."""
    inputs = spec.inputs
    if spec.kernel == "linear":
        return LinearTerm(inputs, label="gp")
    if spec.kernel == "periodic":
        if len(inputs) != 1 or not is_circular(inputs[0]):
            raise WorkbenchError(
                f"{spec}: the periodic kernel takes one angle column (heading, cog, *_dir)"
            )
        return PeriodicTerm(inputs[0])
    if any(is_circular(i) for i in inputs):
        raise WorkbenchError(f"{spec}: angles go in a gp term of their own, gp(ANGLE, periodic)")
    dims = sum(2 if i == "position" else 1 for i in inputs)
    if dims > 3:
        raise WorkbenchError(
            f"{spec}: a gp term takes at most 3 input dimensions (position counts as 2)"
        )
    return HilbertGPTerm(inputs, spec.kernel, dims=dims)


def gp_in_time(spec: TermSpec) -> bool:
    """A GP with time among its inputs (`gp(t, matern32)`, `gp(position, t)`) changes in time."""
    return bool(TIME_INPUTS & set(spec.inputs))


def gp_from_table(where: str, inputs: list[str], table: dict) -> str:
    """A `[[term]]` table of kind gp as its term string (`kernel` optional)."""
    kernel = table.get("kernel", "matern32")
    if not isinstance(kernel, str):
        raise WorkbenchError(f"{where}: kernel must be a name, one of {', '.join(KERNELS)}")
    if kernel.lower() not in KERNELS and kernel.lower() not in KERNEL_ALIASES:
        raise WorkbenchError(f"{where}: unknown kernel '{kernel}'; kernels are {', '.join(KERNELS)}")
    return f"gp({', '.join(inputs + [kernel])})"
