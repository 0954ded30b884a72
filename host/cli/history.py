"""`forcemap history`: every fit of a survey with its CV error, as a table and a PNG plot."""

from __future__ import annotations

import argparse
from pathlib import Path

from forcemap.host.cli.common import (
    add_deprecated,
    add_output,
    add_table,
    add_workspace_options,
    prepare_workspace,
    teach,
)

EPILOG = """\
Every `forcemap fit` of the table is recorded in TABLE.forcemap/history.json. history prints them and
plots the CV RMSE of each target relative to its first fit, so you see the error fall as effects are added.
The latest `forcemap diagnose` of each target follows, round by round: what it added and the error falling.

examples:
  forcemap history survey.csv
  forcemap history survey.csv -o errors.png
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    teach(parser, EPILOG)
    add_table(parser)
    add_output(
        parser, "the plot, a PNG file (default TABLE.forcemap/history.png)", force=False, type=Path
    )
    add_deprecated(parser, "--plot", "-o/--output PNG", "output", convert=Path)
    add_workspace_options(parser)


def run(args: argparse.Namespace) -> int:
    from forcemap.host.outputs import atomic_write, check_output
    from forcemap.host.workbench.diagnose.result import round_steps
    from forcemap.host.workbench.errors import WorkbenchError
    from forcemap.host.workbench.fits.workspace import load_diagnoses, load_history

    ws = prepare_workspace(args)
    history = load_history(ws)
    diagnoses = load_diagnoses(ws)
    if not history and not diagnoses:
        raise WorkbenchError(
            f"no fits recorded for {args.table}; run `forcemap fit {args.table} --target ...` first"
        )
    if args.output is not None:
        plot = check_output(args.output, [args.table], force=args.force)
    else:
        plot = ws / "history.png"  # the workspace's own file, redrawn every time
        check_output(plot, [args.table], force=True)
    from forcemap.host.workbench.survey.table import unit_of

    if history:
        print(
            f"{'fit':>3}  {'time (UTC)':<20} {'target':<16} {'folds':<8} {'cv_rmse':>9} {'cv_mae':>9} "
            f"{'unit':<4} {'cov95':>6}  terms"
        )
    for h in history:
        print(
            f"{h['fit']:>3}  {h['time']:<20} {h['target']:<16} {h.get('folds', ''):<8} {h['cv_rmse']:>9.4g} "
            f"{h['cv_mae']:>9.4g} {unit_of(h['target']):<4} {h['coverage95']:>6.1%}  "
            f"{' + '.join(h['terms'])}"
            + (
                f"  (crossline RMSE {h['crossline_rmse']:.4g} {unit_of(h['target'])})"
                if "crossline_rmse" in h
                else ""
            )
        )
    for target, d in diagnoses.items():
        print(f"diagnose {target}:")
        print("\n".join(f"  {line}" for line in round_steps(d)))
    if history:
        from forcemap.host.workbench.fits import plots
        png = plots.png_bytes(plots.history_figure(history))
        with atomic_write(plot, "wb") as f:
            f.write(png)
        print(f"wrote {plot}")
    return 0
