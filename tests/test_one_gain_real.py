"""One calibration, one estimate: the shipped log the guide follows (tests/data/real/nmea/bundg_zeus_9.log).

`import` estimates the speed log's gain on the first pass's rows; `check` and `fit` of the exported table
estimate it again on the table. They once differed (0.688 ± 0.097 against 0.585 ± 0.090): the import read
the navigation as logged, the table has it smoothed, its latencies removed. The import now estimates on
the rows as the export will give them, so the two are one estimate; and a table's estimate says it is of
the table's `stw` (after any gain the import applied). Applied, a gain leaves nothing to the table: the
residual gain is 1 within its sd, and the misalignment reaches the table's current.

The same log's wind map carries `gp(pitch)`: `fit` gives its lengthscale in degrees, and `grid` says the
map is drawn at the pitch's median (in its notes and the files' metadata).
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import math
import re

import numpy as np
import pytest
from forcemap.host.cli import main

from tests.tools import real_data

LOG = real_data() / "nmea" / "bundg_zeus_9.log"


def _run(*argv: str) -> str:
    """A command's stdout and stderr; it must exit 0."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
        rc = main([str(a) for a in argv])
    assert rc == 0, out.getvalue()[-2000:]
    return out.getvalue()


def _gain(path, folder) -> dict:
    """`forcemap check PATH`'s speed-log gain finding."""
    report = folder / f"{path.name}.json"
    _run("check", path, "--json", report)
    found = json.loads(report.read_text())["categories"]["speed_through_water"]["findings"]
    return next(f for f in found if f["check"] == "gain")


def _imported(folder, boat: str | None = None) -> tuple:
    """The log imported (with a boat file's pins) and exported: the log, the table."""
    mcap, table = folder / "zeus.mcap", folder / "zeus.csv"
    extra = []
    if boat is not None:
        (folder / "boat.toml").write_text(boat)
        extra = ["--boat", folder / "boat.toml"]
    _run("import", LOG, "-o", mcap, *extra)
    _run("export", mcap, "-o", table)
    return mcap, table


@pytest.fixture(scope="module")
def as_read(tmp_path_factory):
    folder = tmp_path_factory.mktemp("zeus")
    mcap, table = _imported(folder)
    return folder, table, _gain(mcap, folder), _gain(table, folder)


def test_import_and_the_exported_table_give_one_gain(as_read):
    _, _, log, table = as_read
    # one course: too uncertain to apply, so the table's stw is the log's as read
    assert not log["applied"] and not table["applied"]
    assert abs(table["value"] - log["value"]) < 0.01 * log["sd"], (log["message"], table["message"])
    assert abs(table["sd"] - log["sd"]) < 0.01 * log["sd"]
    # the table's estimate says what it is of, and what to pin from it
    assert "on the table's stw" in table["message"] and "on the table's stw" not in log["message"]
    assert "x the gain the log's import applied" in table["fix"]


def test_the_estimate_applied_leaves_the_table_a_gain_of_one(as_read, tmp_path):
    _, _, log, _ = as_read
    beta = float(log["extra"]["misalignment_deg"])
    boat = f"[speed_log]\ngain = {log['value']!r}\nmisalignment_deg = {beta!r}\n"
    _, table = _imported(tmp_path, boat)
    left = _gain(table, tmp_path)
    # the table's stw is the log's x the pinned gain: what is left is 1 within its sd
    assert abs(left["value"] - 1) <= left["sd"], left["message"]
    # no column is turned by the misalignment: the table still shows all of it
    assert abs(float(left["extra"]["misalignment_deg"]) - beta) < 0.5, left["message"]
    # ... and the table's current has it: the ground velocity less the stw along heading + beta
    c = _columns(table, ("sog", "cog", "heading", "stw", "current_east", "current_north"))

    def off(b: float) -> float:
        h, g = np.radians(c["heading"] + b), np.radians(c["cog"])
        e = c["sog"] * np.sin(g) - c["stw"] * np.sin(h) - c["current_east"]
        n = c["sog"] * np.cos(g) - c["stw"] * np.cos(h) - c["current_north"]
        return float(np.nanmax(np.hypot(e, n)))

    # what beta moves the current by
    turned = float(np.nanmedian(c["stw"])) * math.radians(abs(beta))
    assert off(beta) < 1e-6 and off(0.0) > 0.5 * turned, (off(beta), off(0.0), turned)


def test_a_covariates_map_says_where_it_is_drawn_and_its_lengthscale_has_a_unit(as_read):
    folder, table, _, _ = as_read
    text = _run("fit", table, "--target", "wind_speed", "--effects", "pitch")
    assert "gp(pitch, matern32): lengthscale=" in text
    line = next(s for s in text.splitlines() if "gp(pitch, matern32): lengthscale=" in s)
    assert " deg, std=" in line, line
    text = _run("grid", table, "-o", folder / "maps.nc", "--target", "wind_speed")
    said = re.search(
        r"note: wind_speed: (gp\(pitch, matern32\) drawn at pitch = (\S+) deg everywhere)", text
    )
    assert said, text
    pitch = _columns(table, ("pitch", "wind_speed"))
    both = np.isfinite(pitch["pitch"]) & np.isfinite(pitch["wind_speed"])  # the rows of the fit
    assert abs(float(said.group(2)) - np.median(pitch["pitch"][both])) < 0.01, said.group(0)
    import xarray as xr

    with xr.open_dataset(folder / "maps.nc", decode_times=False) as ds:
        assert said.group(1) in ds["wind_speed"].attrs["forcemap_notes"]


def _columns(table, names: tuple[str, ...]) -> dict[str, np.ndarray]:
    with table.open() as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) if r[k] else np.nan for r in rows]) for k in names}
