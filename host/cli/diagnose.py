"""`forcemap diagnose`: find which physical effect the current model of a target is missing."""

from __future__ import annotations

import argparse

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
from forcemap.host.errors import CliError

EPILOG = """\
diagnose fits the current model of the target (the latest `forcemap fit` of it, or the paper's baseline),
then adds a term in each candidate covariate in turn: every numeric column outside the target's own family,
time (t), and derived ones (heading relative to the flow, speed through water stw, a vector's own direction
for its speed). For wind and current it also tries clock_offset: the time offset (up to +-30 s) between the
boat-frame reading (anemometer, paddle wheels, speed log) and the heading and ground velocity that
makes the vector steadiest through the turns. It ranks them by how much the spatially
blocked CV error falls (pooled over three assignments of the blocks to folds). A candidate is a finding
when its error falls at least 10 %, a paired Wilcoxon test over spatial blocks passes Bonferroni over the
candidates, it beats by 5 % the same term on time-shifted copies of itself (its null), and a stand-in
predicted from position does not keep its gain (identifiable); else the survey advice says what survey
would tell it apart. A finding is added and the survey diagnosed again, up to --rounds times.

With --reference-current, the stations' predicted current is one more form a change in time can take at
the revisits: a tide that follows it is named as the station's tide and advised tide(reference, position).

Boat kinematics (sog, cog, crab = heading - cog, throttle) respond to the current and wind being mapped, so at a
held-out place they carry the answer: they are credited only with the gain that survives random folds,
where the field around each held-out sample is known. Instrument errors that grow with boat speed or
appear in turns survive that test; mere consequences do not. Proxies (t, the apparent wind, course, raw
wheel speeds) give way to a direct cause close behind that leaves them nothing to add. Details:
docs/WORKBENCH.md.

examples:
  forcemap diagnose survey.csv --target current_speed
  forcemap diagnose survey.csv --target wind_speed --json diag.json
  forcemap diagnose survey.csv --target current_speed --rounds 1     # only the first finding
  forcemap fit survey.csv --target current_speed --effects depth   # add what diagnose found ...
  forcemap diagnose survey.csv --target current_speed              # ... and look for the next effect
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    teach(parser, EPILOG)
    add_table(parser, several=True)
    add_target(parser, "column to diagnose")
    add_effects(parser, "start from baseline + these terms instead of the latest fit")
    parser.add_argument("--model", help="start from this TOML model spec instead of the latest fit")
    parser.add_argument("--baseline", action="store_true", help="start from the paper's baseline")
    add_json(parser)
    parser.add_argument(
        "--rounds",
        type=int,
        default=3,
        metavar="N",
        help="add each finding and diagnose again, at most N times (default 3)",
    )
    add_quiet(parser)
    add_keep_outliers(parser)
    add_water_level(parser)
    add_reference_current(parser)
    add_workspace_options(parser)


def run(args: argparse.Namespace) -> int:
    from forcemap.host.workbench.diagnose.rounds import diagnose
    from forcemap.host.workbench.engine.model import small_blas
    from forcemap.host.workbench.fits.fit import resolve_terms
    from forcemap.host.workbench.fits.workspace import current_terms, save_diagnosis
    from forcemap.host.workbench.terms.spec import BASELINE, check_terms

    if args.rounds < 1:
        raise CliError(f"--rounds must be at least 1, not {args.rounds}")
    # the same rule as fit: --target, or else the --model spec's target
    given, target = resolve_terms(args.model, args.effects, args.target)
    target = require_target(target)
    check_json_output(args)
    ws = prepare_workspace(args)
    if args.model or args.effects:
        terms = given
    elif args.baseline:
        terms = list(BASELINE)
    else:
        terms = current_terms(ws, target) or list(BASELINE)
    check_terms(terms)
    survey = load_table(args)
    with small_blas():
        result = diagnose(survey, target, terms, rounds=args.rounds, progress=not args.quiet)
    print_notes(survey)
    save_diagnosis(ws, target, result.details())
    write_json(args.json, result.to_json())
    out = human(args)
    print(result.summary(), file=out)
    for name, why in result.skipped.items():
        print(f"skipped {name}: {why}", file=out)
    return 0
