"""Parse model specifications: term strings like `gp(position, matern32)`, `--effects` names and TOML files."""

from __future__ import annotations

import re
import tomllib
from collections.abc import Callable
from pathlib import Path

from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.terms import (
    KERNEL_ALIASES,
    KERNELS,
    ConstTerm,
    CosineTerm,
    HilbertGPTerm,
    LinearTerm,
    PeriodicTerm,
    PowerTerm,
    Term,
    TermSpec,
    UserTerm,
)

BASELINE = ["const", "gp(position, matern32)"]
KINDS = ("gp", "linear", "power", "cos", "user", "const")
_CALL = re.compile(r"^\s*(\w+)\s*\((.*)\)\s*$")


def parse_term(text: str, is_circular: Callable[[str], bool]) -> TermSpec:
    """`gp(depth, matern32)`, `power(depth)`, `cos(heading)`, `user(depth, mod:fn)`, `const`, or a bare
    covariate name, which becomes its default term: a periodic GP for an angle, a Matern 3/2 GP otherwise."""
    text = text.strip()
    if text == "const":
        return TermSpec("const", ())
    m = _CALL.match(text)
    if not m:
        if not re.fullmatch(r"[A-Za-z_][\w]*", text):
            raise WorkbenchError(
                f"cannot read term '{text}'; write e.g. depth, gp(depth, matern32) or power(depth)"
            )
        return TermSpec("gp", (text,), "periodic" if is_circular(text) else "matern32")
    kind, args = m.group(1).lower(), [a.strip() for a in m.group(2).split(",") if a.strip()]
    if kind not in KINDS:
        raise WorkbenchError(
            f"unknown term kind '{kind}' in '{text}'; kinds are {', '.join(KINDS)}"
        )
    if kind == "gp":
        if len(args) < 1:
            raise WorkbenchError(f"'{text}': a gp term needs inputs, e.g. gp(position, matern32)")
        kernel = "matern32"
        if args[-1].lower() in KERNELS or args[-1].lower() in KERNEL_ALIASES:
            kernel = KERNEL_ALIASES.get(args[-1].lower(), args[-1].lower())
            args = args[:-1]
        if not args:
            raise WorkbenchError(f"'{text}': a gp term needs at least one input")
        if len(args) == 1 and is_circular(args[0]) and kernel != "linear":
            kernel = "periodic"
        return TermSpec("gp", tuple(args), kernel)
    if kind == "user":
        if len(args) != 2 or ":" not in args[1]:
            raise WorkbenchError(f"'{text}': write a user term as user(covariate, module:function)")
        return TermSpec("user", (args[0],), function=args[1])
    if len(args) != 1:
        raise WorkbenchError(f"'{text}': {kind}() takes one covariate")
    return TermSpec(kind, (args[0],))


def build_term(spec: TermSpec, is_circular: Callable[[str], bool]) -> Term:
    """The estimator term for a spec (data-dependent setup happens at fit time)."""
    if spec.kind == "const":
        return ConstTerm()
    if spec.kind == "linear":
        return LinearTerm(spec.inputs)
    if spec.kind == "cos":
        if not is_circular(spec.inputs[0]):
            raise WorkbenchError(
                f"cos({spec.inputs[0]}) needs an angle column (heading, cog, *_dir)"
            )
        return CosineTerm(spec.inputs[0])
    if spec.kind == "power":
        return PowerTerm(spec.inputs[0])
    if spec.kind == "user":
        return UserTerm(spec.inputs[0], spec.function)
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


def parse_terms(texts: list[str], is_circular: Callable[[str], bool]) -> list[TermSpec]:
    out: list[TermSpec] = []
    for t in texts:
        spec = parse_term(t, is_circular)
        if str(spec) not in {str(s) for s in out}:
            out.append(spec)
    return out


def split_effects(text: str | None) -> list[str]:
    """`depth,t,gp(heading, periodic)` -> items, keeping commas inside parentheses."""
    if not text:
        return []
    items, depth, cur = [], 0, ""
    for ch in text:
        if ch == "," and depth == 0:
            items.append(cur)
            cur = ""
            continue
        depth += ch == "("
        depth -= ch == ")"
        cur += ch
    items.append(cur)
    return [i.strip() for i in items if i.strip()]


def read_spec_file(path: str | Path) -> tuple[list[str], str | None]:
    """A TOML model spec: `terms = ["const", "gp(position, matern32)", ...]` or `[[term]]` tables
    with `kind`, `inputs`, `kernel`, `function`; optional `target`. Returns term strings and the target."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise WorkbenchError(f"{path}: no such model spec") from None
    except tomllib.TOMLDecodeError as exc:
        raise WorkbenchError(f"{path}: not valid TOML ({exc})") from None
    texts: list[str] = [str(t) for t in data.get("terms", [])]
    for table in data.get("term", []):
        kind = table.get("kind", "gp")
        inputs = table.get("inputs", table.get("input", []))
        inputs = [inputs] if isinstance(inputs, str) else list(inputs)
        if kind == "gp":
            texts.append(f"gp({', '.join(inputs + [table.get('kernel', 'matern32')])})")
        elif kind == "user":
            texts.append(f"user({inputs[0]}, {table['function']})")
        elif kind == "const":
            texts.append("const")
        else:
            texts.append(f"{kind}({', '.join(inputs)})")
    if not texts:
        raise WorkbenchError(
            f"{path}: the spec has no terms (write terms = [...] or [[term]] tables)"
        )
    return texts, data.get("target")
