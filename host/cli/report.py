"""`forcemap report`: write a self-contained HTML report of a survey's maps, residuals, diagnosis and history."""

from __future__ import annotations

import argparse
from pathlib import Path

from forcemap.host.cli.common import (
    add_keep_outliers,
    add_output,
    add_quiet,
    add_reference_current,
    add_table,
    add_water_level,
    add_workspace_options,
    load_table,
    prepare_workspace,
    print_notes,
    teach,
)

EPILOG = """\
The report shows the measurements on the map; the model's mean and uncertainty (wind and current as
arrows, depth as contours); residual maps and residual-against-covariate panels of every fitted target;
the ranked missing effects from `forcemap diagnose`; and the error history of `forcemap fit`.
Images are embedded, so the one file can be mailed or archived.

examples:
  forcemap report survey.csv
  forcemap report survey.csv -o river-2026-05-01.html
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    teach(parser, EPILOG)
    add_table(parser)
    add_output(
        parser, "HTML file to write (default TABLE.forcemap/report.html)", force=False, type=Path
    )
    add_quiet(parser)
    add_keep_outliers(parser)
    add_water_level(parser)
    add_reference_current(parser)
    add_workspace_options(parser)


def run(args: argparse.Namespace) -> int:
    from forcemap.host.outputs import atomic_write, check_output
    from forcemap.host.report.build import build_report
    from forcemap.host.workbench.engine.model import small_blas
    from forcemap.host.workbench.fits.workspace import load_diagnoses

    ws = prepare_workspace(args, create=args.output is None)  # the default report goes there
    load_diagnoses(ws)  # a corrupt diagnosis stops the report before the fits
    if args.output is not None:
        out = check_output(args.output, [args.table], force=args.force)
    else:
        out = check_output(ws / "report.html", [args.table], force=True)  # the workspace's own
    survey = load_table(args)
    with small_blas():
        text = build_report(args.table, survey, progress=not args.quiet)
    print_notes(survey)
    with atomic_write(out) as f:
        f.write(text)
    print(f"wrote {out.resolve()}")
    return 0
