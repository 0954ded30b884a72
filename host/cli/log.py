"""`forcemap log info|recover`: summarize an MCAP log, or rebuild a truncated one with its index."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import Any, TextIO

from forcemap.host.cli.common import add_force, add_json, add_output, write_json
from forcemap.host.convert.log_info import (
    WIND_PAIR_S,
    LogInfo,
    info_json,
    recover,
    scan_file,
    wind_routes,
)
from forcemap.host.errors import CliError


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="log_command", metavar="ACTION", required=True)
    info = sub.add_parser("info", help="channels, counts, duration, gaps and error counters")
    info.add_argument("files", nargs="*", metavar="FILE", help="MCAP logs")
    add_json(info, "the summary", old_flag=True)
    add_force(info)
    rec = sub.add_parser(
        "recover", help="rewrite a truncated (killed) file as a complete one with index and summary"
    )
    rec.add_argument("file", metavar="FILE")
    add_output(rec, "output file (default: FILE with -recovered)", metavar="OUT")


def _print_columns_and_winds(info: LogInfo, w: Any) -> None:
    if info.columns:
        w("\n  samples columns fed by:\n")
        for col, label in info.columns.items():
            w(f"    {col:<24}{label}\n")
    routes = wind_routes(info)
    if routes is None:
        return
    w(f"\n  true wind, both routes: {routes['pairs']} instrument readings within ")
    w(f"{WIND_PAIR_S:g} s of a computed one\n")
    if routes["pairs"]:
        w(
            f"    instrument - computed: speed {routes['speed_mean']:+.2f} m/s mean, "
            f"{routes['speed_median_abs']:.2f} median |diff|; direction {routes['dir_mean']:+.1f} deg "
            f"mean, {routes['dir_median_abs']:.1f} median |diff|\n"
            "    (an instrument's true wind is often over the water, the computed one over ground)\n"
        )


def _fmt_time(ns: int) -> str:
    import datetime as dt

    return dt.datetime.fromtimestamp(ns / 1e9, dt.UTC).strftime("%Y-%m-%d %H:%M:%S.%f")[:-3] + "Z"


def print_info(info: LogInfo, out: TextIO | None = None) -> None:
    w = (out or sys.stdout).write
    state = "complete" if info.complete else ("TRUNCATED" if info.truncated else "no summary")
    w(f"{info.path}\n  {info.size} bytes, {state}")
    if info.truncated:
        w(f" (reading stopped: {info.error}); `forcemap log recover` rewrites it")
    w("\n")
    if info.start_ns:
        dur = (info.end_ns - info.start_ns) / 1e9
        w(f"  {_fmt_time(info.start_ns)} .. {_fmt_time(info.end_ns)}  ({dur:.1f} s)\n")
    if info.metadata:
        w(f"  metadata: {', '.join(info.metadata)}\n")
    w(f"\n  {'topic':<30}{'schema':<28}{'messages':>10}{'rate/s':>9}\n")
    for topic in sorted(info.topics):
        ti = info.topics[topic]
        span = (ti.last_ns - ti.first_ns) / 1e9
        rate = (ti.count - 1) / span if span > 0 else 0.0
        w(f"  {topic:<30}{ti.schema[:27]:<28}{ti.count:>10}{rate:>9.2f}\n")
    outages = info.outages()
    if outages:
        w("\n  source outages:\n")
        for o in outages:
            length = "until the end" if o["length_s"] is None else f"{o['length_s']:.2f} s"
            w(f"    {o['source']:<9}{_fmt_time(o['start_ns'])}  {length}  ({o['reason']})\n")
    gaps = info.gaps()
    if gaps:
        w("\n  gaps in regular topics:\n")
        for topic, start, length in gaps[:50]:
            w(f"    {topic:<30}{_fmt_time(int(start * 1e9))}  {length:.2f} s\n")
        if len(gaps) > 50:
            w(f"    ... {len(gaps) - 50} more\n")
    _print_columns_and_winds(info, w)
    for line in info.sources.lines():
        w(line + "\n")
    for line in _navigation_lines(info.path):
        w(line + "\n")
    if info.replans:
        _print_replans(info.replans, w)
    if info.findings:
        w("\n  quality findings (qa.*):\n")
        for f in info.findings.values():
            w(f"    {f.verdict:<7}{f.category}.{f.check}: {f.message}\n")
    errors = info.error_counters()
    if errors:
        w("\n  errors, rejections and gaps (last recorded counters):\n")
        for k in sorted(errors):
            w(f"    {k:<50} {errors[k]}\n")
    w("\n")


def _navigation_lines(path: str) -> list[str]:
    """Per navigation source: latency, noise, bias, outliers (host/convert/nav_findings.py)."""
    from forcemap.host.convert import nav_findings

    try:
        return nav_findings.lines(nav_findings.log_findings([path]))
    except (OSError, ValueError) as exc:  # a truncated file read up to its damage, or worse
        return ["", f"  navigation sources: not smoothed ({exc})"]


def _print_replans(replans: list[dict[str, Any]], w: Any) -> None:
    from forcemap.host.log.plan_records import describe_counts

    w(f"\n  in-flight replanning: {describe_counts(replans)}\n")
    for r in replans:
        age = r.get("map_age_s")
        age_s = f"map {age:.0f} s old" if isinstance(age, int | float) else "no map"
        cur = r.get("current_mean_mps")
        cur_s = f", current {cur:.2f} m/s" if isinstance(cur, int | float) else ""
        mark = "uploaded" if r.get("uploaded") else "late    " if r.get("late") else "kept    "
        t = _fmt_time(int(float(r.get("t", 0)) * 1e9))
        w(f"    {t}  after line {int(r.get('line_done', -1)) + 1}  {mark}  {age_s}{cur_s}: "
          f"{r.get('reason', '')}\n")  # fmt: skip


def _default_output(path: str) -> str:
    p = Path(path)
    return str(p.with_name(p.stem + "-recovered" + p.suffix))


def info_cmd(args: argparse.Namespace) -> int:
    from forcemap.host.outputs import check_output

    files = [*args.files, *getattr(args, "json_files", [])]
    if not files:
        raise CliError("give one or more MCAP logs")
    if args.json not in (None, "-"):
        check_output(args.json, files, force=args.force)
    status = 0
    infos: list[LogInfo] = []
    for path in files:
        try:
            infos.append(scan_file(path))
        except OSError as exc:
            print(f"forcemap log info: {exc}", file=sys.stderr)
            status = 1
    from forcemap.host.qa.report import log_findings, summary

    found = {i.path: log_findings(i.path) for i in infos}
    if args.json != "-":
        for info in infos:
            print_info(info)
            for line in summary(found[info.path]):  # the whole report: `forcemap check`
                print("  " + line)
    js = [info_json(i) | {"qa": [f.to_metadata() | {"name": f.name} for f in found[i.path]]}
          for i in infos]  # fmt: skip
    write_json(args.json, js, indent=1)
    return status


def run(args: argparse.Namespace) -> int:
    from forcemap.host.outputs import check_output

    if args.log_command == "info":
        return info_cmd(args)
    if not Path(args.file).is_file():
        raise CliError(f"{args.file}: no such file")
    if os.path.abspath(args.output or "") == os.path.abspath(args.file):
        raise CliError("the output must not be the input; choose another output file")
    out = check_output(args.output or _default_output(args.file), [args.file], args.force)
    try:
        count, scan = recover(args.file, out)
    except OSError as exc:
        raise CliError(f"cannot recover {args.file}: {exc.strerror or exc}") from None
    state = f"truncated ({scan.error})" if scan.truncated else "complete"
    print(f"{args.file}: {state}; wrote {count} messages to {out}")
    return 0
