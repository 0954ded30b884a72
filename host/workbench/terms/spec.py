"""Parse model specifications: term strings like `gp(position, matern32)`, `--effects` names and TOML files."""

from __future__ import annotations

import re
import tomllib
from collections.abc import Callable
from pathlib import Path

from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.terms.base import (
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
    WaterLevelTerm,
)
from forcemap.host.workbench.terms.seiche import SeicheTerm, parse_seiche
from forcemap.host.workbench.terms.tide import TideTerm, parse_tide
from forcemap.host.workbench.terms.user import UserTerm, load_function

BASELINE = ["const", "gp(position, matern32)"]
KINDS = ("gp", "linear", "power", "cos", "user", "const", "tide", "seiche")
# terms in time that predict beyond the survey (host/workbench/terms/tide.py, seiche.py)
TIME_KINDS = ("tide", "seiche")
_CALL = re.compile(r"^\s*(\w+)\s*\((.*)\)\s*$")
_NAME = re.compile(r"[A-Za-z_]\w*")
# a last gp argument that reads like a kernel name is one, even when it is misspelt
_KERNEL_LIKE = re.compile(
    r"(?i)(matern|rbf|periodic|linear|exp|se$|gauss|laplace|cos|sin|poly|white)"
)


def parse_term(text: str, is_circular: Callable[[str], bool]) -> TermSpec:
    """`gp(depth, matern32)`, `power(depth)`, `cos(heading)`, `user(depth, mod:fn)`, `const`, or a bare
    covariate name, which becomes its default term: a periodic GP for an angle, a Matern 3/2 GP otherwise."""
    text = text.strip()
    if text == "const":
        return TermSpec("const", ())
    if text == "water_level":
        return TermSpec("water_level", ("t",))
    if text in TIME_KINDS:
        return parse_tide([], text) if text == "tide" else parse_seiche([], text)
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
    if kind == "tide":
        return parse_tide(args, text)
    if kind == "seiche":
        return parse_seiche(args, text)
    if kind == "gp":
        if len(args) < 1:
            raise WorkbenchError(f"'{text}': a gp term needs inputs, e.g. gp(position, matern32)")
        kernel = "matern32"
        if args[-1].lower() in KERNELS or args[-1].lower() in KERNEL_ALIASES:
            kernel = KERNEL_ALIASES.get(args[-1].lower(), args[-1].lower())
            args = args[:-1]
        elif len(args) > 1 and _KERNEL_LIKE.match(args[-1]):
            raise WorkbenchError(
                f"'{text}': unknown kernel '{args[-1]}'; kernels are {', '.join(KERNELS)}"
            )
        for a in args:
            if not _NAME.fullmatch(a):
                raise WorkbenchError(f"'{text}': '{a}' is not a column name")
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
    if spec.kind == "water_level":
        return WaterLevelTerm()
    if spec.kind == "tide":
        return TideTerm(spec.options.get("constituents", ()), spatial="position" in spec.inputs)
    if spec.kind == "seiche":
        return SeicheTerm(spec.options.get("period_s"), spec.options.get("harmonics", 1))
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


def check_terms(texts: list[str]) -> None:
    """Parse every term and import every user function: the checks that need no data, made up front."""
    from forcemap.host.workbench.survey.table import is_circular
    from forcemap.host.workbench.terms.clock_offset import split_terms

    for spec in parse_terms(split_terms(texts)[0], is_circular):
        if spec.kind == "user":
            load_function(spec.function)


def _read_toml(path: Path) -> dict:
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise WorkbenchError(f"{path}: no such model spec") from None
    except IsADirectoryError:
        raise WorkbenchError(f"{path} is a folder; give a TOML model spec file") from None
    except OSError as exc:
        raise WorkbenchError(
            f"{path}: cannot read the model spec ({exc.strerror or exc})"
        ) from None
    try:
        return tomllib.loads(raw.decode("utf-8-sig"))
    except UnicodeDecodeError:
        raise WorkbenchError(f"{path}: not a TOML text file (it is not UTF-8 text)") from None
    except tomllib.TOMLDecodeError as exc:
        raise WorkbenchError(f"{path}: not valid TOML ({exc})") from None


def _term_table_text(path: Path, i: int, table: object) -> str:
    """One `[[term]]` table as a term string."""
    where = f"{path}: [[term]] number {i + 1}"
    if not isinstance(table, dict):
        raise WorkbenchError(f"{where} is not a table")
    kind = table.get("kind", "gp")
    if kind not in KINDS:
        raise WorkbenchError(f"{where}: kind must be one of {', '.join(KINDS)}, not {kind!r}")
    inputs = table.get("inputs", table.get("input", []))
    inputs = [inputs] if isinstance(inputs, str) else inputs
    if not isinstance(inputs, list) or not all(isinstance(x, str) for x in inputs):
        raise WorkbenchError(f'{where}: inputs must be a list of column names, e.g. ["depth"]')
    if kind == "const":
        return "const"
    if not inputs:
        raise WorkbenchError(f'{where}: a {kind} term needs inputs, e.g. inputs = ["depth"]')
    if kind == "gp":
        kernel = table.get("kernel", "matern32")
        if not isinstance(kernel, str):
            raise WorkbenchError(f"{where}: kernel must be a name, one of {', '.join(KERNELS)}")
        if kernel.lower() not in KERNELS and kernel.lower() not in KERNEL_ALIASES:
            raise WorkbenchError(
                f"{where}: unknown kernel '{kernel}'; kernels are {', '.join(KERNELS)}"
            )
        return f"gp({', '.join(inputs + [kernel])})"
    if kind == "user":
        function = table.get("function")
        if not isinstance(function, str):
            raise WorkbenchError(f'{where}: a user term needs function = "module:function"')
        return f"user({inputs[0]}, {function})"
    return f"{kind}({', '.join(inputs)})"


def read_spec_file(path: str | Path) -> tuple[list[str], str | None]:
    """A TOML model spec: `terms = ["const", "gp(position, matern32)", ...]` or `[[term]]` tables
    with `kind`, `inputs`, `kernel`, `function`; optional `target`. Returns term strings and the target."""
    path = Path(path)
    data = _read_toml(path)
    unknown = set(data) - {"terms", "term", "target"}
    if unknown:
        raise WorkbenchError(
            f"{path}: unknown key(s) {', '.join(sorted(unknown))}; a spec has terms, [[term]] and target"
        )
    terms = data.get("terms", [])
    if not isinstance(terms, list) or not all(isinstance(t, str) for t in terms):
        raise WorkbenchError(
            f'{path}: terms must be a list of strings, e.g. terms = ["const", "gp(position, matern32)"]'
        )
    tables = data.get("term", [])
    if not isinstance(tables, list):
        raise WorkbenchError(f"{path}: write each term table as [[term]]")
    texts = list(terms) + [_term_table_text(path, i, t) for i, t in enumerate(tables)]
    if not texts:
        raise WorkbenchError(
            f"{path}: the spec has no terms (write terms = [...] or [[term]] tables)"
        )
    target = data.get("target")
    if target is not None and not isinstance(target, str):
        raise WorkbenchError(f'{path}: target must be a column name, e.g. target = "depth"')
    return texts, target
