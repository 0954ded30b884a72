"""The shape of the package, read from its source with `ast`: imports point one way, modules stay small.

- host's rooms import only the rooms above them on docs/ARCHITECTURE.md's page.
- No cycle among the modules of `forcemap` (every import counts: top level, inside functions, under
  TYPE_CHECKING). A failure names the cycle.
- `host` imports `sim_devices` only in the simulator's own commands (`host/cli/sim.py`, `host/cli/demo.py`).
- No module over MAX_MODULE_LINES lines, no function over MAX_FUNCTION_LINES; modules over SIGNAL_MODULE_LINES
  are reported (a signal to split by meaning, not a wall).
- Nothing outside the term registry's room (`host/workbench/terms/`) dispatches on a term's class or kind
  string: it asks the capability (`terms/registry.py`, `terms/base.py`).
- Every module is named in docs/ARCHITECTURE.md by its path (a package by its folder, `host/vessel/`).

Run as a script, it prints each module's imports of the package and the cycles, if any.
"""

from __future__ import annotations

import ast
import importlib
import sys
from pathlib import Path

PACKAGES = (
    "forcemap",
    "forcemap.host",
    "forcemap.protocol",
    "forcemap.sim_devices",
    "forcemap.firmware_bridge",
)
SIM_COMMANDS = {"forcemap.host.cli.sim", "forcemap.host.cli.demo"}
# host's rooms in import order (docs/ARCHITECTURE.md): "host" is its top-level modules
ROOMS = [
    "host", "vessel", "log", "acquire", "decode", "fuse", "convert", "workbench", "qa", "plan", "gis",
    "report",
    "season",
    "live", "api", "cli",
]  # fmt: skip
MAX_MODULE_LINES = 600
SIGNAL_MODULE_LINES = 400
MAX_FUNCTION_LINES = 80
ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "ARCHITECTURE.md"


def modules() -> dict[str, Path]:
    """Every module of the installed package: dotted name -> file (`forcemap` itself is `api/`)."""
    out: dict[str, Path] = {}
    for pkg in PACKAGES:
        for root in importlib.import_module(pkg).__path__:
            files = [Path(root) / "__init__.py"] if pkg == "forcemap" else Path(root).rglob("*.py")
            for f in sorted(files):
                parts = f.relative_to(root).with_suffix("").parts
                if parts[-1] == "__init__":
                    parts = parts[:-1]
                out[".".join((pkg, *parts))] = f
    return out


def repo_path(name: str, file: Path) -> str:
    """The module's path in the repository: `host/vessel/geodesy.py`, a package as `host/vessel/`. From the
    name, as pyproject's package-dir maps it, since the package may be installed anywhere (`forcemap` is `api/`,
    `forcemap.host` is `host/`)."""
    parts = name.split(".")
    path = "/".join(["api"] if len(parts) == 1 else parts[1:])
    return path + "/" if file.name == "__init__.py" else path + ".py"


def imports_of(name: str, file: Path, known: set[str]) -> set[str]:
    """The package's modules that ``name`` imports anywhere in its source."""
    is_pkg = file.name == "__init__.py"
    here = name if is_pkg else name.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(file.read_text(), str(file))):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = here.split(".")
                anchor = anchor[: len(anchor) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            # `from pkg import mod` imports the module pkg.mod; `from mod import name` imports mod
            targets = [
                f"{base}.{a.name}" if f"{base}.{a.name}" in known else base for a in node.names
            ]
        else:
            continue
        for t in targets:
            while t and t not in known:
                t = t.rpartition(".")[0]
            if t and t != name:
                found.add(t)
    return found


def import_graph() -> dict[str, set[str]]:
    mods = modules()
    known = set(mods)
    return {name: imports_of(name, f, known) for name, f in mods.items()}


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle as [a, b, ..., a], or None (iterative depth-first search)."""
    state: dict[str, int] = {}  # 1 on the current path, 2 done
    for start in sorted(graph):
        if start in state:
            continue
        path = [start]
        stack = [iter(sorted(graph[start]))]
        state[start] = 1
        while stack:
            nxt = next(stack[-1], None)
            if nxt is None:
                state[path.pop()] = 2
                stack.pop()
            elif state.get(nxt) == 1:
                return path[path.index(nxt) :] + [nxt]
            elif nxt not in state:
                state[nxt] = 1
                path.append(nxt)
                stack.append(iter(sorted(graph.get(nxt, ()))))
    return None


def test_no_import_cycle():
    cycle = find_cycle(import_graph())
    assert cycle is None, "import cycle: " + " -> ".join(cycle or [])


def test_cycle_finder_finds_a_cycle():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set(), "c": {"a", "b"}}) is None


def test_host_uses_the_simulator_only_in_its_commands():
    graph = import_graph()
    bad = sorted(
        f"{m} -> {t}"
        for m, ts in graph.items()
        if m.startswith("forcemap.host") and m not in SIM_COMMANDS
        for t in ts
        if t.startswith("forcemap.sim_devices")
    )
    assert not bad, "host imports the simulator outside cli/sim.py and cli/demo.py:\n" + "\n".join(
        bad
    )


def room_of(module: str) -> str:
    parts = module.split(".")
    if module == "forcemap.host.api":
        return "api"
    if parts[1] != "host":
        return parts[1]
    return parts[2] if len(parts) > 3 or f"host/{parts[2]}" in ROOM_PACKAGES else "host"


ROOM_PACKAGES = {f"host/{r}" for r in ROOMS if r != "host"}


def test_rooms_import_only_rooms_above_them():
    """docs/ARCHITECTURE.md's order: a room imports its own modules and those of the rooms above it
    (so the report, above the workbench and the plan, is imported by the commands alone)."""
    graph = import_graph()
    bad = sorted(
        f"{m} -> {t}"
        for m, ts in graph.items()
        if m.startswith("forcemap.host")
        for t in ts
        if t.startswith("forcemap.host") and ROOMS.index(room_of(t)) > ROOMS.index(room_of(m))
    )
    assert not bad, "imports that point up docs/ARCHITECTURE.md's rooms:\n" + "\n".join(bad)
    assert room_of("forcemap.host.workbench.diagnose.rounds") == "workbench"
    assert room_of("forcemap.host.outputs") == "host"


def test_the_simulator_commands_do_use_it():
    """The rule above is not empty: the graph sees those imports (inside functions too)."""
    graph = import_graph()
    assert any(t.startswith("forcemap.sim_devices") for t in graph["forcemap.host.cli.sim"])
    assert "forcemap.host.vessel.geodesy" in graph["forcemap.host.fuse.compensation"]


def test_modules_and_functions_are_small():
    long_modules, long_functions, signals = [], [], []
    for name, f in modules().items():
        text = f.read_text()
        n = len(text.splitlines())
        if n > MAX_MODULE_LINES:
            long_modules.append(f"{name}: {n} lines")
        elif n > SIGNAL_MODULE_LINES:
            signals.append(f"{name}: {n} lines")
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                length = node.end_lineno - node.lineno + 1  # type: ignore[operator]
                if length > MAX_FUNCTION_LINES:
                    long_functions.append(
                        f"{name}.{node.name} (line {node.lineno}): {length} lines"
                    )
    if signals:
        import warnings

        warnings.warn(
            f"modules over {SIGNAL_MODULE_LINES} lines (split where the meaning splits): "
            + ", ".join(signals),
            stacklevel=1,
        )
    assert not long_modules and not long_functions, "\n".join(long_modules + long_functions)


def test_every_module_is_in_the_architecture_page():
    doc = DOC.read_text()
    missing = [p for p in (repo_path(n, f) for n, f in modules().items()) if f"`{p}`" not in doc]
    assert not missing, "docs/ARCHITECTURE.md does not name: " + ", ".join(missing)


if __name__ == "__main__":
    g = import_graph()
    for m in sorted(g):
        print(m, "->", ", ".join(sorted(g[m])) or "-")
    c = find_cycle(g)
    print("cycle:", " -> ".join(c) if c else "none")
    sys.exit(1 if c else 0)


def test_every_package_folder_is_installed():
    """A wheel holds only the packages pyproject lists: a folder with an `__init__.py` left out of
    `[tool.setuptools] packages` works from the clone and is missing once installed."""
    import tomllib

    setup = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(setup["packages"])
    wanted = set()
    for pkg, folder in setup["package-dir"].items():
        for init in (ROOT / folder).rglob("__init__.py"):
            rel = init.parent.relative_to(ROOT / folder).parts
            wanted.add(".".join((pkg, *rel)))
    assert wanted - listed == set(), f"packages missing from pyproject: {sorted(wanted - listed)}"


TERMS_ROOM = "forcemap.host.workbench.terms"


def term_dispatch(tree: ast.AST, classes: set[str], kinds: set[str]) -> list[str]:
    """Where a module's source dispatches on a term: `isinstance(x, <a Term subclass>)`, a `.kind` compared
    with a registered kind's name, or a term string tested by `startswith` a kind's name."""
    found = []

    def is_kind_text(node) -> bool:
        values = node.elts if isinstance(node, ast.Tuple) else [node]
        return any(
            isinstance(v, ast.Constant)
            and isinstance(v.value, str)
            and (v.value in kinds or v.value.split("(")[0] in kinds and "(" in v.value)
            for v in values
        )

    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "isinstance":
            types = node.args[1] if len(node.args) > 1 else None
            names = types.elts if isinstance(types, ast.Tuple) else [types]
            hit = [n.id for n in names if isinstance(n, ast.Name) and n.id in classes]
            if hit:
                found.append(f"line {node.lineno}: isinstance(..., {', '.join(hit)})")
        elif isinstance(node, ast.Compare):
            sides = [node.left, *node.comparators]
            on_kind = any(isinstance(x, ast.Attribute) and x.attr == "kind" for x in sides)
            if on_kind and any(is_kind_text(x) for x in sides):
                found.append(f"line {node.lineno}: .kind compared with a term kind")
        elif isinstance(node, ast.Call) and getattr(node.func, "attr", None) == "startswith":
            if node.args and is_kind_text(node.args[0]):
                found.append(f"line {node.lineno}: startswith a term kind")
    return found


def test_no_dispatch_on_a_terms_class_or_kind_outside_the_registry():
    from forcemap.host.workbench.terms import registry
    from forcemap.host.workbench.terms.base import Term

    def subclasses(c):
        return {c, *(s for d in c.__subclasses__() for s in subclasses(d))}

    classes = {c.__name__ for c in subclasses(Term)} - {"Term"}
    kinds = set(registry.names()) - {"user"}  # "user" is a word too; its class is still caught
    assert {"TideTerm", "HilbertGPTerm", "ClockOffsetTerm"} <= classes and "water_level" in kinds
    bad = []
    for name, f in modules().items():
        if name.startswith(TERMS_ROOM) or not name.startswith("forcemap.host"):
            continue
        bad += [f"{name} {w}" for w in term_dispatch(ast.parse(f.read_text()), classes, kinds)]
    assert not bad, "ask the term's capability instead:\n" + "\n".join(bad)


def test_the_dispatch_finder_finds_dispatch():
    src = (
        "isinstance(t, TideTerm)\n"
        "s.kind in ('tide', 'seiche')\n"
        "name.startswith('gp(position')\n"
        "c.kind == 'rate'\n"
    )
    found = term_dispatch(ast.parse(src), {"TideTerm"}, {"tide", "seiche", "gp"})
    assert [f.split(":")[0] for f in found] == ["line 1", "line 2", "line 3"]
