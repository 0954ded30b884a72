"""The CLI's one grammar: shared option builders, old spellings, durations, outputs, JSON, notes.

Every option that more than one command takes is declared here, once, so that it means one thing
(docs/CLI.md): ``-o/--output`` for what a command writes, ``--force`` to replace it, ``--json PATH|-``
for machine output, ``--boat BOAT.toml`` for the boat, ``--quiet`` for no progress, ``--effects`` for
model terms, ``--phenomena`` for the simulator's, durations as ``30s``, ``20m``, ``3h``.
An old spelling keeps working for one release through ``add_deprecated``: a one-line note on stderr
names the new spelling, and the value lands where the new option puts it.

Errors are not handled here: a ``CliError`` (``WorkbenchError`` is one) reaches ``forcemap.host.cli.main``,
which prints it on one line and exits 2.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any, TextIO

from forcemap.host.errors import CliError
from forcemap.host.outputs import atomic_write, check_output

# ---------------------------------------------------------------- old spellings


def deprecation_note(prog: str, old: str, new: str) -> None:
    """The one line an old spelling prints on stderr."""
    print(
        f"{prog}: note: {old} is deprecated and goes in the next release; use {new}",
        file=sys.stderr,
    )


class Deprecated(argparse.Action):
    """An old spelling: prints its note, then stores (through ``convert``) into the new option's dest."""

    def __init__(self, option_strings, dest, new: str = "", convert=None, **kwargs):  # type: ignore[no-untyped-def]
        kwargs.setdefault("default", argparse.SUPPRESS)  # the new option's default stands
        kwargs.setdefault("help", argparse.SUPPRESS)
        super().__init__(option_strings, dest, **kwargs)
        self.new = new
        self.convert = convert

    def __call__(self, parser, namespace, values, option_string=None):  # type: ignore[no-untyped-def]
        deprecation_note(parser.prog, option_string or self.dest, self.new)
        value = self.const if self.nargs == 0 else values
        if self.convert is not None:
            try:
                value = self.convert(value)
            except (ValueError, argparse.ArgumentTypeError) as exc:
                raise argparse.ArgumentError(self, str(exc)) from None
        setattr(namespace, self.dest, value)


def add_deprecated(
    parser: argparse.ArgumentParser,
    old: str | tuple[str, ...],
    new: str,
    dest: str,
    *,
    flag: bool = False,
    const: Any = None,
    convert: Callable[[Any], Any] | None = None,
) -> None:
    """Keep ``old`` working for one release: it stores into ``dest`` and names ``new`` on stderr."""
    names = (old,) if isinstance(old, str) else old
    extra: dict[str, Any] = {"nargs": 0, "const": const} if flag else {}
    parser.add_argument(
        *names, dest=dest, action=Deprecated, new=new, convert=convert, **extra
    )  # fmt: skip


# ---------------------------------------------------------------- durations

_UNIT_S = {"h": 3600.0, "m": 60.0, "s": 1.0}
_NUMBER = r"(?:\d+(?:\.\d*)?|\.\d+)"


def parse_duration(text: str) -> float:
    """``30s``, ``20m``, ``3h``, ``1.5h`` or ``1h30m`` to seconds (ValueError otherwise)."""
    compact = text.strip().replace(" ", "").lower()
    parts = re.findall(rf"({_NUMBER})([hms])", compact)
    if not parts or "".join(a + b for a, b in parts) != compact:
        raise ValueError(
            f"bad duration {text!r}: use a number and a unit, e.g. 30s, 20m, 3h, 1h30m"
        )
    return sum(float(v) * _UNIT_S[u] for v, u in parts)


class Duration(argparse.Action):
    """A duration option: ``30s``/``20m``/``3h`` to seconds. A bare number still means
    ``bare_unit`` seconds for one release, with a note asking for the unit."""

    def __init__(self, option_strings, dest, bare_unit: float = 1.0, **kwargs):  # type: ignore[no-untyped-def]
        kwargs.setdefault("metavar", "DURATION")
        super().__init__(option_strings, dest, **kwargs)
        self.bare_unit = bare_unit

    def __call__(self, parser, namespace, values, option_string=None):  # type: ignore[no-untyped-def]
        text = str(values).strip()
        if re.fullmatch(_NUMBER, text):
            seconds = float(text) * self.bare_unit
            deprecation_note(
                parser.prog, f"{option_string} {text} (a number without a unit)",
                f"{option_string} {seconds:g}s",
            )  # fmt: skip
        else:
            try:
                seconds = parse_duration(text)
            except ValueError as exc:
                raise argparse.ArgumentError(self, str(exc)) from None
        setattr(namespace, self.dest, seconds)


def add_duration(
    parser: argparse.ArgumentParser, name: str, default: float | None, help: str, **kwargs: Any
) -> None:
    """A duration option; its value is in seconds (``default`` too)."""
    parser.add_argument(name, action=Duration, default=default, help=help, **kwargs)


def format_duration(seconds: float) -> str:
    """Seconds as a duration the parser reads back (``35m``, ``90s``, ``1.5h``)."""
    for unit in ("h", "m"):
        n = seconds / _UNIT_S[unit]
        if n >= 1 and float(n).is_integer():
            return f"{n:g}{unit}"
    return f"{seconds:g}s"


# ---------------------------------------------------------------- shared options


def add_output(
    parser: argparse.ArgumentParser,
    help: str,
    *,
    required: bool = False,
    force: bool = True,
    **kw: Any,
) -> None:
    """``-o/--output`` (what the command writes: a file, or a folder for several) and ``--force``."""
    parser.add_argument("-o", "--output", required=required, help=help, **kw)
    if force:
        add_force(parser)


def add_force(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--force", action="store_true", help="replace an existing output")


class JsonOrOldFlag(argparse.Action):
    """``--json PATH|-`` where ``--json`` was a flag (``log info``): the bare flag, or the flag followed
    by an .mcap (a log to read, never the output), still prints the JSON on stdout, with a note."""

    def __init__(self, option_strings, dest, **kwargs):  # type: ignore[no-untyped-def]
        super().__init__(option_strings, dest, nargs="?", const=None, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):  # type: ignore[no-untyped-def]
        if values is None or str(values).lower().endswith(".mcap"):
            deprecation_note(parser.prog, "--json without a value", "--json - (or --json PATH)")
            if values is not None:
                namespace.json_files = [*getattr(namespace, "json_files", []), values]
            values = "-"
        setattr(namespace, self.dest, values)


def add_json(
    parser: argparse.ArgumentParser, what: str = "the result", old_flag: bool = False
) -> None:
    """``--json PATH``: the machine-readable result; ``-`` prints nothing but the JSON on stdout.
    ``old_flag``: the command's ``--json`` was a flag, which keeps working for one release."""
    parser.add_argument(
        "--json",
        metavar="PATH",
        action=JsonOrOldFlag if old_flag else "store",
        help=f"write {what} as JSON to PATH; '-' prints only the JSON on stdout (the rest on stderr)",
    )


def add_boat(parser: argparse.ArgumentParser, what: str, old_config: bool = True) -> None:
    """``--boat BOAT.toml`` (and the old ``--config``, with its note, where it was the spelling)."""
    parser.add_argument("--boat", metavar="BOAT.toml", help=what)
    if old_config:
        add_deprecated(parser, "--config", "--boat BOAT.toml", "boat")


def add_quiet(
    parser: argparse.ArgumentParser, what: str = "no progress on stderr; only the results"
) -> None:
    parser.add_argument("--quiet", action="store_true", help=what)


def add_target(parser: argparse.ArgumentParser, what: str = "column to model") -> None:
    """``--target``: the same rule everywhere, this option or else the ``--model`` spec's target."""
    parser.add_argument(
        "--target",
        help=f"{what}, e.g. current_speed, wind_dir, depth (default: the --model spec's target)",
    )


def add_effects(parser: argparse.ArgumentParser, what: str) -> None:
    """``--effects``: model terms (never the simulator's phenomena: those are ``--phenomena``)."""
    parser.add_argument("--effects", metavar="TERMS", help=what)


def add_phenomena(parser: argparse.ArgumentParser, what: str, default: str | None) -> None:
    """``--phenomena``: what the simulator simulates (the old ``--effects``/``--effect`` too)."""
    parser.add_argument("--phenomena", metavar="LIST", default=default, help=what)


def require_target(target: str | None) -> str:
    if not target:
        raise CliError("no target: give --target COLUMN (or target = ... in the --model spec)")
    return target


def human(args: argparse.Namespace) -> TextIO:
    """Where human text goes: stdout, or stderr when stdout carries the JSON (``--json -``)."""
    return sys.stderr if str(getattr(args, "json", None)) == "-" else sys.stdout


def output_for(given: str | None, first_input: str, suffix: str) -> str:
    """The output path: ``given`` (a folder gets the input's name with ``suffix``) or the default."""
    if given is None:
        return str(Path(first_input).with_suffix(suffix))
    if given != "-" and Path(given).is_dir():
        return str(Path(given) / Path(first_input).with_suffix(suffix).name)
    if given.endswith("/"):
        raise CliError(f"the folder {given} does not exist; create it first")
    return given


class Tables(argparse.Action):
    """Several tables: all in ``tables``, the first (whose workspace the survey keeps) in ``table``."""

    def __call__(self, parser, namespace, values, option_string=None):  # type: ignore[no-untyped-def]
        namespace.tables = list(values)
        namespace.table = values[0]


def add_table(parser: argparse.ArgumentParser, several: bool = False) -> None:
    """The samples table; with `several`, one or more (days of the same water as one survey)."""
    if several:
        parser.add_argument(
            "table",
            type=Path,
            nargs="+",
            action=Tables,
            metavar="TABLE",
            help="samples table(s): .csv, .parquet, or an .mcap log from `forcemap run`; several are "
            "one survey (days of the same water), kept in the first one's workspace",
        )
        return
    parser.add_argument(
        "table",
        type=Path,
        help="samples table: .csv, .parquet, or an .mcap log from `forcemap run`",
    )


def add_workspace_options(parser: argparse.ArgumentParser, output: bool = True) -> None:
    """--reset-history, and --force when the command writes a file the user names."""
    parser.add_argument(
        "--reset-history",
        action="store_true",
        help="move a corrupt TABLE.forcemap/history.json aside (kept as history.json.bak-N) and "
        "start a new history",
    )
    if output:
        add_force(parser)


def add_keep_outliers(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--keep-outliers",
        action="store_true",
        help="fit the spikes flagged along the track too (by default they are left out of the fits)",
    )


def add_water_level(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--water-level",
        type=Path,
        metavar="GAUGE.csv",
        help="a water-level gauge's record (USGS RDB/CSV, NOAA CO-OPS CSV, or time,level CSV): the "
        "depth is reduced to the gauge's datum (without it, the term water_level estimates the level "
        "from the survey's crossings)",
    )


def add_reference_current(parser: argparse.ArgumentParser) -> None:
    """--reference-current FILE and --reference-station ID (docs/WORKBENCH.md, "A reference current")."""
    parser.add_argument(
        "--reference-current",
        type=Path,
        metavar="FILE",
        help="a reference current: stations' harmonic constants (NOAA's fields, JSON) or a station's "
        "predicted series (CSV: time, speed along the flood axis, flood direction); the tide on a "
        "current is then each place's ratio and time offset to its nearest station",
    )
    parser.add_argument(
        "--reference-station",
        metavar="ID",
        help="with --reference-current: this station for every place (default: each place's nearest)",
    )


def reference_of(args: argparse.Namespace):
    """The reference current --reference-current names (None without it); a bad file is one line."""
    path = getattr(args, "reference_current", None)
    station = getattr(args, "reference_station", None)
    if path is None:
        if station is not None:
            raise CliError("--reference-station needs --reference-current FILE")
        return None
    from forcemap.host.workbench.survey.reference import load_reference

    return load_reference(path, station)


def load_table(args: argparse.Namespace):
    """The samples table of `args.table` as the workbench's Survey, with --keep-outliers and, when given,
    the depth reduced to --water-level's gauge datum (a bad gauge file is one line and exit 2) and the
    reference current of --reference-current."""
    from forcemap.host.workbench.survey.reference import with_reference
    from forcemap.host.workbench.survey.several import load_surveys

    survey = load_surveys(getattr(args, "tables", None) or args.table, keep_outliers=args.keep_outliers)
    with_reference(survey, reference_of(args))
    gauge = getattr(args, "water_level", None)
    if gauge is None:
        return survey
    from forcemap.host.workbench.depth.water_level import read_gauge, reduce_to_gauge

    return reduce_to_gauge(survey, read_gauge(gauge))


def teach(parser: argparse.ArgumentParser, epilog: str) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = epilog


def prepare_workspace(args: argparse.Namespace, create: bool = False) -> Path:
    """Check the table and the workspace before any heavy work (creating it only with `create`:
    a command that fails leaves no empty folder behind); apply --reset-history."""
    from forcemap.host.workbench.fits.workspace import (
        check_workspace,
        load_history,
        reset_history,
        workspace_dir,
    )

    table = Path(args.table)
    if not table.exists():
        raise CliError(f"{table}: no such file")
    if table.is_dir():
        raise CliError(f"{table} is a folder; give a samples table (.csv, .parquet or .mcap)")
    ws = workspace_dir(table, create=create)
    check_workspace(ws)
    if getattr(args, "reset_history", False):
        backup = reset_history(ws)
        if backup is not None:
            print(f"note: the old history is kept as {backup}; a new one starts", file=sys.stderr)
    load_history(ws)  # a corrupt history stops the command here, before the work
    return ws


def check_json_output(args: argparse.Namespace, inputs: list | None = None) -> None:
    """--json PATH must be writable (and new, or --force) before the work starts."""
    if args.json is not None and str(args.json) != "-":
        check_output(args.json, [args.table] if inputs is None else inputs, force=args.force)


def write_json(path: str | Path | None, data: Any, indent: int = 2) -> None:
    """The JSON to ``path``, or alone on stdout for ``-``; nothing without ``--json``."""
    if path is None:
        return
    text = json.dumps(data, indent=indent)
    if str(path) == "-":
        print(text)
    else:
        with atomic_write(path) as f:
            f.write(text + "\n")


def print_notes(survey: Any) -> None:
    for n in survey.notes:
        print(f"note: {n}", file=sys.stderr)


def positive(name: str, value: float) -> float:
    """``value`` if it is a finite number above 0, else a one-line CliError naming ``name``."""
    if not math.isfinite(value) or value <= 0:
        raise CliError(f"{name} must be a number above 0, not {value:g}")
    return value
