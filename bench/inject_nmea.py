"""Put a known current or water level into a real NMEA 0183 capture, and write down the truth.

A test ground for everything downstream of the raw log (import, calibration, the smoother, export,
diagnose): the real log keeps its instruments' noise, faults and latencies, and gains one effect
whose every value is known. ``python bench/inject_nmea.py --help`` shows how; the effects' shapes
are in ``bench/inject_effects.py``; ``--verify`` measures how much of the effect a samples table
recovered (``bench/inject_verify.py``).

What changes, as if the water itself had moved by c(t) while the boat sailed through it exactly as
recorded (docs/QA.md, "Testing a pipeline on your own log"):

- every position (RMC, GGA, GLL, GNS) moves by the displacement d(t), the integral of c from the
  log's start (``host/vessel/geodesy.py``'s LocalFrame, the project's one geodesy);
- the velocity over ground (RMC and VTG speed and course) becomes the recorded one plus c(t); a
  set-and-drift sentence (VDR) gains c(t);
- the air does not move: the apparent wind (MWV R, VWR) becomes the recorded one minus c(t), turned
  into the boat's frame with the recorded heading (HDT; HDG or HDM with the log's variation, else
  IGRF-14's declination at the first fix), so the wind over ground a pipeline computes stays the
  recorded one;
- an instrument's own true wind (MWV T, VWT, MWD) is computed by the instrument from the apparent
  wind and the speed log, so it is wind over the water: it becomes the recorded one minus c(t) too
  (``--true-wind ground`` leaves it as recorded, for instruments that compute it over ground);
- a water level L(t) makes every sounding (DBT, DBS, DBK in feet, metres and fathoms; DPT) deeper by
  L(t); DPT's transducer offset is kept;
- everything measured against the water or the boat (speed log VHW, compass HDG/HDM/HDT, rate of
  turn, water temperature, the log's distance) and every route sentence (RMB, APB, BWR, BWC, XTE:
  they describe a waypoint from the boat as it was) is left as recorded.

Times: a sentence with its own time (RMC, GGA, GLL, GNS, ZDA) is injected at that time; any other
takes the time of the last timed sentence before it (a sentence before the first one: the log's
start). A stamp more than an hour from the running clock is taken as damaged, and the clock used.
The date is the day most valid fixes' RMC or ZDA dates give (a date without a fix never counts),
midnight crossings counted, as ``forcemap import`` finds it, so the truth's ``t`` is the samples
table's.

Every rewritten field keeps its decimals and padding (``bench/nmea_fields_like.py``); its rounding
error is carried into the same field's next value, so a change smaller than the log's resolution (a
current's part of a wind angle in whole degrees, a level in decimetres) is not lost, on average, to
rounding. A modified sentence keeps the checksum convention it was written with (a correct one, or
its bus's variant, as Irene 2013-07-31's checksums over the address only). The sentence of a line is
what follows its last ``$`` (junk or a cut sentence before it is kept as it is). A sentence whose
checksum matches no convention, one that lacks what its rewriting needs (an apparent wind before
any heading, a speed without its course) or has a field that is not a number, passes through
untouched and is counted by reason; proprietary sentences and lines that are not sentences are
copied. Lines and their endings are otherwise copied byte for byte; an injection of nothing
reproduces the input exactly.
"""

from __future__ import annotations

import argparse
import csv
import gzip
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from forcemap.host.convert.capture_file import ImportFailed, capture_bytes  # noqa: E402
from forcemap.host.errors import CliError  # noqa: E402
from forcemap.host.outputs import atomic_path, check_output  # noqa: E402

from bench.inject_effects import Current, Effect, Shape, parse_current, parse_shape  # noqa: E402
from bench.inject_sentences import Report, inject_lines  # noqa: E402

TRUTH_COLUMNS = ("t", "current_east", "current_north", "level", "offset_east", "offset_north")
TRUTH_STEP_S = 1.0
TRUTH_MARGIN_S = 10.0  # lines after the last stamp: the importer times them at the log's line rate

__all__ = ["Current", "Effect", "Shape", "inject", "read_truth", "truth_path"]


def truth_path(out: str | Path) -> Path:
    """The truth file beside an output capture: ``race.nmea`` -> ``race.truth.csv``."""
    p = Path(out)
    name = p.name[:-3] if p.name.endswith(".gz") else p.name
    stem = name.rsplit(".", 1)[0] if "." in name else name
    return p.with_name(stem + ".truth.csv")


def write_truth(path: Path, effect: Effect, t0: float, t1: float) -> None:
    """One row a second over the log: t (UNIX s), the current (east, north, m/s), the level (m)
    and the displacement since the log's start (east, north, m)."""
    tau = np.arange(0.0, t1 - t0 + TRUTH_MARGIN_S, TRUTH_STEP_S)
    zero = np.zeros_like(tau)
    ce, cn = effect.current.velocity(tau) if effect.current else (zero, zero)
    de, dn = effect.current.offset(tau) if effect.current else (zero, zero)
    lv = effect.level.value(tau) if effect.level else zero
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(TRUTH_COLUMNS)
        for row in zip(t0 + tau, ce, cn, lv, de, dn, strict=True):
            w.writerow([f"{row[0]:.3f}", *(f"{v:.6f}" for v in row[1:])])


def read_truth(path: str | Path) -> dict[str, np.ndarray]:
    """A truth file's columns as arrays."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    if not rows or tuple(rows[0]) != TRUTH_COLUMNS:
        raise CliError(f"{path}: not a truth file (its header is not {','.join(TRUTH_COLUMNS)})")
    data = np.array(rows[1:], dtype=float).reshape(-1, len(TRUTH_COLUMNS))
    return {c: data[:, i] for i, c in enumerate(TRUTH_COLUMNS)}


def inject(
    src: str | Path,
    dst: str | Path,
    effect: Effect,
    truth: str | Path | None = None,
    true_wind: str = "water",
    force: bool = False,
) -> tuple[Report, Effect]:
    """Write ``src`` with ``effect`` injected to ``dst`` (gzipped when its name ends in .gz) and
    the truth to ``truth`` (default: beside ``dst``); the report and the effect as resolved for
    this log. Neither output may be the input; an existing one is replaced only with ``force``."""
    out = check_output(dst, [src], force)
    tpath = check_output(truth or truth_path(dst), [src, dst], force)
    if tpath.resolve() == out.resolve():
        raise CliError("the truth file and the output capture must be two files")
    try:
        data = capture_bytes(src)
    except ImportFailed as e:
        raise CliError(str(e)) from None
    except OSError as e:
        raise CliError(f"{src}: cannot read it ({e.strerror or e})") from None
    lines, eff, rep = inject_lines(data.split(b"\n"), effect, true_wind)
    with atomic_path(out) as tmp, open(tmp, "wb") as raw:
        if out.name.endswith(
            ".gz"
        ):  # no name or time in the header: the same input, the same bytes
            with gzip.GzipFile(filename="", mode="wb", fileobj=raw, mtime=0) as f:
                f.write(b"\n".join(lines))
        else:
            raw.write(b"\n".join(lines))
    write_truth(tpath, eff, rep.t0, rep.t1)
    return rep, eff


EPILOG = """\
effects (SHAPE key=value ...; bench/inject_effects.py):
  tidal     amplitude=A [period_s=44714.2] [phase_deg=0]    A cos(2 pi tau / P + phase); M2
  periodic  amplitude=A period_s=P [phase_deg=0]            a seiche (Lake Geneva: about 74 min)
  ramp      amplitude=A [ramp_s=the log's span]             A min(tau / ramp_s, 1): drift, stage
  step      amplitude=A [at_s=the middle] [width_s=1800]    A (1 + tanh((tau - at_s) / width_s)) / 2
  tau is the time since the log's first stamp; a current also needs toward=DEG (where it sets TO,
  clockwise from true north; a negative value sets the other way). A current is uniform in space.

examples:
  # a 74-min seiche of +-0.15 m/s along Lake Geneva's axis
  python bench/inject_nmea.py race.nmea -o seiche.nmea \\
      --current "periodic amplitude=0.15 period_s=4440 toward=30"
  # an M2 tidal stream and a 0.6 m rise of the water in one log; the truth in tide.truth.csv
  python bench/inject_nmea.py race.nmea.gz -o tide.nmea.gz \\
      --current "tidal amplitude=0.26 toward=50 phase_deg=30" --level "step amplitude=0.6"
  # then run the pipeline on both logs and measure what it recovered
  forcemap import race.nmea -o clean.mcap && forcemap export clean.mcap -o clean.csv
  forcemap import seiche.nmea -o seiche.mcap && forcemap export seiche.mcap -o seiche.csv
  python bench/inject_nmea.py --verify seiche.csv --truth seiche.truth.csv --clean clean.csv

The truth file has one row a second: t (UNIX s, the samples table's time), current_east,
current_north (m/s), level (m), offset_east, offset_north (m: how far the water carried the boat).
Exit 2, in one line, on bad input; an existing output is replaced only with --force, and the
input is never an output.
"""


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python bench/inject_nmea.py",
        description="Put a known current or water level into a real NMEA 0183 capture (plain or "
        "gzipped), as if the water had moved while the boat sailed exactly as recorded; write "
        "the new capture and the truth. Or, with --verify, measure how much of it a samples "
        "table recovered (2-minute means against the truth).",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=EPILOG,
    )
    p.add_argument("capture", nargs="?", help="the NMEA 0183 capture to inject into")
    p.add_argument("-o", "--output", help="the new capture (.gz: gzipped)")
    p.add_argument("--current", metavar="SPEC", help='e.g. "tidal amplitude=0.26 toward=50"')
    p.add_argument("--level", metavar="SPEC", help='e.g. "step amplitude=0.6 width_s=2700"')
    p.add_argument("--truth", help="the truth CSV (default: OUTPUT's name with .truth.csv)")
    p.add_argument(
        "--true-wind",
        choices=("water", "ground"),
        default="water",
        help="what the instruments' own true wind (MWV T, VWT, MWD) is relative to: water "
        "(default: computed from the apparent wind and the speed log, so it changes by -c) or "
        "ground (left as recorded)",
    )
    p.add_argument("--force", action="store_true", help="replace existing outputs")
    p.add_argument("--verify", metavar="TABLE", help="a samples table (CSV, Parquet) to measure")
    p.add_argument("--clean", metavar="TABLE", help="--verify: the same log's table without it")
    p.add_argument(
        "--toward", type=float, help="--verify: also the current along this direction (deg)"
    )
    return p


def _effect(args: argparse.Namespace) -> Effect:
    try:
        current = parse_current(args.current) if args.current else None
        level = parse_shape(args.level)[0] if args.level else None
    except ValueError as e:
        raise CliError(f"bad effect: {e}") from None
    if current is None and level is None:
        raise CliError("give --current SPEC, --level SPEC or both (see --help)")
    return Effect(current, level)


def _verify(args: argparse.Namespace) -> int:
    from bench.inject_verify import read_table, recovery

    if not args.truth:
        raise CliError("--verify needs --truth TRUTH.csv")
    try:
        table = read_table(args.verify)
        clean = read_table(args.clean) if args.clean else None
    except (OSError, KeyError, IndexError) as e:
        raise CliError(f"cannot read the table: {e}") from None
    fits = recovery(table, read_truth(args.truth), clean, args.toward)
    if not fits:
        raise CliError("the truth varies nothing the table has (current_east/north, depth)")
    for f in fits:
        print(f.line())
    return 0


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        if args.verify:
            return _verify(args)
        if not args.capture or not args.output:
            raise CliError("give a capture and -o OUTPUT (or --verify TABLE); see --help")
        rep, eff = inject(
            args.capture, args.output, _effect(args), args.truth, args.true_wind, args.force
        )
    except CliError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    if eff.current is not None:
        print(
            f"current (m/s, toward {eff.current.toward_deg:g} deg): {eff.current.shape.describe()}"
        )
    if eff.level is not None:
        print(f"level (m): {eff.level.describe()}")
    for line in rep.summary():
        print(line)
    print(f"-> {args.output}, truth {args.truth or truth_path(args.output)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
