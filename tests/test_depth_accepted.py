"""One depth surface for every depth map (issue 61): the soundings the CUBE-like surface rejects are left
out of every fit, flagged and counted with their reason, and grid's surface is built from exactly the
soundings the fit uses (host/workbench/depth/accepted.py).

The survey is a ramp such as a yacht crosses, 80 to 100 m over 400 m, run as a lawnmower at 2.5 m/s
with a sounding a second (the sounder's noise 0.3 m, inside its TVU: 0.55 m at 1 sd at 90 m), and wild
readings put in at known rows, all closer to the bed than the spike test's floor (what it leaves to
the surface): beyond the hypotheses' gate, just beyond the TVU, and held over several rows.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from forcemap.host.cli import main
from forcemap.host.fuse import tvu
from forcemap.host.vessel.geodesy import LocalFrame
from forcemap.host.workbench.depth import verdicts
from forcemap.host.workbench.depth.accepted import accepted
from forcemap.host.workbench.depth.surface import survey_soundings
from forcemap.host.workbench.engine.model import small_blas
from forcemap.host.workbench.survey.table import survey_from_columns
from forcemap.host.workbench.targets.target_model import SurveyModel

from tests.tools import write_csv_rows

LAT0, LON0 = 37.8, -122.5
NOISE = 0.3
# row -> metres off the bed, each under the spike test's floor (0.5 m + 5 % of the depth: 4.5-5.5 m here)
WILD = {
    300: 3.5,
    700: -3.0,
    1100: 4.0,
}  # beyond the hypotheses' gate (3 sds): alone in a depth of its own
NEAR = {500: 1.8, 900: -1.8}  # beyond the TVU (1.96 sds, 1.2-1.4 m here), within the gate


def bed(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The ramp and a gentle swell across it."""
    return 80.0 + 0.05 * (x + 200.0) + 0.8 * np.sin(y / 60.0)


def ramp(held: int = 1, seed: int = 0) -> dict[str, np.ndarray]:
    """The lawnmower's columns (t, lat, lon, depth), each sounding held over ``held`` rows."""
    rng = np.random.default_rng(seed)
    xs, ys = [], []
    for k, y in enumerate(np.arange(-150.0, 151.0, 25.0)):
        x = np.arange(-200.0, 200.0, 2.5)
        xs.append(x if k % 2 == 0 else x[::-1])
        ys.append(np.full(len(x), y))
    x, y = np.concatenate(xs), np.concatenate(ys)
    depth = bed(x, y) + NOISE * rng.standard_normal(len(x))
    for row, off in {**WILD, **NEAR}.items():
        depth[row] = bed(x[row], y[row]) + off
    t = 1.7e9 + np.arange(len(x), dtype=float)
    if held > 1:  # a table sampled faster than the sounder: its reading repeated
        x, y = np.interp(np.arange(len(x) * held) / held, np.arange(len(x)), x), np.repeat(y, held)
        depth, t = np.repeat(depth, held), 1.7e9 + np.arange(len(x), dtype=float) / held
    lat, lon = LocalFrame(LAT0, LON0).to_latlon(x, y)
    return {"t": t, "lat": lat, "lon": lon, "depth": depth}


def survey_of(cols: dict[str, np.ndarray]):
    return survey_from_columns(Path("ramp.csv"), {k: v.copy() for k, v in cols.items()})


def write(cols: dict[str, np.ndarray], path: Path) -> Path:
    names = list(cols)
    rows = [[repr(float(cols[c][i])) for c in names] for i in range(len(cols["t"]))]
    return write_csv_rows(path, names, rows)


@pytest.fixture(scope="module")
def cols():
    return ramp()


def test_a_wild_reading_in_a_smooth_ramp_is_alone_and_left_out(cols):
    survey = survey_of(cols)
    found = accepted(survey)
    assert found.reason[1100] == verdicts.ALONE  # 4 m off: a hypothesis of its own, outvoted
    assert np.all(found.rejected[list(WILD)]), found.reason[list(WILD)]
    # the bed's own soundings: hardly any rejected (a 0.3 m sounder inside a 0.55 m TVU)
    others = np.ones(survey.n, bool)
    others[list(WILD) + list(NEAR)] = False
    assert found.rejected[others].mean() < 0.01


def test_a_sounding_beyond_its_tvu_moves_the_map_by_less_than_a_tenth_of_its_disagreement(cols):
    """The map at each put-in sounding's place, with it and with the bed's own reading there: it moves by
    less than a tenth of how far the sounding is from the depth the surface chose."""
    truthful = {k: v.copy() for k, v in cols.items()}
    x, y = LocalFrame(LAT0, LON0).to_local(cols["lat"], cols["lon"])
    rng = np.random.default_rng(1)
    rows = [*WILD, *NEAR]
    truthful["depth"][rows] = bed(x[rows], y[rows]) + NOISE * rng.standard_normal(len(rows))
    with small_blas():
        wild = SurveyModel(survey_of(cols), "depth").fit()
        clean = SurveyModel(survey_of(truthful), "depth").fit()
    survey = wild.rows.survey.origin[0]
    at = {"position": survey.xy[rows], "t": survey.trel[rows]}
    moved = np.abs(wild.primary.predict(at) - clean.primary.predict(at))
    disagreement = np.abs(cols["depth"][rows] - bed(x[rows], y[rows]))
    s = survey_soundings(survey)
    assert np.all(
        disagreement > tvu.Z95 * s["sd"][s["reading"][rows]]
    )  # beyond what its TVU allows
    assert np.all(moved < 0.1 * disagreement), (moved, disagreement)


def test_every_row_is_kept_and_the_rejected_ones_are_flagged_with_their_reason(cols):
    survey = survey_of(cols)
    with small_blas():
        sm = SurveyModel(survey, "depth").fit()
    assert survey.n == len(cols["t"])  # the table keeps every row
    flag = survey.columns["spike_depth"]
    assert np.all(flag[list(WILD)] == 1)
    used = sm.rows.survey.origin[1]
    assert not set(used) & set(WILD)
    assert len(used) == survey.n - int(flag.sum())
    (line,) = [ln for ln in sm.spikes.lines() if "disagreeing with the depth surface" in ln]
    n = int(re.match(r"(\d+) of", line).group(1))
    assert n == int(sm.spikes.surface.sum()) and "alone in a depth of its own" in line
    kinds = sm.spikes.to_json()["kinds"]
    assert kinds["disagreeing with the depth surface"] == n
    reasons = sm.spikes.to_json()["surface"]["reasons"]
    assert sum(reasons.values()) == n and reasons["alone in a depth of its own"] >= 1


def test_a_held_reading_is_one_sounding_and_its_rows_share_its_verdict():
    cols = ramp(held=4)
    survey = survey_of(cols)
    found = accepted(survey)
    for row in WILD:  # the reading's four rows, one verdict
        assert found.reason[4 * row] > 0 and np.all(
            found.reason[4 * row : 4 * row + 4] == found.reason[4 * row]
        )
    assert len(survey_soundings(survey)["depth"]) < 0.3 * survey.n


def test_keep_outliers_keeps_them_in_the_fit_and_says_so(cols):
    survey = survey_of(cols)
    survey.keep_outliers = True
    with small_blas():
        sm = SurveyModel(survey, "depth").fit()
    assert sm.survey.n == survey.n
    assert any("kept in the fit (--keep-outliers)" in ln for ln in sm.spikes.lines())


def test_fit_and_grid_use_the_same_accepted_soundings_and_say_the_same_figure(
    cols, tmp_path, capsys
):
    """`fit` and `grid` say the same count of soundings the surface rejected, and grid's surface bands
    are built from exactly the soundings the fit was fitted on."""
    import rasterio  # noqa: F401  (the [gis] extra, in the test extras: a missing one fails)
    import xarray as xr
    from forcemap.host.api import read_survey
    from forcemap.host.gis.grid import make_grid
    from forcemap.host.gis.surface import surface_bands

    table = write(cols, tmp_path / "ramp.csv")
    assert main(["fit", str(table), "--target", "depth", "--no-plots"]) == 0
    fit_err = "".join(capsys.readouterr())
    out = tmp_path / "maps.nc"
    assert main(["grid", str(table), "-o", str(out), "--target", "depth", "--quiet"]) == 0
    grid_err = "".join(capsys.readouterr())
    said = re.compile(r"(\d+) of (\d+) soundings flagged as disagreeing with the depth surface")
    assert said.search(fit_err) and said.search(fit_err).groups() == said.search(grid_err).groups()
    # the bands: from the accepted soundings, not from every sounding the spike test left
    s = read_survey(table)
    fit = s.fit("depth")
    rows = fit.model_.rows
    kept = rows.survey.columns["t"]
    assert set(np.round(rows.soundings["t"], 3)) == set(np.round(kept, 3))
    ds = xr.open_dataset(out)
    grid = make_grid(s.table, float(ds.attrs["resolution_m"]))
    mine = surface_bands(grid, fit.model_.survey, rows.soundings)["surface_soundings"]
    every = surface_bands(grid, s.table, survey_soundings(s.table))["surface_soundings"]
    written = ds["depth_surface_soundings"].values
    assert np.array_equal(
        np.nan_to_num(written[::-1] if _flipped(ds) else written), np.nan_to_num(mine)
    )
    assert np.nansum(every) > np.nansum(mine)  # the wild readings would have reached it


def _flipped(ds) -> bool:
    """Whether the file's rows run south to north (the grid's run north to south)."""
    y = ds["y"].values
    return bool(len(y) > 1 and y[1] > y[0])


def test_season_fits_depth_on_the_same_rows(cols):
    from forcemap.host.season.tasks import _depth_rows
    from forcemap.host.workbench.survey.target_rows import target_rows

    survey = survey_of(cols)
    ok, line = _depth_rows(survey)
    assert np.array_equal(ok, target_rows(survey, "depth").used)
    assert not ok[list(WILD)].any() and "disagreeing with the depth surface" in line
    assert math.isclose(ok.mean(), 1.0 - survey.columns["spike_depth"].mean())
