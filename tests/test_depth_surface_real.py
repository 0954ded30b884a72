"""One depth surface on every real NMEA log with depth (issue 61, item 4), by properties any correct
pipeline has, each log imported and exported once per run (tests/real_cases.py):

- every row kept: the table has the log's rows, and every sounding the depth map leaves out is flagged
  in ``spike_depth`` (spikes, the bottom lost, the surface's rejections), never dropped;
- the surface is continuous where the sounder held the bottom: between successive accepted soundings
  of a pass the bed changes no faster than a seabed can (the seabed path's floor, 0.5 m + 5 %, plus 1 in
  2 of the distance travelled) but in a few places;
- the fit's noise sd is within 1.5 x the soundings' robust scatter: the median over 5-minute windows of
  the accepted soundings' 1.48 x MAD about their own 5-minute trend line (a straight line fitted to
  them). The scatter about a line over 5 minutes holds the bed's own shape as well as the sounder's
  noise, so a fit may come under it (PacCupStart's 0.5 m under 1.2 m); the bound is the one way;
- no cell is made from a rejected sounding: every cell of grid's surface has an accepted sounding
  within its capture, and every cell of the GP map a row it was fitted on within the mask distance.

Four logs miss the noise bound for causes outside the surface, each said where it is marked.
"""

from __future__ import annotations

import gzip

import numpy as np
import pytest
from forcemap.host.fuse.bottom_lost import path_tolerance
from forcemap.host.workbench.depth.surface import CAPTURE
from forcemap.host.workbench.engine.model import small_blas
from forcemap.host.workbench.survey.table import load_survey
from forcemap.host.workbench.targets.target_model import SurveyModel

from tests.tools import csv_rows, real_data

WINDOW_S = 300.0
SEABED_SLOPE = 0.5
BASIS = "its map is limited by its basis: the lengthscale sits at the reduced-rank GP's shortest"
LOGS = {
    "nmea/PacCupStartNMEA.txt": None,
    "nmea/bundg_zeus_9.log": None,
    "nmea/plaka.log": f"{BASIS} (573 m over 25 km), its noise is the shoals it cannot follow",
    "nmea/NeutronDance.log": None,
    "nmea/irene/irene_2008-08-20_geneva.nmea": None,
    "nmea/irene/irene_2013-07-31_flensburg_checksums.nmea": None,
    "nmea/irene/irene_2013-08-03_flensburg.nmea": (
        "96 soundings of 35-80 m in 10-20 m of fjord, in runs at the edges of the bottom-lost stretches "
        "that test does not find (the lost-bottom work's); without them 1.16 x"
    ),
    "nmea/irene/irene_2014-06-27_geneva.nmea": (
        "the shelf's edge needs a lengthscale under the map's shortest (58 m over its box; fitted on "
        "every row it sits there, noise 0.54 m; on the fit's rows, one per 5 s, 225 m and 0.80 m)"
    ),
    "nmea/sfbay/swift-day1.nmea.gz": None,
    "nmea/sfbay/duxbury.nmea.gz": (
        f"{BASIS} (411 m over 14 km), as plaka's; fitted on every row, not one per 5 s, its noise is 1.36 x"
    ),
}


def _depth_sentences(path) -> bool:
    opener = gzip.open if path.suffix == ".gz" else open
    with opener(path, "rt", errors="replace") as f:
        return any(("DBT," in line or "DPT," in line or "DBS," in line) for line in f)


def test_every_real_nmea_log_with_depth_is_here():
    root = real_data()
    found = {
        str(p.relative_to(root))
        for p in (root / "nmea").rglob("*")
        if p.is_file() and p.suffix in (".nmea", ".log", ".txt", ".gz") and _depth_sentences(p)
    }
    assert found == set(LOGS)


def robust_scatter(t: np.ndarray, depth: np.ndarray) -> float:
    """The median over WINDOW_S windows of 1.4826 x the soundings' median absolute deviation about their
    own least-squares line in time."""
    out = []
    for a in np.arange(t.min(), t.max(), WINDOW_S):
        m = (t >= a) & (t < a + WINDOW_S)
        if m.sum() < 10:
            continue
        r = depth[m] - np.polyval(np.polyfit(t[m] - a, depth[m], 1), t[m] - a)
        out.append(1.4826 * np.median(np.abs(r - np.median(r))))
    return float(np.median(out))


@pytest.fixture(scope="module")
def fitted(real_case):
    """Each log's survey and its depth model (the fit of `forcemap fit`, without its CV)."""
    cache = {}

    def get(name):
        if name not in cache:
            built = real_case(name)
            survey = load_survey(built.csv)
            with small_blas():
                cache[name] = (built, survey, SurveyModel(survey, "depth").fit())
        return cache[name]

    return get


def _bound(name: str):
    why = LOGS[name]
    return pytest.param(name, marks=pytest.mark.xfail(reason=why, strict=True)) if why else name


@pytest.mark.parametrize("name", [_bound(n) for n in LOGS])
def test_the_fits_noise_is_within_one_and_a_half_times_the_soundings_robust_scatter(fitted, name):
    _, _, sm = fitted(name)
    s = sm.rows.soundings
    scatter = robust_scatter(s["t"], s["depth"])
    assert sm.primary.noise_std_ <= 1.5 * scatter, (sm.primary.noise_std_, scatter)


@pytest.mark.parametrize("name", list(LOGS))
def test_every_row_is_kept_and_what_the_map_leaves_out_is_flagged(fitted, name):
    built, survey, sm = fitted(name)
    _, rows = csv_rows(built.csv)
    assert survey.n == len(rows)  # the exported table's rows, each one in the survey
    depth = np.isfinite(survey.columns["depth"])
    flagged = np.nan_to_num(survey.columns.get("spike_depth", np.zeros(survey.n))) > 0
    used = np.zeros(survey.n, bool)
    used[sm.rows.survey.origin[1]] = True
    assert np.array_equal(used, depth & ~flagged)
    # the surface's rejections are a few per cent at most: it judges, it does not thin
    surface = sm.spikes.surface if sm.spikes.surface is not None else np.zeros(survey.n, bool)
    assert surface.sum() <= 0.06 * depth.sum()


@pytest.mark.parametrize("name", list(LOGS))
def test_the_surface_is_continuous_where_the_sounder_held_the_bottom(fitted, name):
    _, _, sm = fitted(name)
    s = sm.rows.soundings
    d, step = s["depth"], np.hypot(*np.diff(s["xy"], axis=0).T)
    same_pass = np.diff(s["t"]) < 60.0
    jump = (np.abs(np.diff(d)) > path_tolerance(d[1:]) + SEABED_SLOPE * step) & same_pass
    assert jump.sum() <= 0.02 * same_pass.sum(), (int(jump.sum()), int(same_pass.sum()))


@pytest.mark.parametrize("name", list(LOGS))
def test_no_cell_is_made_from_a_rejected_sounding(fitted, name):
    import pyproj  # noqa: F401  (the [gis] extra, in the test extras: a missing one fails)
    from forcemap.host.gis.grid import evaluate, make_grid
    from scipy.spatial import cKDTree

    _, survey, sm = fitted(name)
    span = float(np.max(np.ptp(survey.xy, axis=0)))
    grid = make_grid(survey, max(10.0, span / 300.0))
    with small_blas():
        layer = evaluate(grid, sm)
    kept = cKDTree(sm.rows.soundings["xy"])
    cells = grid.local_xy
    made = np.isfinite(layer.bands["surface"].ravel())
    assert made.any()
    assert np.all(kept.query(cells[made])[0] <= CAPTURE * grid.resolution + 1e-6)
    rows = cKDTree(sm.survey.xy)  # the rows it was fitted on (a held reading's rows move on)
    mapped = np.isfinite(layer.bands["mean"].ravel())
    assert np.all(rows.query(cells[mapped])[0] <= grid.max_distance + grid.resolution)
