"""The simple kinds: `const` (the mean level), `cos(ANGLE)` (a cosine of a compass angle) and
`power(COVARIATE)` (a power law as a mean function)."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.terms.base import Hyper, Term, TermSpec


class ConstTerm(Term):
    """A constant offset with a broad, fitted prior: the model's mean level."""

    kind = "const"
    is_constant = True

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


class CosineTerm(Term):
    """a*cos(angle - phase): two features cos, sin of a compass angle in degrees."""

    kind = "cos"

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


class PowerTerm(Term):
    """Mean function a * (z / z_ref)^b for a positive covariate (a power law, e.g. Manning's depth^(2/3))."""

    kind = "power"
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


def parse_const(args: list[str] | None, text: str, is_circular: Callable[[str], bool]) -> TermSpec:
    """`const`, alone."""
    if args is not None:
        raise WorkbenchError(f"'{text}': write const alone")
    return TermSpec("const", (), text="const")


def one_covariate(kind: str) -> Callable[..., TermSpec]:
    """The parser of a kind that takes one covariate: `cos(heading)`, `power(depth)`, `linear(depth)`."""

    def parse(args: list[str] | None, text: str, is_circular: Callable[[str], bool]) -> TermSpec:
        if args is None or len(args) != 1:
            raise WorkbenchError(f"'{text}': {kind}() takes one covariate")
        return TermSpec(kind, (args[0],), text=f"{kind}({args[0]})")

    return parse


def build_cos(spec: TermSpec, is_circular: Callable[[str], bool]) -> Term:
    if not is_circular(spec.inputs[0]):
        raise WorkbenchError(f"cos({spec.inputs[0]}) needs an angle column (heading, cog, *_dir)")
    return CosineTerm(spec.inputs[0])
