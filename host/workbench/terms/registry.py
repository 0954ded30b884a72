"""The term registry: every term kind declared once, with its name, parser, builder, TOML form and the
class whose attributes are its capabilities (`terms/base.py`'s `Term`).

A new kind is one module (its `Term` subclass, its parser and builder) and one `register(...)` line below;
`docs/TERMS.md` walks through one. Everything else in the workbench asks this module: what a term string
is (`parse_term`), what it builds (`build_term`), and what it can do (`caps`, `in_time`, `periods_s`, ...).
"""

from __future__ import annotations

import re
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field

from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.terms import (
    clock_offset,
    gp,
    level,
    reference_tide,
    seiche,
    simple,
    tide,
    user,
)
from forcemap.host.workbench.terms.base import Term, TermSpec

IsCircular = Callable[[str], bool]
_CALL = re.compile(r"^\s*(\w+)\s*\((.*)\)\s*$")


def _generic_table(kind: str) -> Callable[[str, list[str], dict], str]:
    def from_table(where: str, inputs: list[str], table: dict) -> str:
        return f"{kind}({', '.join(inputs)})"

    return from_table


@dataclass(frozen=True)
class TermKind:
    """One kind of term. `parse(args, text, is_circular)` reads a term string (`args` None when the kind
    is written alone, `tide`; else the arguments inside its parentheses); `build(spec, is_circular)` makes
    the term; `cls` carries the capabilities; `from_table(where, inputs, table)` turns a TOML `[[term]]`
    table into the term string; `periods(spec)` the periods a spec may oscillate at before it meets data;
    `uniform(spec)` the form without variation over the reach (a vector's flow frame fits that);
    `in_time_if(spec)` whether a spec of a kind not in time by class is in time all the same (`gp(t)`);
    `referenced(spec)` what the spec becomes on a survey with a reference current (a harmonic tide
    becomes its relation to the reference); `summary` one line for `--help` and docs/TERMS.md."""

    name: str
    cls: type[Term]
    parse: Callable[[list[str] | None, str, IsCircular], TermSpec]
    build: Callable[[TermSpec, IsCircular], Term]
    summary: str
    from_table: Callable[[str, list[str], dict], str] | None = None
    periods: Callable[[TermSpec], list[float]] = field(default=lambda spec: [])
    uniform: Callable[[TermSpec], str] = field(default=str)
    in_time_if: Callable[[TermSpec], bool] = field(default=lambda spec: False)
    referenced: Callable[[TermSpec], TermSpec] = field(default=lambda spec: spec)


KINDS: dict[str, TermKind] = {}


def register(kind: TermKind) -> TermKind:
    """Declare a term kind; its name must be new."""
    if kind.name in KINDS:
        raise ValueError(f"term kind {kind.name!r} is registered twice")
    KINDS[kind.name] = kind
    return kind


def _user_parse(args: list[str] | None, text: str, is_circular: IsCircular) -> TermSpec:
    if args is None or len(args) != 2 or ":" not in args[1]:
        raise WorkbenchError(f"'{text}': write a user term as user(covariate, module:function)")
    return TermSpec("user", (args[0],), function=args[1], text=f"user({args[0]}, {args[1]})")


def _user_table(where: str, inputs: list[str], table: dict) -> str:
    function = table.get("function")
    if not isinstance(function, str):
        raise WorkbenchError(f'{where}: a user term needs function = "module:function"')
    return f"user({inputs[0]}, {function})"


# fmt: off
register(TermKind("gp", gp.HilbertGPTerm, gp.parse_gp, gp.build_gp,
                  "a Gaussian process in 1-3 inputs: gp(position, matern32), gp(heading, periodic)",
                  from_table=gp.gp_from_table, in_time_if=gp.gp_in_time))
register(TermKind("linear", gp.LinearTerm, simple.one_covariate("linear"),
                  lambda s, c: gp.LinearTerm(s.inputs), "a slope in one covariate: linear(depth)",
                  from_table=_generic_table("linear")))
register(TermKind("power", simple.PowerTerm, simple.one_covariate("power"),
                  lambda s, c: simple.PowerTerm(s.inputs[0]),
                  "a power law as a mean function: power(depth)", from_table=_generic_table("power")))
register(TermKind("cos", simple.CosineTerm, simple.one_covariate("cos"), simple.build_cos,
                  "a cosine of a compass angle: cos(heading)", from_table=_generic_table("cos")))
register(TermKind("user", user.UserTerm, _user_parse, lambda s, c: user.UserTerm(s.inputs[0], s.function),
                  "your own function as a mean function: user(depth, mylaws:manning)",
                  from_table=_user_table))
register(TermKind("const", simple.ConstTerm, simple.parse_const, lambda s, c: simple.ConstTerm(),
                  "the mean level: const", from_table=lambda where, inputs, table: "const"))
register(TermKind("tide", tide.TideTerm, tide.parse_tide,
                  lambda s, c: tide.TideTerm(s.options.get("constituents", ()),
                                             spatial="position" in s.inputs),
                  "the astronomical tide's constituents: tide, tide(M2, K1), tide(position)",
                  periods=tide.spec_periods, uniform=tide.uniform_text,
                  referenced=reference_tide.referenced))
register(TermKind(reference_tide.KIND, reference_tide.ReferenceTideTerm, reference_tide.parse,
                  reference_tide.build,
                  "the tide as a subordinate station of a reference current (--reference-current): "
                  "tide(reference, position)",
                  periods=reference_tide.spec_periods, uniform=reference_tide.uniform_text))
register(TermKind("seiche", seiche.SeicheTerm, seiche.parse_seiche,
                  lambda s, c: seiche.SeicheTerm(s.options.get("period_s"), s.options.get("harmonics", 1)),
                  "an oscillation whose period the data give: seiche, seiche(74 min)",
                  periods=seiche.spec_periods))
register(TermKind("water_level", level.WaterLevelTerm, level.parse_water_level,
                  lambda s, c: level.WaterLevelTerm(),
                  "the water surface's level under every sounding, smooth in time: water_level"))
register(TermKind(clock_offset.NAME, clock_offset.ClockOffsetTerm, clock_offset.parse_clock_offset,
                  clock_offset.build_clock_offset,
                  "the clock offset between a vector's sources, undone: clock_offset, clock_offset(+1.5 s)"))
# fmt: on


def load_entry_points(group: str = "forcemap.terms") -> list[str]:
    """Register the kinds other packages declare as entry points in `group` (each a `TermKind`), so a
    lab's own term needs no change to forcemap; a kind that cannot be loaded is named, not fatal."""
    from importlib.metadata import entry_points

    problems = []
    for ep in entry_points(group=group):
        try:
            kind = ep.load()
            if kind.name not in KINDS:
                register(kind)
        except Exception as exc:  # a broken plug-in must not stop the workbench
            problems.append(f"term kind {ep.name!r} from {ep.value}: {exc}")
    return problems


for _problem in load_entry_points():
    warnings.warn(_problem, stacklevel=1)


def names() -> tuple[str, ...]:
    """The registered kinds' names, in registration order."""
    return tuple(KINDS)


def kind_of(spec: TermSpec) -> TermKind:
    return KINDS[spec.kind]


def parse_term(text: str, is_circular: IsCircular) -> TermSpec:
    """A term string as its spec: a kind written alone (`const`, `tide`), a kind with its arguments
    (`gp(depth, matern32)`, `power(depth)`), or a bare covariate name, which becomes its default GP."""
    text = text.strip()
    if text in KINDS:
        return KINDS[text].parse(None, text, is_circular)
    m = _CALL.match(text)
    if not m:
        return gp.default_gp(text, is_circular)
    name = m.group(1).lower()
    if name not in KINDS:
        raise WorkbenchError(f"unknown term kind '{name}' in '{text}'; kinds are {', '.join(KINDS)}")
    args = [a.strip() for a in m.group(2).split(",") if a.strip()]
    return KINDS[name].parse(args, text, is_circular)


def build_term(spec: TermSpec, is_circular: IsCircular) -> Term:
    """The estimator term for a spec (data-dependent setup happens at fit time)."""
    return kind_of(spec).build(spec, is_circular)


def caps(spec: TermSpec) -> type[Term]:
    """The capabilities of a spec's kind (the class attributes of `terms/base.py`'s `Term`)."""
    return kind_of(spec).cls


def in_time(spec: TermSpec) -> bool:
    """Whether a term is a function of time: a kind in time, or a GP in time alone."""
    kind = kind_of(spec)
    return kind.cls.in_time or kind.in_time_if(spec)


def periods_s(spec: TermSpec) -> list[float]:
    """The periods (s) a spec may oscillate at before it meets data (none for a term without one)."""
    return kind_of(spec).periods(spec)


def uniform(spec: TermSpec) -> str:
    """The spec's form without variation over the reach, as a term string."""
    return kind_of(spec).uniform(spec)


def with_reference(spec: TermSpec) -> TermSpec:
    """What a spec becomes on a survey with a reference current (a harmonic `tide`: its relation to the
    reference, `tide(reference, position)`); most kinds stay as they are."""
    return kind_of(spec).referenced(spec)


def from_table(kind: str, where: str, inputs: list[str], table: dict) -> str:
    """A TOML `[[term]]` table of `kind` as its term string."""
    if kind not in KINDS or KINDS[kind].from_table is None:
        tables = [k for k, v in KINDS.items() if v.from_table is not None]
        raise WorkbenchError(f"{where}: kind must be one of {', '.join(tables)}, not {kind!r}")
    return KINDS[kind].from_table(where, inputs, table)


def split_data_terms(specs: list[TermSpec]) -> tuple[list[TermSpec], list[TermSpec]]:
    """The model's sum terms, and the terms that act on the survey before the model (a clock offset)."""
    model = [s for s in specs if not caps(s).acts_on_data]
    data = [s for s in specs if caps(s).acts_on_data]
    return model, data


def corrections(texts: list[str], is_circular: IsCircular) -> list[str]:
    """The term strings among `texts` that act on the survey before the model (a clock offset)."""
    return [t for t in texts if caps(parse_term(t, is_circular)).acts_on_data]
