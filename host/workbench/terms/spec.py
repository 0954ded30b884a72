"""Parse model specifications: term strings like `gp(position, matern32)`, `--effects` names and TOML files."""

from __future__ import annotations

import tomllib
from collections.abc import Callable
from pathlib import Path

from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.terms.base import TermSpec
from forcemap.host.workbench.terms.registry import from_table, parse_term
from forcemap.host.workbench.terms.user import load_function

BASELINE = ["const", "gp(position, matern32)"]


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

    for spec in parse_terms(texts, is_circular):
        if spec.function:
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
    inputs = table.get("inputs", table.get("input", []))
    inputs = [inputs] if isinstance(inputs, str) else inputs
    if not isinstance(inputs, list) or not all(isinstance(x, str) for x in inputs):
        raise WorkbenchError(f'{where}: inputs must be a list of column names, e.g. ["depth"]')
    if not inputs and kind != "const":
        raise WorkbenchError(f'{where}: a {kind} term needs inputs, e.g. inputs = ["depth"]')
    return from_table(kind, where, inputs, table)


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
