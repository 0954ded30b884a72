"""`forcemap season`: many surveys of one river as one season: a static depth map, the current's shape times a
per-survey discharge scale, the wind per survey, and how long a map stays true."""

from __future__ import annotations

import argparse
import glob
import sys
from pathlib import Path

from forcemap.host.cli.common import add_json, add_output, add_quiet, add_water_level, human, teach
from forcemap.host.extras import install_hint

EPILOG = """\
examples:
  forcemap sim --season 20 --days 30 -o season-sim          # a simulated season to try it on
  forcemap season 'season-sim/*/samples.parquet' -o season
  forcemap season logs/*.mcap tables/*.csv -o season --dask local:2
  forcemap season 'survey-*/samples.parquet' -o season --dask tcp://scheduler:8786 --no-cv

Inputs: MCAP logs of the daemon or samples tables (CSV, Parquet); quoted globs are expanded here.
A log that cannot be used (corrupt, no position, no overlap with the others: another river) is left
out with one line, and the season is made of the rest.

--dask local[:N] runs the per-log work on a LocalCluster of N single-threaded worker processes,
--dask tcp://HOST:8786 on a running cluster (every worker needs forcemap installed); without it,
everything runs in this process with the same result. Needs: {install}.

writes SEASON_DIR/season.json, maps.npz, season.html and the figures. `forcemap plan --season
SEASON_DIR` then says how old its map is and what that costs. Docs: docs/SEASON.md.
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    teach(parser, EPILOG.replace("{install}", install_hint("dask")))
    parser.add_argument("inputs", nargs="+", metavar="LOG_OR_TABLE", help="logs or tables (globs)")
    add_output(
        parser, "the season's folder (created if missing)", required=True, metavar="SEASON_DIR"
    )
    parser.add_argument("--dask", metavar="local[:N]|tcp://HOST:PORT", help="run on Dask")
    parser.add_argument(
        "--basis", type=int, default=400, help="basis functions of the spatial maps (default 400)"
    )
    parser.add_argument(
        "--offsets",
        choices=("auto", "yes", "no"),
        default="auto",
        help="a per-survey current offset: auto (the evidence decides), yes, no",
    )
    parser.add_argument(
        "--levels",
        choices=("auto", "yes", "no"),
        default="auto",
        help="one water level per survey under the static depth: auto (the evidence decides), yes, no",
    )
    add_water_level(parser)
    parser.add_argument("--no-cv", action="store_true", help="skip the depth map's blocked CV")
    add_json(parser, "the season's summary (season.json)")
    add_quiet(parser)


def expand(inputs: list[str]) -> list[str]:
    from forcemap.host.errors import CliError

    paths: list[str] = []
    for item in inputs:
        found = sorted(glob.glob(item)) if any(c in item for c in "*?[") else [item]
        if not found:
            raise CliError(f"{item} matches no file")
        for p in found:
            if not Path(p).is_file():
                raise CliError(f"no such log or table {p}")
            if p not in paths:
                paths.append(p)
    return paths


def check_dir(out: Path, inputs: list[str], force: bool) -> None:
    from forcemap.host.errors import CliError
    from forcemap.host.season.output import FILES

    if out.exists() and not out.is_dir():
        raise CliError(f"the output {out} is a file; give a folder (it is created if missing)")
    if any(Path(p).resolve().parent == out.resolve() for p in inputs):
        raise CliError(f"the output folder {out} holds inputs; choose another folder")
    if out.is_dir() and any((out / f).exists() for f in FILES) and not force:
        raise CliError(
            f"{out} already holds a season; pass --force to replace it, or choose another folder"
        )
    if not out.parent.is_dir() and str(out.parent):
        raise CliError(f"the folder {out.parent} does not exist; create it first")


def run(args: argparse.Namespace) -> int:
    import json

    from forcemap.host.cli.common import check_json_output, write_json
    from forcemap.host.convert.export import TRUNCATED
    from forcemap.host.errors import CliError
    from forcemap.host.season.engine import runner
    from forcemap.host.season.output import write
    from forcemap.host.season.run import run_season
    from forcemap.host.workbench.errors import WorkbenchError

    paths = expand(args.inputs)
    args.output = Path(args.output)
    check_dir(args.output, paths, args.force)
    check_json_output(args, paths)
    if args.basis < 16:
        raise CliError(f"--basis must be at least 16, not {args.basis}")

    def progress(text: str) -> None:
        if not args.quiet:
            print(text, file=sys.stderr, flush=True)

    gauge = None
    if args.water_level is not None:
        from forcemap.host.workbench.depth.water_level import read_gauge

        gauge = read_gauge(args.water_level)
    work = runner(args.dask)
    try:
        choice = {"auto": None, "yes": True, "no": False}
        season = run_season(
            paths, work, args.basis, choice[args.offsets], not args.no_cv, progress,
            levels=choice[args.levels], gauge=gauge,
        )  # fmt: skip
    except WorkbenchError as e:
        raise CliError(str(e)) from None
    finally:
        work.close()
    for r in season.rejected:
        print(f"left out: {r.reason}", file=sys.stderr)
    for s in season.surveys:  # a truncated log: how much of it the season holds
        for note in s.notes:
            if TRUNCATED in note:
                print(f"note: {note}", file=sys.stderr)
    args.output.mkdir(exist_ok=True)
    written = write(season, args.output)
    data = json.loads((args.output / "season.json").read_text())
    out = human(args)
    _print_summary(data, out)
    for p in written:
        print(f"wrote {p}", file=out)
    write_json(args.json, data)
    return 0


def _print_summary(data: dict, out) -> None:  # type: ignore[no-untyped-def]
    print(f"{len(data['surveys'])} surveys, {data['samples']} samples ({data['runner']})", file=out)
    for s in data["surveys"]:
        sc = "" if s["current_scale"] is None else f"current x{s['current_scale']:.3f}"
        print(f"  {s['start']}  {s['samples']:7d}  {sc}  {s['path']}", file=out)
    st = data.get("staleness")
    if st:
        d = st["doubling_age_days"]
        print(
            "a map's error doubles after "
            + (f"{d:.1f} days" if d is not None else "- (it did not grow with age)")
            + f" (fresh {st['fresh_map_rmse_mps']:.3f} m/s, +{st['rmse_growth_mps_per_day']:.4f} m/s per day)",
            file=out,
        )
    if data.get("depth_cv"):
        cv = data["depth_cv"]
        wins = sum(c["rmse_static"] < c["rmse_own"] for c in cv)
        print(
            f"depth: the static map beats the survey's own in blocked CV on {wins} of {len(cv)}",
            file=out,
        )
