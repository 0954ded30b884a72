"""`forcemap fit`: fit a map model to a samples table, report its cross-validated error, save it."""

from __future__ import annotations

import argparse

from forcemap.host.cli.at_option import add_at, at_time
from forcemap.host.cli.common import (
    add_effects,
    add_json,
    add_keep_outliers,
    add_quiet,
    add_reference_current,
    add_table,
    add_target,
    add_water_level,
    add_workspace_options,
    check_json_output,
    human,
    load_table,
    prepare_workspace,
    print_notes,
    require_target,
    teach,
    write_json,
)

EPILOG = """\
The model is a sum of terms. Without --model it is the paper's baseline, a GP over position with a
Matern 3/2 kernel (plus a constant mean level): const + gp(position, matern32).

examples:
  forcemap fit survey.csv --target current_speed
  forcemap fit survey.csv --target current_speed --effects depth          # add a GP in depth
  forcemap fit survey.csv --target current_speed --effects "power(depth),t"
  forcemap fit survey.csv --target wind_dir --effects heading --json fit.json
  forcemap fit survey.parquet --target depth --model spec.toml
  forcemap fit survey.csv --target current_speed --effects tide --at 2026-06-02T14:00Z

terms: gp(INPUTS, KERNEL) with kernel linear, rbf, matern12, matern32, matern52 or periodic (angles);
  linear(COV); power(COV) = a*COV^b; cos(ANGLE) = a*cos(ANGLE-phase); user(COV, module:function).
  A bare name is its default term: gp(NAME, periodic) for an angle, gp(NAME, matern32) otherwise.
  tide: tidal constituents chosen by the Rayleigh criterion for the record's span (tide(M2, K1): those;
  tide(position): varying over the survey), with nodal corrections: amplitudes and Greenwich phases with
  their sd, a vector's tidal ellipses; it predicts at any time (--at). seiche: a cos/sin pair at a period
  estimated from the data (recorded as seiche(4436 s)); seiche(74 min) a given one.
  clock_offset (wind and current) re-references the vector with the heading and ground velocity shifted by the
  offset that makes it steadiest in turns; clock_offset(+1.5 s) uses a given offset.
spec.toml:  terms = ["const", "gp(position, matern32)", "user(depth, mylaws:manning)"]

wind_* and current_* speed and direction are modelled through their east/north components; effect terms
act along the flow for a speed and across it for a direction.
The CV folds are spatially blocked (whole areas held out). --folds random holds out scattered samples whose
along-track neighbours stay in training: that flatters every model. The fit is saved in TABLE.forcemap/
with residual plots; `forcemap history TABLE` lists every fit. A fit whose CV error is not a number
(a user function gave NaN) is refused, never saved. An existing --json file is replaced only with
--force; with --json - stdout carries only the JSON (the summary goes to stderr). A corrupt
history.json stops the fit until it is fixed or --reset-history moves it aside.
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    teach(parser, EPILOG)
    add_table(parser, several=True)
    add_target(parser)
    add_effects(parser, "comma-separated covariates or terms to add, e.g. depth,t")
    parser.add_argument("--model", help="TOML model spec (terms, optional target)")
    parser.add_argument(
        "--folds",
        choices=("blocked", "random"),
        default="blocked",
        help="CV folds (default blocked)",
    )
    add_at(parser, "also predict the target at this time over the surveyed places")
    add_json(parser)
    parser.add_argument("--no-plots", action="store_true", help="do not write residual plots")
    add_quiet(parser)
    add_keep_outliers(parser)
    add_water_level(parser)
    add_reference_current(parser)
    add_workspace_options(parser)


def run(args: argparse.Namespace) -> int:
    from forcemap.host.api import Fit, Survey
    from forcemap.host.workbench.fits.fit import resolve_terms, save_residual_plots
    from forcemap.host.workbench.terms.spec import check_terms

    # everything that can be checked is checked before the fit, which can take a minute
    terms, target = resolve_terms(args.model, args.effects, args.target)
    target = require_target(target)
    check_terms(terms)
    at = at_time(args)
    check_json_output(args)
    ws = prepare_workspace(args)
    survey = Survey(load_table(args))
    fit = Fit(target, terms=terms, folds=args.folds).fit(
        survey, record=True, progress=not args.quiet
    )
    result, entry = fit.result_, fit.entry_
    print_notes(survey.table)
    report = result.to_json()
    if at is not None:
        report["at"] = prediction_at(fit, at)
    write_json(args.json, report)
    out = human(args)
    from forcemap.host.qa.report import check_table, summary

    for line in summary(check_table(args.table).findings):  # `forcemap check` has the whole report
        print(line, file=out)
    print(result.summary(), file=out)
    if at is not None:
        print(prediction_line(report["at"]), file=out)
    if not args.no_plots:
        for p in save_residual_plots(args.table, result, entry["fit"]):
            print(f"wrote {p}", file=out)
    print(f"saved fit {entry['fit']} in {ws}", file=out)
    return 0


def prediction_at(fit, at: float, most: int = 2000) -> dict:
    """The fitted target at UNIX time `at` over the survey's own places (at most `most` of them): its mean,
    range and mean predictive sd there, and what the time terms do at that time."""
    import numpy as np
    from forcemap.host.workbench.terms.time_terms import iso, notes_at

    s = fit.model_.survey
    idx = np.unique(np.linspace(0, s.n - 1, min(most, s.n)).astype(int))
    pred = fit.model_.predict_grid(s.xy[idx], at)
    mean = pred["mean"]
    return {
        "target": fit.target,
        "time": iso(at),
        "unix_s": at,
        "places": len(idx),
        "mean": float(np.mean(mean)),
        "min": float(np.min(mean)),
        "max": float(np.max(mean)),
        "sd": float(np.mean(pred["std"])),
        "notes": notes_at(fit.model_.primary, s, at),
    }


def prediction_line(p: dict) -> str:
    """`prediction_at` in words, with its notes."""
    from forcemap.host.workbench.survey.table import unit_of

    unit = f" {u}" if (u := unit_of(p["target"])) else ""
    head = (
        f"at {p['time']}: {p['target']} over the {p['places']} surveyed places {p['mean']:.4g}{unit} "
        f"on average ({p['min']:.4g} to {p['max']:.4g}; predictive sd {p['sd']:.3g}{unit})"
    )
    return "\n".join([head] + [f"  {n}" for n in p["notes"]])
