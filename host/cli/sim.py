"""`forcemap sim`: a simulated river or lake with its instruments behind virtual serial ports."""

from __future__ import annotations

import argparse
import math
import signal
import threading
import time
from pathlib import Path

from forcemap.host.cli.common import (
    add_deprecated,
    add_duration,
    add_output,
    add_phenomena,
    parse_duration,
)
from forcemap.host.errors import CliError
from forcemap.host.vessel import mission as ms
from forcemap.host.vessel import scenario as sc
from forcemap.sim_devices import effects as fx
from forcemap.sim_devices import faults as fl

EPILOG = """\
examples:
  forcemap sim --list
  forcemap sim --scenario river --mission lawnmower --duration 30m --speed 50 \\
               --phenomena depth_current --faults default --ports /tmp/ports -o /tmp/truth
  forcemap sim --scenario lake --ports /tmp/ports                # real time, no hidden effect
  forcemap sim --scenario my_river.toml --mission my_mission.toml --ports /tmp/ports
  forcemap sim --mission planned.waypoints --duration 15m -o /tmp/flown   # offline, seconds

then, in another shell:
  forcemap run --bridge /tmp/ports/bridge --depth /tmp/ports/depth \\
               --mavlink /tmp/ports/mavlink --clock sim:/tmp/ports/clock -o logs/

Ports: DIR/bridge (the real bridge firmware on emulated pins, COBS frames), DIR/depth (NMEA 0183 at
4800 baud pacing, talker SD), DIR/mavlink (MAVLink 2, ArduPilot Rover rates); open them with pyserial.
DIR/clock holds the virtual clock's anchor, so the daemon can stamp arrivals at --speed N.
Phenomena: name or name:key=value:...  (e.g. wheel_misalignment:wheel=2:angle_deg=15).
Faults: a set (default, none) or kind:key=value:... (e.g. pull:source=bridge:at=120:for=5,reset:at=300).
Truth (-o DIR): effects.json, fields.npz, samples.csv as in docs/CONVENTIONS.md, and the mission
flown: mission.waypoints (QGC WPL 110) and mission.json (waypoints and intended lines, lat/lon and local m).
Without --ports the simulator runs offline as fast as it can and writes only the truth. Ctrl-C stops cleanly.
A folder that holds an earlier truth is replaced only with --force.
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = EPILOG
    parser.add_argument(
        "--list",
        action="store_true",
        help="list scenarios, missions, phenomena and faults, then exit",
    )
    parser.add_argument(
        "--scenario", default="river", help="built-in name (river, lake) or a scenario TOML path"
    )
    parser.add_argument(
        "--mission",
        default="lawnmower",
        help="built-in name, a mission TOML path, a QGC WPL 110 file (.waypoints) or a QGC .plan",
    )
    add_duration(
        parser,
        "--duration",
        parse_duration("30m"),
        "simulated time, e.g. 90s, 30m, 2h (default 30m)",
    )
    parser.add_argument(
        "--speed", type=float, default=1.0, help="virtual clock x N (default 1: real time)"
    )
    add_phenomena(
        parser, "comma-separated phenomena to simulate (default: the scenario's; see --list)", None
    )
    add_deprecated(parser, "--effects", "--phenomena LIST", "phenomena")
    parser.add_argument("--faults", default="none", help="fault set or specs (default none)")
    parser.add_argument(
        "--ports", metavar="DIR", help="directory for the port symlinks and the clock file"
    )
    parser.add_argument(
        "--lockstep",
        metavar="SOURCES",
        help="with --ports: drive the daemon's clock (`run --clock sim:DIR/clock`) in lockstep with "
        "its readers of these ports (e.g. bridge,depth,mavlink): each chunk stamped at its send "
        "time and sent once the last is queued, so the same seed gives the same log on any "
        "machine; --speed then only caps the pace",
    )
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    add_output(parser, "folder for the ground truth (created if missing)", metavar="DIR")
    parser.add_argument(
        "--adcp",
        nargs="?",
        const="",
        default=None,
        metavar="SETTINGS",
        help="also record a moving-boat ADCP along the track: DIR/adcp.PD0 beside the truth, for "
        "`forcemap import` (docs/ADCP.md); SETTINGS key=value,... e.g. "
        "bt_loss=0.1,compass_error_deg=6",
    )
    add_deprecated(parser, "--truth", "-o/--output DIR", "output")
    season = parser.add_argument_group("a season of offline surveys (docs/SEASON.md), into -o DIR")
    season.add_argument("--season", type=int, metavar="N", help="N surveys of the river")
    season.add_argument("--days", type=float, default=30.0, help="over D days (default 30)")
    season.add_argument(
        "--samples",
        type=int,
        default=54_000,
        help="samples per survey at 5 Hz (default 54000: 3 h)",
    )
    season.add_argument(
        "--bar-shift",
        type=float,
        default=0.0,
        metavar="M_PER_DAY",
        help="the sand bars move this far downstream per day (default 0: fixed depth)",
    )
    season.add_argument(
        "--stage",
        type=float,
        default=0.0,
        metavar="M",
        help="the stage follows the discharge through a rating curve of this scale (m; 0.98 gives a 0.6 m "
        "range; default 0: fixed stage)",
    )


def print_list() -> None:
    print("scenarios:")
    for n, d in sc.describe_all():
        print(f"  {n:22s} {d}")
    print("missions:")
    for n, d in ms.describe_all():
        print(f"  {n:22s} {d}")
    print("phenomena:")
    for line in fx.lines():
        print(f"  {line}")
    print("faults:")
    for line in fl.lines():
        print(f"  {line}")


def _world(args: argparse.Namespace):  # type: ignore[no-untyped-def]
    """The scenario, mission, phenomena and faults the arguments name, each checked (CliError)."""
    try:
        scen = sc.load(args.scenario)
        mis = ms.load(args.mission, scen)
        effects = fx.parse_list(args.phenomena) if args.phenomena is not None else None
        return scen, mis, effects, fl.parse(args.faults)
    except (ValueError, OSError) as e:
        raise CliError(str(e)) from None


def run_offline(args: argparse.Namespace) -> int:
    """No ports: the world, the boat and the autopilot only, as fast as the machine goes; the truth is written."""
    from forcemap.sim_devices.engine import Simulation

    scen, mis, effects, faults = _world(args)
    Path(args.output).mkdir(parents=True, exist_ok=True)
    t_start = time.monotonic()
    print(f"{scen.name} / {mis.name}, {args.duration:.0f} s offline", flush=True)

    def progress(t: float, total: float) -> None:
        if t >= total or (t > 1 and int(t) % 300 == 0):
            print(
                f"  t={t:7.1f} s of {total:.0f} s ({time.monotonic() - t_start:.1f} s wall)",
                flush=True,
            )

    sim = Simulation(
        scen, mis, effects, faults, seed=args.seed, truth_dir=args.output, instruments=False
    )
    sim.run(args.duration, lambda *a: None, progress=progress)
    print(
        f"done: {sim.t:.1f} s simulated in {time.monotonic() - t_start:.1f} s; truth in {args.output}"
    )
    _adcp(args)
    return 0


def _adcp_setup(args: argparse.Namespace):  # type: ignore[no-untyped-def]
    """The simulated ADCP's setup from --adcp (None without it), checked before the run."""
    if args.adcp is None:
        return None
    from forcemap.sim_devices.adcp import parse_setup

    if not args.output:
        raise CliError("--adcp records beside the truth: give -o DIR")
    try:
        return parse_setup(args.adcp)
    except ValueError as e:
        raise CliError(str(e)) from None


def _adcp(args: argparse.Namespace) -> None:
    setup = _adcp_setup(args)
    if setup is not None:
        from forcemap.sim_devices.adcp import record_run

        print(f"ADCP: {record_run(args.output, setup)}")


def check_arguments(args: argparse.Namespace) -> None:
    """Refuse what cannot work, before any pty appears: a clock that never advances, ports in a file."""
    if not math.isfinite(args.speed) or args.speed <= 0:
        raise CliError(
            f"--speed must be a finite number above 0 (1 is real time), not {args.speed:g}"
        )
    if args.lockstep is not None:
        if not args.ports:
            raise CliError("--lockstep needs --ports DIR: it paces the daemon that reads them")
        from forcemap.sim_devices.ports import SOURCES

        bad = sorted(set(args.lockstep.split(",")) - set(SOURCES))
        if bad or not args.lockstep:
            raise CliError(
                f"--lockstep {args.lockstep}: name the ports the daemon reads, from "
                f"{', '.join(SOURCES)}"
            )
    if not args.ports and not args.output:
        raise CliError(
            "give --ports DIR (live, behind virtual serial ports) or -o DIR for the truth "
            "(offline, as fast as it goes), or --list"
        )
    for flag, folder in (("--ports", args.ports), ("-o/--output", args.output)):
        if folder and Path(folder).exists() and not Path(folder).is_dir():
            raise CliError(f"{flag} {folder} is a file; give a folder (it is created if missing)")
    if args.output and (Path(args.output) / "effects.json").exists() and not args.force:
        raise CliError(
            f"{args.output} holds an earlier truth; pass --force to replace it, or choose "
            "another folder"
        )


def run_season(args: argparse.Namespace) -> int:
    """N surveys over D days: a hydrograph, the wind by day, fixed depth (or slowly moving bars)."""
    from forcemap.sim_devices.season import make_season

    if not (math.isfinite(args.stage) and args.stage >= 0):
        raise CliError(f"--stage needs a scale of at least 0 m, not {args.stage}")
    if args.season < 1 or args.samples < 100 or not (math.isfinite(args.days) and args.days > 0):
        raise CliError(
            "--season needs N >= 1 surveys, --days above 0 and --samples of at least 100"
        )
    if args.output is None:
        raise CliError("--season writes a folder: give it with -o DIR")
    out = Path(args.output)
    if out.exists() and not out.is_dir():
        raise CliError(f"the output {out} is a file; give a folder (it is created if missing)")
    if (out / "season_truth.json").exists() and not args.force:
        raise CliError(f"{out} already holds a season; pass --force to replace it")
    t0 = time.monotonic()

    def progress(i: int, n: int) -> None:
        if i == n or i % 10 == 0:
            print(f"  survey {i} of {n} ({time.monotonic() - t0:.1f} s)", flush=True)

    paths = make_season(
        args.season, args.days, out, samples=args.samples, seed=args.seed,
        bar_shift_per_day=args.bar_shift, stage_scale_m=args.stage,
        progress=progress,
    )  # fmt: skip
    print(f"{len(paths)} surveys of {args.samples} samples over {args.days:g} days in {out}")
    print(f"truth: {out / 'season_truth.json'} and survey-*/truth.json")
    return 0


def run(args: argparse.Namespace) -> int:
    if args.list:
        print_list()
        return 0
    if args.season is not None:
        return run_season(args)
    check_arguments(args)
    _adcp_setup(args)
    if not args.ports:
        return run_offline(args)
    from forcemap.sim_devices.engine import Simulation
    from forcemap.sim_devices.ports import SOURCES, PortSet, run_live

    scen, mis, effects, faults = _world(args)  # validated before any pty appears
    ports = PortSet(args.ports)
    stop = threading.Event()
    # Ctrl-C and SIGTERM end the run between steps: the truth is written and the ports are removed
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    signal.signal(signal.SIGTERM, lambda *_: stop.set())

    def factory(**kw: object) -> Simulation:
        return Simulation(scen, mis, effects, faults, seed=args.seed, truth_dir=args.output, **kw)  # type: ignore[arg-type]

    for s in SOURCES:
        print(f"{s:8s} {ports.path(s)}")
    print(f"clock    {ports.clock_path}  (daemon: --clock sim:{ports.clock_path})")
    print(
        f"{scen.name} / {mis.name}, {args.duration:.0f} s at x{args.speed:g}; Ctrl-C stops",
        flush=True,
    )
    t_start = time.monotonic()

    def progress(t: float, total: float) -> None:
        print(
            f"  t={t:7.1f} s of {total:.0f} s ({time.monotonic() - t_start:.1f} s wall)", flush=True
        )

    lock = None
    try:
        if args.lockstep:
            from forcemap.sim_devices.lockstep import run_lockstep

            sim, lock = run_lockstep(
                factory, ports, args.duration, args.lockstep.split(","), args.speed, stop,
                on_progress=progress,
            )  # fmt: skip
        else:
            sim = run_live(factory, ports, args.duration, args.speed, stop, on_progress=progress)
    finally:
        ports.close()
    print(f"{'stopped' if stop.is_set() else 'done'}: {sim.t:.1f} s simulated; bytes {sim.stats}")
    if lock is not None:
        print(
            f"lockstep with the daemon: {lock.chunks} chunks, {time.monotonic() - t_start:.1f} s "
            f"wall, {lock.waited_s:.1f} s of it waiting for the daemon; {lock.timeouts} timeouts"
            + ("" if not lock.timeouts else " (this run may not repeat exactly)")
        )
    if ports.reanchors:
        print(
            f"the machine fell behind x{args.speed:g} {ports.reanchors} time(s); the clock waited "
            "for the bytes each time (a lower --speed runs smoother)"
        )
    if args.output:
        print(f"truth in {args.output}")
        _adcp(args)
    return 0
