"""`forcemap export`: the samples table in the conventions' columns, and the track."""

from __future__ import annotations

import csv
import json
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import pyarrow.parquet as pq
import pytest
from forcemap.host.cli import main
from forcemap.host.convert.export import COLUMNS, samples_table
from forcemap.host.log.mcap import McapLog
from forcemap.host.log.messages import LocationFix

ROOT = Path(__file__).resolve().parents[1]
T0 = 1_750_000_000.0


def _row(i: int, **over) -> dict:
    row = dict.fromkeys(COLUMNS)
    row.update(
        t=T0 + i * 0.25,
        lat=47.0 + i * 1e-5,
        lon=8.0 + i * 2e-5,
        heading=90.0,
        sog=1.5,
        cog=91.0,
        wind_speed=3.0,
        wind_dir=270.0,
        current_speed=0.4,
        current_dir=180.0,
        depth=None if i < 3 else 2.0 + i / 100,  # no sounding yet at the start
    )
    row.update(over)
    return row


def _log(tmp_path: Path, n: int = 40, fixes: bool = True, **over) -> Path:
    with McapLog(tmp_path / "logs") as log:
        for i in range(n):
            t_ns = int((T0 + i * 0.25) * 1e9)
            log.write("/samples", t_ns, _row(i, **over))
            if fixes:
                log.write("/fix", t_ns, LocationFix.at(t_ns, 47.0 + i * 1e-5, 8.0 + i * 2e-5))
    return log.path


def test_columns_are_the_documented_ones_in_order():
    doc = (ROOT / "docs" / "CONVENTIONS.md").read_text()
    table = doc[doc.index("## The samples table") :].split("### Column families")[0]
    names = []
    for cell in re.findall(r"^\| (.+?) \|", table, re.M)[1:]:
        for name in re.findall(r"`([a-z0-9_]+)`", cell):
            names.append(name)
        if "…" in cell:  # `wheel1_speed` … `wheel4_speed`
            names[-1:-1] = ["wheel2_speed", "wheel3_speed"]
    assert tuple(names) == COLUMNS


def test_csv_keeps_order_leaves_out_empty_columns_and_writes_blanks(tmp_path):
    path = _log(tmp_path, water_temp=None, extra_probe=1.25, note="text")
    out = tmp_path / "s.csv"
    assert main(["export", str(path), "-o", str(out)]) == 0
    rows = list(csv.reader(out.open()))
    header = rows[0]
    expected = [
        c
        for c in COLUMNS
        if c
        in (
            "t",
            "lat",
            "lon",
            "heading",
            "sog",
            "cog",
            "depth",
            "wind_speed",
            "wind_dir",
            "current_speed",
            "current_dir",
        )
    ]
    # None throughout and text columns are left out; each sounding's TVU follows (issue 37)
    assert header == expected + ["extra_probe", "depth_tvu"]
    assert len(rows) == 41
    first = dict(zip(header, rows[1], strict=True))
    assert first["depth"] == "" and float(first["t"]) == T0 and first["extra_probe"] == "1.25"
    assert float(dict(zip(header, rows[10], strict=True))["depth"]) == pytest.approx(2.09)
    assert first["depth_tvu"] == "" and float(dict(zip(header, rows[10], strict=True))["depth_tvu"]) > 0


def test_parquet_has_nulls_and_float_columns(tmp_path):
    path = _log(tmp_path)
    out = tmp_path / "s.parquet"
    assert main(["export", str(path), "-o", str(out)]) == 0
    table = pq.read_table(out)
    assert table.column_names[:3] == ["t", "lat", "lon"]
    assert table.num_rows == 40
    depth = table.column("depth").to_pylist()
    assert depth[:3] == [None, None, None] and depth[3] == pytest.approx(2.03)
    assert str(table.schema.field("t").type) == "double"


def test_several_files_are_one_table_in_time_order(tmp_path):
    a = _log(tmp_path / "a", n=10)
    with McapLog(tmp_path / "b") as log:
        for i in range(10, 20):
            log.write("/samples", int((T0 + i * 0.25) * 1e9), _row(i))
    table = samples_table([log.path, a])
    assert table.column("t") == [T0 + i * 0.25 for i in range(20)]


def test_truncated_log_exports_its_complete_part(tmp_path):
    path = _log(tmp_path, n=4000)
    cut = tmp_path / "cut.mcap"
    data = path.read_bytes()
    cut.write_bytes(data[: len(data) * 2 // 3])
    n = len(samples_table([cut]))
    assert 0 < n < 4000


def test_geojson_track_from_fix_and_sample_points(tmp_path):
    path = _log(tmp_path)
    out = tmp_path / "track.geojson"
    assert main(["export", str(path), "-o", str(out)]) == 0
    doc = json.loads(out.read_text())
    line = doc["features"][0]
    assert line["geometry"]["type"] == "LineString"
    assert len(line["geometry"]["coordinates"]) == 40
    assert line["geometry"]["coordinates"][0] == pytest.approx([8.0, 47.0])  # lon, lat
    points = [f for f in doc["features"] if f["geometry"]["type"] == "Point"]
    assert len(points) == 40 and points[0]["properties"]["wind_dir"] == 270.0


def test_kml_track_falls_back_to_samples_without_fix(tmp_path):
    path = _log(tmp_path, fixes=False)
    out = tmp_path / "track.kml"
    assert main(["export", str(path), "-o", str(out)]) == 0
    root = ET.parse(out).getroot()
    ns = {"k": "http://www.opengis.net/kml/2.2"}
    coords = root.find(".//k:LineString/k:coordinates", ns).text.split()
    assert len(coords) == 40
    lon, lat, _ = map(float, coords[0].split(","))
    assert (lat, lon) == pytest.approx((47.0, 8.0))


def test_missing_file_is_an_error_not_a_traceback(tmp_path, capsys):
    assert main(["export", str(tmp_path / "nope.mcap")]) == 2  # bad input, not a bug
    assert "nope.mcap" in capsys.readouterr().err


def test_a_directory_means_its_mcap_files(tmp_path, capsys):
    path = _log(tmp_path, n=10)
    out = tmp_path / "s.csv"
    assert main(["export", str(path.parent), "-o", str(out)]) == 0
    assert len(out.read_text().splitlines()) == 11
    assert main(["export", str(tmp_path / "empty_dir_that_is_missing")]) == 2
