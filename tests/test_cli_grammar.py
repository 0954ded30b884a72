"""The CLI's one grammar (docs/CLI.md), read from the real parsers of every subcommand.

The table OPTIONS is the grammar: every option name any command takes, with its one meaning and its
kind. A command that adds an option must add it here (and to docs/CLI.md); a name cannot take a second
meaning, a file a command writes is ``-o/--output`` (or ``--json``), a duration goes through the shared
parser, and a boat TOML is ``--boat``. Old spellings (``common.Deprecated``) are checked in
tests/test_cli_old_spellings.py.
"""

from __future__ import annotations

import argparse
import importlib
import inspect
import re

import pytest
from forcemap.host.cli import COMMANDS, build_parser, common

OUTPUT, JSON, FORCE, DURATION, BOAT, QUIET, FLAG, VALUE = (
    "output", "json", "force", "duration", "boat", "quiet", "flag", "value",
)  # fmt: skip

# option -> (kind, its one meaning)
OPTIONS: dict[str, tuple[str, str]] = {
    "-o/--output": (OUTPUT, "what the command writes: a file, or a folder where there are several"),
    "--force": (FORCE, "replace an existing output"),
    "--json": (JSON, "the machine-readable result: a path, or '-' for nothing but JSON on stdout"),
    "--boat": (BOAT, "the boat TOML (calibration, config, boat and controller model)"),
    "--quiet": (QUIET, "no progress; only the results"),
    "--duration": (DURATION, "how long the simulated survey lasts"),
    "--clock-wait": (DURATION, "how long the daemon waits for the simulator's clock file"),
    "--rotate-every": (DURATION, "the age after which the daemon starts a new log file"),
    "--rotate-mb": (VALUE, "the size after which the daemon starts a new log file"),
    "--effects": (VALUE, "model terms to add (never simulated phenomena)"),
    "--phenomena": (VALUE, "what the simulator simulates (never model terms)"),
    "--target": (VALUE, "the samples-table column to model (default: the --model spec's)"),
    "--model": (VALUE, "a TOML model spec"),
    "--folds": (VALUE, "how the CV folds are drawn"),
    "--baseline": (FLAG, "start a diagnosis from the paper's baseline"),
    "--rounds": (VALUE, "how many findings a diagnosis adds"),
    "--no-plots": (FLAG, "write no residual plots"),
    "--keep-outliers": (FLAG, "fit the readings the spike test flagged too"),
    "--water-level": (VALUE, "a water-level gauge's record: the depth reduced to its datum"),
    "--reference-current": (VALUE, "a reference current: the tide on a current related to its stations"),
    "--reference-station": (VALUE, "the one reference station every place takes"),
    "--reset-history": (FLAG, "move a corrupt workspace history aside"),
    "--from": (VALUE, "the format of the input to import"),
    "--reference": (VALUE, "what an ADCP's water velocity is referenced to: bottom track or GPS"),
    "--heading-offset": (VALUE, "a compass correction pinned instead of estimated (deg)"),
    "--adcp": (VALUE, "record a simulated moving-boat ADCP too, with these settings"),
    "--to": (VALUE, "the format of the export, where the output's name does not say"),
    "--sync": (VALUE, "how samples are matched to the boat's state"),
    "--sample-rate": (VALUE, "samples per second in the table"),
    "--nmea-checksum": (VALUE, "strict or lenient: whether NMEA checksum variants are accepted"),
    "--date": (VALUE, "the UTC day an NMEA log whose sentences carry no date starts on"),
    "--bridge": (VALUE, "the bridge's port"),
    "--nmea": (VALUE, "an NMEA 0183 instrument's port"),
    "--depth": (VALUE, "an NMEA 0183 port named depth"),
    "--mavlink": (VALUE, "the autopilot's connection"),
    "--clock": (VALUE, "the arrival clock: the host's or the simulator's"),
    "--prefix": (VALUE, "the log files' name prefix"),
    "--raw": (FLAG, "also log the raw bytes"),
    "--scenario": (VALUE, "a simulated scenario, by name or TOML"),
    "--mission": (VALUE, "a mission: built-in name, mission TOML or QGC WPL 110 file"),
    "--speed": (VALUE, "the speed-up over real time: the simulator's clock, a replay's pace"),
    "--faults": (VALUE, "the simulated instruments' faults"),
    "--seed": (VALUE, "the simulator's random seed"),
    "--lockstep": (
        VALUE,
        "the ports whose daemon readers the simulator's clock drives (each chunk acknowledged)",
    ),
    "--list": (FLAG, "list what the simulator knows, then exit"),
    "--ports": (
        VALUE,
        "the simulator's port folder (an interface the daemon opens, not an output)",
    ),
    "--season": (
        VALUE,
        "a season of surveys of one river: how many to simulate (sim), the folder to read (plan)",
    ),
    "--days": (VALUE, "the number of days a simulated season spans"),
    "--samples": (VALUE, "samples per simulated survey of a season"),
    "--bar-shift": (VALUE, "how far the simulated sand bars move downstream per day"),
    "--stage": (VALUE, "the simulated season's rating-curve stage scale"),
    "--at": (VALUE, "the time a fit's prediction or a map is for"),
    "--start/--at": (VALUE, "when the planned mission starts: its lines' predicted current, its map's age"),
    "--replan-terms": (VALUE, "with --replan: the refit's terms beyond the baseline"),
    "--dask": (VALUE, "where the per-log work runs: a LocalCluster or a Dask scheduler"),
    "--basis": (VALUE, "basis functions of the season's spatial maps"),
    "--offsets": (VALUE, "a per-survey current offset: auto, yes or no"),
    "--levels": (VALUE, "a per-survey water level under the static depth: auto, yes or no"),
    "--no-cv": (FLAG, "skip the season's depth blocked CV"),
    "--upload": (VALUE, "the vehicle's MAVLink port to send the mission to"),
    "--port": (VALUE, "the bridge board's serial port"),
    "--baud": (VALUE, "a serial baud rate"),
    "--board": (VALUE, "the bridge board's type"),
    "--build-dir": (VALUE, "a staging folder for the compiled firmware (a cache, not an output)"),
    "--dry-run": (FLAG, "print commands instead of running them"),
    "--frames": (VALUE, "stop after this many frames"),
    "--resolution": (VALUE, "a map grid's cell size, in metres"),
    "--mask-distance": (VALUE, "how far from every sample a map grid's cells are still mapped, m"),
    "--live": (VALUE, "serve the survey to Foxglove on HOST:PORT (default 127.0.0.1:8765)"),
    "--map-every": (DURATION, "how often, in survey time, the live maps are updated"),
    "--no-maps": (FLAG, "a live view without the growing maps"),
    "--replan": (FLAG, "replan the rest of the mission in flight, after each line"),
    "--replan-bound": (VALUE, "the largest move of a waypoint across its line when replanning"),
}


def _walk(path: str, parser: argparse.ArgumentParser):
    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if not subs:
        yield path, parser
    for action in subs:
        for name, child in action.choices.items():
            yield from _walk(f"{path} {name}", child)


def _command_parsers() -> list[tuple[str, argparse.ArgumentParser]]:
    """(`forcemap CMD [ACTION]`, its parser) for every subcommand, built as `forcemap` builds it."""
    out = []
    for name in COMMANDS:
        root = build_parser(name)
        [sub] = [a for a in root._actions if isinstance(a, argparse._SubParsersAction)]
        out += list(_walk(name, sub.choices[name]))
    return out


PARSERS = _command_parsers()


def _options(parser: argparse.ArgumentParser, deprecated: bool = False):
    for a in parser._actions:
        if not a.option_strings or isinstance(a, argparse._HelpAction):
            continue
        if isinstance(a, common.Deprecated) == deprecated:
            yield "/".join(a.option_strings), a


def test_every_command_is_walked():
    names = {p.split()[0] for p, _ in PARSERS}
    assert names == set(COMMANDS)
    assert {"log info", "log recover", "bridge flash", "bridge monitor"} <= {p for p, _ in PARSERS}


@pytest.mark.parametrize("path, parser", PARSERS, ids=[p for p, _ in PARSERS])
def test_every_option_has_one_meaning_in_the_table(path, parser):
    for name, action in _options(parser):
        assert name in OPTIONS, (
            f"forcemap {path}: {name} is not in the grammar; add it to OPTIONS with its one meaning "
            "(and to docs/CLI.md), or use the existing option that means the same"
        )
        kind = OPTIONS[name][0]
        takes_value = action.nargs != 0
        assert takes_value == (kind not in (FLAG, FORCE, QUIET)), (path, name)
        for short in action.option_strings:
            assert short.startswith("--") or short == "-o", f"{path}: short option {short}"


def test_an_option_name_means_the_same_everywhere():
    """The same name has the same shape in every command (a flag here is a flag there)."""
    shapes: dict[str, set] = {}
    for _, parser in PARSERS:
        for name, action in _options(parser):
            kind = "duration" if isinstance(action, common.Duration) else action.nargs != 0
            shapes.setdefault(name, set()).add(kind)
    assert {n: s for n, s in shapes.items() if len(s) > 1} == {}


@pytest.mark.parametrize("path, parser", PARSERS, ids=[p for p, _ in PARSERS])
def test_what_a_command_writes_is_o_output_or_json(path, parser):
    for name, action in _options(parser):
        kind = OPTIONS[name][0]
        help_ = (action.help or "").lower()
        if name == "-o/--output":
            assert action.option_strings == ["-o", "--output"]
        if re.search(r"\b(write|writes|written)\b", help_) and not help_.startswith("do not"):
            assert kind in (OUTPUT, JSON), (
                f"forcemap {path}: {name} writes a file: make it -o/--output"
            )
        if kind == OUTPUT:
            assert any(n == "--force" for n, _ in _options(parser)) or path in ("run", "demo"), (
                f"forcemap {path}: an output without --force"
            )


@pytest.mark.parametrize("path, parser", PARSERS, ids=[p for p, _ in PARSERS])
def test_json_takes_a_path_or_dash(path, parser):
    for name, action in _options(parser):
        if name != "--json":
            continue
        ns = argparse.Namespace()
        action(parser, ns, "out.json", "--json")
        assert ns.json == "out.json"
        assert action.nargs is None or isinstance(action, common.JsonOrOldFlag), path


@pytest.mark.parametrize("path, parser", PARSERS, ids=[p for p, _ in PARSERS])
def test_every_duration_reads_s_m_h_through_the_shared_parser(path, parser):
    for name, action in _options(parser):
        help_ = action.help or ""
        if OPTIONS[name][0] == DURATION or re.search(
            r"\b(seconds|minutes|hours)\b|how long", help_
        ):
            assert isinstance(action, common.Duration), f"forcemap {path}: {name} is not a Duration"
            for text, seconds in (("30s", 30), ("20m", 1200), ("3h", 10800), ("1h30m", 5400)):
                ns = argparse.Namespace()
                action(parser, ns, text, name)
                assert getattr(ns, action.dest) == seconds
            with pytest.raises(argparse.ArgumentError):
                action(parser, argparse.Namespace(), "20 minutes", name)


@pytest.mark.parametrize("path, parser", PARSERS, ids=[p for p, _ in PARSERS])
def test_quiet_means_no_progress(path, parser):
    for name, action in _options(parser):
        if name == "--quiet":
            assert isinstance(action, argparse._StoreTrueAction)
            assert "no progress" in action.help, (path, action.help)


@pytest.mark.parametrize("path, parser", PARSERS, ids=[p for p, _ in PARSERS])
def test_a_boat_toml_is_read_through_boat(path, parser):
    names = dict(_options(parser))
    for name, action in names.items():
        help_ = (action.help or "").lower()
        boat_toml = "boat" in help_ and "toml" in help_ and "--boat" not in help_
        if boat_toml or (action.metavar or "").upper().startswith("BOAT"):
            assert name == "--boat", f"forcemap {path}: {name} reads a boat TOML: call it --boat"
    module = importlib.import_module(COMMANDS[path.split()[0]][0])
    boat_readers = r"calibration\.load\(|fuse\.calibration import[^\n]*\bload\b|\bload_boat\b"
    reads_boat = re.search(boat_readers, inspect.getsource(module))
    assert bool(reads_boat) == ("--boat" in names), f"forcemap {path}: reads a boat without --boat"


def test_the_old_spellings_print_and_store_through_deprecated():
    """Every old spelling is a Deprecated action that names a new spelling the command takes."""
    seen = set()
    for path, parser in PARSERS:
        current = {s for n, _ in _options(parser) for s in n.split("/")}
        for name, action in _options(parser, deprecated=True):
            seen.add(f"{path} {name}")
            new_names = set(re.findall(r"--?[a-z][a-z-]*", action.new))
            assert new_names and new_names <= current, (path, name, action.new)
            assert (
                name not in current
            )  # an old name never lives on with a new meaning in its command
    assert seen == {
        "demo --out", "demo --effect", "sim --effects", "sim --truth", "run --config", "run --out",
        "run --rotate-min", "import --out", "import --format", "import --config",
        "export --format/-f", "history --plot",
    }  # fmt: skip
