"""The time terms' figures (docs/WORKBENCH.md, "Time terms"; bench/RESULTS.md): what the tests assert, with
the numbers printed.

    python bench/bench_time_terms.py [--out DIR]

1. a lake with a 0.5 m/s M2 stream (Greenwich phase 200 deg), 4 hours: the tide's amplitude and phase
   with their sd, the CV error with and without `tide`;
2. a river with a reversing tide (M2 1.0, S2 0.25 m/s, the river's current x 0.5) over a day: fitted on the
   first 60 %, the error on the last 40 % over the in-sample error, for `tide` and for a GP in `t`;
3. a lake with a 74-minute seiche, 3.5 hours: the estimated period and its sd, the CV error;
4. the plan in a tidal river (tests/test_plan_tide.py): p95 of the worst line, flown, for the plan from the
   mean current and the plan from the tide; and the CPU of each plan.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from forcemap.host.api import read_survey  # noqa: E402
from forcemap.host.vessel import scenario as sc  # noqa: E402
from forcemap.host.workbench.terms.tide import constituents  # noqa: E402

from bench.tidal_survey import truth_survey  # noqa: E402


def lake_tide(out: Path) -> None:
    table = truth_survey(
        "lake", ["tidal_stream:amplitude_m_s=0.5:phase_deg=200"], 1, 4 * 3600.0, out / "lake"
    )
    s = read_survey(table)
    base, fit = s.fit("current_east"), s.fit("current_east", effects="tide")
    (m2,) = constituents(fit.model_.primary)
    print(f"lake, 4 h, truth M2 0.5 m/s at 200 deg: amplitude {m2['amplitude']:.4f} +- {m2['amplitude_sd']:.4f} m/s, "
          f"phase {m2['phase_deg']:.2f} +- {m2['phase_sd_deg']:.2f} deg; CV RMSE {base.cv_rmse:.4f} -> {fit.cv_rmse:.4f} m/s")  # fmt: skip
    e = s.fit("current_speed", effects="tide").tide()["ellipses"][0]
    print(f"  ellipse: major {e['major']:.4f} +- {e['major_sd']:.4f}, direction {e['direction_deg']:.2f} +- "
          f"{e['direction_sd_deg']:.2f} deg, minor {e['minor']:+.4f} +- {e['minor_sd']:.4f}, phase "
          f"{e['phase_deg']:.2f} +- {e['phase_sd_deg']:.2f}")  # fmt: skip


def day(out: Path) -> None:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from test_time_terms import RIVER_TIDE, _errors, _split

    cpu = time.process_time()
    table = truth_survey("river", RIVER_TIDE, 1, 24 * 3600.0, out / "day", every_s=10.0)
    print(f"a day of the river ({time.process_time() - cpu:.0f} s of CPU to simulate)")
    head, later = _split(table, 0.6)
    whole, train = read_survey(table).table, read_survey(head)
    for effect in ("tide", "t"):
        sm = train.fit("current_speed", effects=effect).model_
        a, b = _errors(sm, whole, np.arange(train.n)), _errors(sm, whole, later)
        print(f"  {effect:5s} in-sample RMSE {a:.4f} m/s, last 40 % {b:.4f} m/s: ratio {b / a:.2f}")


def seiche(out: Path) -> None:
    s = read_survey(truth_survey("lake", ["seiche"], 1, 3.5 * 3600.0, out / "seiche"))
    base, fit = s.fit("current_speed"), s.fit("current_speed", effects="seiche")
    p = fit.tide()["seiche"]
    print(f"seiche, truth 4440 s: {p['period_s']:.1f} +- {p['period_sd_s']:.1f} s (power {p['power']:.2f}, "
          f"FAP {p['fap']:.2g}); CV RMSE {base.cv_rmse:.4f} -> {fit.cv_rmse:.4f} m/s")  # fmt: skip


def plan(out: Path) -> None:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from test_plan_tide import START_H, TIDE, later_river, plan_and_fly

    table = truth_survey("river", TIDE, 3, 6 * 3600.0, out / "plan-survey")
    start = sc.load("river").t0 + START_H * 3600
    scenario = later_river(out, start)
    for effect in ("", "tide"):
        cpu = time.process_time()
        maps, flight = plan_and_fly(table, effect, start, scenario, out)
        print(f"plan from {'the tide' if effect else 'the mean current'}: flown p95 worst line "
              f"{flight.summary['p95_worst_line']:.2f} m, coverage {flight.summary['coverage']:.3f} "
              f"({time.process_time() - cpu:.1f} s of CPU: fit, plan and flight)")  # fmt: skip


def field_speed() -> None:
    """The planner's inner loop with a field in time (12 slices, read between two of them at every step)
    against the same field static: CPU per predicted mission, in this process."""
    from forcemap.host.plan.boat_model import BoatModel
    from forcemap.host.plan.maps import Field, Maps
    from forcemap.host.plan.mission_io import read_mission
    from forcemap.host.plan.predict import predict_track
    from forcemap.host.vessel.geodesy import LocalFrame

    m = read_mission("lawnmower", "river")
    s = sc.load("river")
    wps = LocalFrame(s.lat0, s.lon0).points_to_local(m.latlon)
    gx, gy = np.arange(-400, 400, 4.0), np.arange(-200, 200, 4.0)
    X, Y = np.meshgrid(gx, gy)
    e, n = 1.0 + 0.3 * np.sin(X / 90), 0.2 * np.cos(Y / 60)
    z = np.zeros_like(e)
    static = Field(gx[0], gy[0], 4.0, e, n, z, z)
    k = np.linspace(0.5, 1.5, 12)[:, None, None]
    times = s.t0 + np.arange(12) * 1800.0
    timed = Field(gx[0], gy[0], 4.0, e * k, n * k, z + 0 * k, z + 0 * k, times=times)
    wind = Field.still()
    cpu = {}
    for name, f in (("static", static), ("in time", timed)):
        maps = Maps(f, wind, s.lat0, s.lon0, start=s.t0 + 900.0)
        c = time.process_time()
        for _ in range(20):
            tr = predict_track(wps, m.speeds, maps, BoatModel())
        cpu[name] = (time.process_time() - c) / 20
    print(
        f"predict_track, the lawnmower ({tr.duration:.0f} s flown): static {cpu['static']:.2f} s, "
        f"in time {cpu['in time']:.2f} s of CPU: x{cpu['in time'] / cpu['static']:.2f}"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    out = args.out or Path(tempfile.mkdtemp(prefix="time-terms-"))
    field_speed()
    for part in (lake_tide, seiche, plan, day):
        part(out)


if __name__ == "__main__":
    main()
