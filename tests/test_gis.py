"""Maps for GIS: every GeoTIFF read back with rasterio and every NetCDF with xarray; the value at the cell
holding a sample's lat/lon is the model's prediction at that cell's centre; the UTM zone is right on both
sides of a zone boundary and in both hemispheres; polar and antimeridian surveys are refused in one line."""

from __future__ import annotations

import json
import math
import subprocess
import sys

import forcemap
import numpy as np
import pytest
import rasterio
import xarray as xr
from forcemap.host.cli import main
from forcemap.host.extras import install_hint
from forcemap.host.gis.grid import cell_of, make_grid, utm_epsg
from forcemap.host.gis.surface import SURFACE_BANDS
from forcemap.host.workbench.survey.table import load_survey
from pyproj import Transformer

from bench.synth_survey import LAT0, LON0, make_survey

TOL = 1e-6


def moved(lat0: float, lon0: float) -> dict:
    """`make_survey` extras that put the synthetic survey's track at (lat0, lon0), same shape in metres."""
    k = math.cos(math.radians(LAT0)) / math.cos(math.radians(lat0))
    return {
        "lat": lambda c: lat0 + (c["lat"] - LAT0),
        "lon": lambda c: (lon0 + (c["lon"] - LON0) * k + 180.0) % 360.0 - 180.0,
    }


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    """A survey in the southern hemisphere astride the 6 E zone boundary (zones 31S | 32S), its depth and
    current fitted through the API, and the CLI's files from those fits."""
    d = tmp_path_factory.mktemp("gis")
    table = make_survey("river", ["depth_current"], 3, 1200.0, d, extra=moved(-45.0, 6.001))
    survey = forcemap.read_survey(table)
    fits = {t: survey.fit(t, record=True) for t in ("depth", "current_speed")}
    out = d / "maps"
    rc = main(["grid", str(table), "-o", str(out), "--target", "depth,current_speed",
               "--resolution", "4", "--quiet", "--json", str(d / "grid.json")])  # fmt: skip
    assert rc == 0
    return survey, fits, out, json.loads((d / "grid.json").read_text())


def _samples(survey, k: int = 25) -> tuple[np.ndarray, np.ndarray]:
    rows = np.linspace(0, survey.n - 1, k).astype(int)
    return survey.table.columns["lat"][rows], survey.table.columns["lon"][rows]


def test_geotiff_round_trip_and_cog_profile(fitted):
    survey, fits, out, summary = fitted
    lat, lon = _samples(survey)
    assert summary["crs"] == "EPSG:32732"  # its centre, 6.001 E, is in zone 32 (south)
    surface = list(SURFACE_BANDS)  # depth's CUBE-like surface beside the GP's bands (issue 37)
    for target, bands in (
        ("depth", ["mean", "sd", "mean_sd"] + surface),
        (
            "current_speed",
            ["east", "north", "east_sd", "north_sd", "speed", "speed_sd", "dir", "speed_mean_sd"],
        ),
    ):
        with rasterio.open(out / f"{target}.tif") as ds:
            assert ds.crs.to_epsg() == int(summary["crs"].split(":")[1])
            assert list(ds.descriptions) == bands
            bands = [b for b in bands if b not in surface]
            assert ds.tags(ns="IMAGE_STRUCTURE")["LAYOUT"] == "COG"
            assert ds.profile["tiled"] and ds.profile["compress"] == "deflate"
            assert math.isnan(ds.nodata)
            assert ds.tags()["model_terms"] == " + ".join(fits[target].model_.terms)
            data = ds.read()
            to_utm = Transformer.from_crs(4326, ds.crs.to_epsg(), always_xy=True)
            to_ll = Transformer.from_crs(ds.crs.to_epsg(), 4326, always_xy=True)
            e, n = to_utm.transform(lon, lat)
            for ei, ni in zip(e, n, strict=True):
                row, col = ds.index(ei, ni)
                xc, yc = ds.xy(row, col)  # the cell's centre
                clon, clat = to_ll.transform(xc, yc)
                pred = fits[target].predict(clat, clon)
                want = _bands(pred, fits[target])
                for b, name in enumerate(bands):
                    assert abs(data[b, row, col] - want[name]) < TOL, (target, name)


def _bands(pred: dict, fit) -> dict[str, float]:
    from forcemap.host.gis.grid import layer_bands

    return {k: float(v[0]) for k, v in layer_bands(fit.model_, pred).items()}


def test_netcdf_round_trip_and_cf_attributes(fitted):
    survey, fits, out, summary = fitted
    epsg = summary_epsg(summary)
    ds = xr.open_dataset(out / "maps.nc", decode_times=False)
    assert ds.attrs["Conventions"] == "CF-1.8"
    std = {v: ds[v].attrs.get("standard_name") for v in ds.data_vars}
    assert std["depth"] == "sea_floor_depth_below_sea_surface"
    assert std["depth_sd"] == "sea_floor_depth_below_sea_surface standard_error"
    assert std["current_east"] == "eastward_sea_water_velocity"
    assert std["current_north"] == "northward_sea_water_velocity"
    assert ds["depth"].attrs["ancillary_variables"] == "depth_sd depth_mean_sd"
    assert "predictive" in ds["depth_sd"].attrs["long_name"]
    assert "of the mean only" in ds["depth_mean_sd"].attrs["long_name"]
    assert ds["current_east"].attrs["ancillary_variables"] == "current_east_sd"
    import netCDF4

    with netCDF4.Dataset(
        out / "maps.nc"
    ) as raw:  # the attributes as written, not as xarray decodes them
        for v in ("depth", "current_speed", "current_dir", "current_speed_sd"):
            assert raw[v].grid_mapping == "crs"
            assert set(raw[v].coordinates.split()) >= {"lat", "lon"}
            assert raw[v].dimensions == ("y", "x")
    assert ds["crs"].attrs["grid_mapping_name"] == "transverse_mercator"
    assert ds["lat"].attrs["standard_name"] == "latitude" and ds["lat"].dims == ("y", "x")
    assert ds["lon"].attrs["units"] == "degrees_east"
    assert ds["x"].attrs["standard_name"] == "projection_x_coordinate"
    assert ds["time"].attrs["bounds"] == "time_bnds"
    t = survey.table.columns["t"]
    assert ds["time_bnds"].values.tolist() == [t.min(), t.max()]
    assert ds.attrs["time_coverage_start"] < ds.attrs["time_coverage_end"]
    assert "depth: const + gp(position, matern32)" in ds.attrs["model_terms"]
    # the 2-D lat/lon are the grid's cell centres, projected back
    to_ll = Transformer.from_crs(epsg, 4326, always_xy=True)
    X, Y = np.meshgrid(ds["x"].values, ds["y"].values)
    lon, lat = to_ll.transform(X, Y)
    assert np.allclose(lat, ds["lat"].values, atol=1e-9) and np.allclose(
        lon, ds["lon"].values, atol=1e-9
    )
    res = float(ds.attrs["resolution_m"])
    to_utm = Transformer.from_crs(4326, epsg, always_xy=True)
    for la, lo in zip(*_samples(survey), strict=True):
        e, n = to_utm.transform(lo, la)
        col = int(np.flatnonzero(np.abs(ds["x"].values - e) <= res / 2)[0])
        row = int(np.flatnonzero(np.abs(ds["y"].values - n) <= res / 2)[0])
        clat, clon = float(ds["lat"][row, col]), float(ds["lon"][row, col])
        depth = fits["depth"].predict(clat, clon)
        assert abs(float(ds["depth"][row, col]) - depth["mean"][0]) < TOL
        assert abs(float(ds["depth_sd"][row, col]) - depth["std"][0]) < TOL
        cur = _bands(fits["current_speed"].predict(clat, clon), fits["current_speed"])
        for band in ("east", "north", "speed", "dir", "speed_sd"):
            assert abs(float(ds[f"current_{band}"][row, col]) - cur[band]) < TOL


def test_masked_cells_are_far_from_every_sample(fitted):
    """Blank beyond the mask distance and beyond the reach of the blocked CV (an untested extrapolation);
    within both, blank only where the predictive sd exceeds the measured depths' own spread."""
    survey, fits, out, summary = fitted
    with rasterio.open(out / "depth.tif") as ds:
        mean, sd = ds.read(1), ds.read(2)
    from forcemap.host.gis.grid import SD_SHARE
    from scipy.spatial import cKDTree

    grid = make_grid(survey.table, 4.0)
    dist, _ = cKDTree(survey.table.xy).query(grid.local_xy)
    dist = dist.reshape(mean.shape)
    reach = summary["coverage95"]["depth"]["reach_m"]
    assert 0 < reach and summary["blank_cells"]["depth"] > 0
    assert np.isnan(mean[dist > min(summary["mask_distance_m"], reach)]).all()
    inside = dist < min(summary["mask_distance_m"], reach) - 1.0
    assert np.isfinite(mean[inside]).mean() > 0.9
    signal = float(np.std(fits["depth"].model_.measured))
    assert (sd[np.isfinite(sd)] <= SD_SHARE * signal).all()


def test_contours_are_lonlat_lines_at_round_levels(fitted):
    survey, _, out, _ = fitted
    fc = json.loads((out / "depth-contours.geojson").read_text())
    assert fc["type"] == "FeatureCollection" and len(fc["features"]) >= 3
    lat, lon = survey.table.columns["lat"], survey.table.columns["lon"]
    with rasterio.open(out / "depth.tif") as ds:
        depth = ds.read(1)
    for f in fc["features"]:
        assert f["geometry"]["type"] == "MultiLineString"
        assert np.nanmin(depth) < f["properties"]["level"] < np.nanmax(depth)
        pts = np.array([p for line in f["geometry"]["coordinates"] for p in line])
        assert (abs(pts[:, 1] - lat.mean()) < 0.01).all() and (
            abs(pts[:, 0] - lon.mean()) < 0.01
        ).all()
    assert not (out / "current_speed-contours.geojson").exists()  # a vector has no contours


@pytest.mark.parametrize(
    ("lat0", "lon0", "epsg"),
    [
        (45.0, 5.97, 32631),  # west of the 6 E boundary
        (45.0, 6.03, 32632),  # east of it
        (-45.0, 5.97, 32731),  # the same in the south
        (-45.0, 6.03, 32732),
        (60.3, 5.3, 32632),  # Bergen: Norway's exception puts 3-12 E in zone 32
        (-16.0, 179.9, 32760),  # beside the antimeridian, not across it
        (83.5, -27.0, 32626),  # north of 80 N, within UTM's limit
        (78.2, 15.6, 32633),  # Longyearbyen: Svalbard's zones are 31, 33, 35 and 37
    ],
)
def test_utm_zone_on_each_side_of_a_boundary(lat0, lon0, epsg, tmp_path):
    table = make_survey("river", [], 1, 200.0, tmp_path, extra=moved(lat0, lon0))
    survey = load_survey(table)
    assert utm_epsg(survey.columns["lat"], survey.columns["lon"])[0] == epsg
    grid = make_grid(survey, 10.0)
    assert grid.epsg == epsg and grid.mask.any()
    # every sample falls in a cell of the grid, and that cell's centre is within a cell of it
    row, col = cell_of(grid, survey.columns["lat"], survey.columns["lon"])
    assert (0 <= row).all() and (row < grid.ny).all() and (0 <= col).all() and (col < grid.nx).all()
    d = np.hypot(*(grid.local_xy.reshape(grid.ny, grid.nx, 2)[row, col] - survey.xy).T)
    assert d.max() < 10.0 * math.sqrt(2) / 2 + 0.01


def test_a_survey_astride_a_zone_boundary_is_gridded_in_its_centres_zone(fitted, capsys):
    survey, _, _, summary = fitted
    lon = survey.table.columns["lon"]
    assert lon.min() < 6.0 < lon.max()  # the fixture's survey spans zones 31 and 32
    grid = make_grid(survey.table, 4.0)
    assert grid.epsg == summary_epsg(summary) == 32732
    assert any("spans UTM zones 31, 32" in n for n in grid.notes)


def summary_epsg(summary: dict) -> int:
    return int(summary["crs"].split(":")[1])


@pytest.mark.parametrize(
    ("lat0", "lon0", "message"),
    [
        (84.5, 10.0, "beyond UTM's limits"),
        (-80.5, 10.0, "beyond UTM's limits"),
        (-16.0, 180.0, "crosses the antimeridian"),
    ],
)
def test_polar_and_antimeridian_surveys_are_refused_in_one_line(
    lat0, lon0, message, tmp_path, capsys
):
    table = make_survey("river", [], 1, 200.0, tmp_path, extra=moved(lat0, lon0))
    rc = main(["grid", str(table), "-o", str(tmp_path / "m.nc"), "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and message in err[0]
    assert not (tmp_path / "m.nc").exists()


def test_without_the_extra_grid_names_it_and_exits_2(tmp_path):
    code = (
        "import sys; sys.modules['rasterio'] = None\n"
        "from forcemap.host.cli import main\n"
        f"sys.exit(main(['grid', {str(tmp_path / 'x.csv')!r}, '-o', 'm.nc']))"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.strip() == (  # the spelling for how forcemap was installed: a clone here
        f"forcemap grid: forcemap grid's maps need rasterio: {install_hint('gis')}"
    )


def test_existing_outputs_need_force(fitted, capsys):
    survey, _, out, _ = fitted
    before = (out / "depth.tif").read_bytes()
    rc = main(["grid", str(survey.path), "-o", str(out / "depth.tif"), "--target", "depth"])
    assert rc == 2 and "--force" in capsys.readouterr().err
    assert (out / "depth.tif").read_bytes() == before


# canonical units of the standard names the files use, from the CF standard name table (v84); the checker
# is given this excerpt because the table's home, cfconventions.org, cannot be reached from the test
CANONICAL = {
    "sea_floor_depth_below_sea_surface": "m",
    "sea_water_temperature": "K",
    "eastward_sea_water_velocity": "m s-1",
    "northward_sea_water_velocity": "m s-1",
    "sea_water_speed": "m s-1",
    "direction_of_sea_water_velocity": "degree",
    "eastward_wind": "m s-1",
    "northward_wind": "m s-1",
    "wind_speed": "m s-1",
    "wind_from_direction": "degree",
    "latitude": "degree_north",
    "longitude": "degree_east",
    "projection_x_coordinate": "m",
    "projection_y_coordinate": "m",
    "time": "s",
}


def _tables(folder) -> list[str]:
    entries = "".join(
        f'<entry id="{n}"><canonical_units>{u}</canonical_units></entry>'
        for n, u in CANONICAL.items()
    )
    head = "<version_number>84</version_number><last_modified>2024-01-19T15:55:10Z</last_modified>"
    lists = "<version_number>84</version_number><date>2024-01-19</date>"
    files = {
        "-s": f"<standard_name_table>{head}{entries}</standard_name_table>",
        "-a": f"<area_type_table>{lists}</area_type_table>",
        "-r": f"<standardized_region_list>{lists}</standardized_region_list>",
    }
    args = []
    for flag, text in files.items():
        path = folder / f"table{flag}.xml"
        path.write_text(text)
        args += [flag, str(path)]
    return args


def _udunits_env(folder) -> dict:
    """cfchecks' units library (cfunits) needs the UDUNITS-2 C library: the one the cf-units wheel from
    PyPI bundles, under the name ctypes looks for, with its unit database."""
    import os
    from pathlib import Path

    import cf_units

    folder.mkdir(exist_ok=True)
    root = Path(cf_units.__file__).parent
    (lib,) = (root.parent / "cf_units.libs").glob("libudunits2*.so*")
    (folder / "libudunits2.so").symlink_to(lib)
    return {
        **os.environ,
        "LD_LIBRARY_PATH": f"{folder}:{lib.parent}",
        "UDUNITS2_XML_PATH": str(root / "etc" / "share" / "udunits2.xml"),
    }


def test_the_cf_checker_finds_no_error_or_warning(fitted, tmp_path):
    import shutil

    _, _, out, _ = fitted
    cmd = [shutil.which("cfchecks"), "-v", "1.8", *_tables(tmp_path), str(out / "maps.nc")]
    proc = subprocess.run(cmd, capture_output=True, text=True, env=_udunits_env(tmp_path))
    report = proc.stdout
    assert "ERRORS detected: 0" in report and "WARNINGS given: 0" in report, report[-3000:]
    # the checker does check: a copy whose depth has units of time and a grid mapping that is not there
    import netCDF4

    bad = tmp_path / "bad.nc"
    shutil.copy(out / "maps.nc", bad)
    with netCDF4.Dataset(bad, "a") as ds:
        ds["depth"].units = "s"
        ds["depth_sd"].grid_mapping = "nowhere"
    proc = subprocess.run(
        [*cmd[:-1], str(bad)], capture_output=True, text=True, env=_udunits_env(tmp_path / "again")
    )
    assert "ERRORS detected: 2" in proc.stdout, proc.stdout[-3000:]


def test_json_dash_is_only_json_on_stdout(fitted, tmp_path, capsys):
    survey, fits, _, _ = fitted
    out = tmp_path / "depth.nc"
    rc = main(["grid", str(survey.path), "-o", str(out), "--target", "depth", "--json", "-"])
    assert rc == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["files"] == [str(out)] and summary["targets"]["depth"] == " + ".join(
        fits["depth"].model_.terms
    )
