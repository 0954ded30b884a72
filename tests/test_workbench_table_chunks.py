"""A samples table read a chunk of rows at a time (CSV) or a row group at a time (Parquet) gives the survey the
whole file gives: the same numbers, the same notes naming the same data rows, the same columns of words."""

from __future__ import annotations

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from forcemap.host.workbench.survey import table_files
from forcemap.host.workbench.survey.cleaning import to_numeric
from forcemap.host.workbench.survey.table import load_survey


def _columns(n: int) -> dict[str, list[str]]:
    rng = np.random.default_rng(5)
    t = 1.7e9 + np.arange(n) * 0.5
    lat = 33.95 + 1e-5 * np.cumsum(rng.uniform(0, 1, n))
    lon = -81.05 + 1e-5 * np.cumsum(rng.uniform(0, 1, n))
    depth = [f"{v:.3f}" for v in 2.0 + rng.standard_normal(n)]
    depth[37] = "x1.5"  # a cell that is not a number, in the second chunk of 25 rows
    depth[80] = "n/a"  # empty: missing, no note
    depth[81] = "inf"
    # a column of numbers with a chunk of words in it (rows 50-74): numbers elsewhere keep it numeric
    sog = [f"{v:.2f}" for v in rng.uniform(1, 3, n)]
    for i in range(50, 75):
        sog[i] = "stopped"
    words = ["boat-a"] * n  # a column of words
    return {
        "t": [f"{v:.3f}" for v in t],
        "lat": [f"{v:.8f}" for v in lat],
        "lon": [f"{v:.8f}" for v in lon],
        "depth": depth,
        "sog": sog,
        "name": words,
    }


def _whole(cols: dict[str, list[str]]):
    """What the table's cells give read whole (`to_numeric` on every column at once)."""
    out = {k: to_numeric(v) for k, v in cols.items()}
    return {k: c for k, c in out.items() if c is not None}, {k for k, c in out.items() if c is None}


def test_a_csv_read_in_chunks_equals_the_whole(tmp_path, monkeypatch):
    cols = _columns(130)
    path = tmp_path / "s.csv"
    lines = [",".join(cols)] + [",".join(r) for r in zip(*cols.values(), strict=True)]
    lines.insert(60, "")  # a blank line is skipped, not a row
    path.write_text("\n".join(lines) + "\n")
    monkeypatch.setattr(table_files, "CHUNK_ROWS", 25)
    monkeypatch.setattr(table_files._csv_chunks, "__defaults__", (25,))
    assert len(list(table_files._csv_chunks(path))) == 6  # read 25 rows at a time
    numeric, words, _ = table_files.read_numeric(path)
    want, want_words = _whole(cols)
    assert words == want_words == {"name"}
    assert set(numeric) == set(want)
    for k, c in want.items():
        np.testing.assert_array_equal(numeric[k].values, c.values)
        assert numeric[k].not_numbers == c.not_numbers and numeric[k].infinite == c.infinite
        assert numeric[k].notes(k) == c.notes(k)
    assert numeric["depth"].not_numbers == [(37, "x1.5")] and numeric["depth"].infinite == [81]
    assert len(numeric["sog"].not_numbers) == 25
    s = load_survey(path)
    assert s.n == 130 and "name" in s.non_numeric
    assert any("data row 38 'x1.5'" in note for note in s.notes)


def test_a_parquet_file_read_by_row_groups_equals_the_csv(tmp_path):
    cols = _columns(130)
    csv_path = tmp_path / "s.csv"
    csv_path.write_text(
        "\n".join([",".join(cols)] + [",".join(r) for r in zip(*cols.values(), strict=True)]) + "\n"
    )
    numeric, _, _ = table_files.read_numeric(csv_path)
    arrays = {k: c.values for k, c in numeric.items() if k != "sog"}
    arrays["name"] = np.array(cols["name"])
    pq_path = tmp_path / "s.parquet"
    pq.write_table(pa.table(arrays), pq_path, row_group_size=40)
    assert pq.ParquetFile(pq_path).num_row_groups == 4
    got, words, _ = table_files.read_numeric(pq_path)
    assert words == {"name"}
    for k, a in arrays.items():
        if k != "name":
            np.testing.assert_array_equal(got[k].values, a)
    a, b = load_survey(csv_path), load_survey(pq_path)
    np.testing.assert_array_equal(a.xy, b.xy)
    np.testing.assert_array_equal(a.columns["depth"], b.columns["depth"])


@pytest.mark.parametrize("text", ["", "t,lat,lon\n"])
def test_an_empty_table_is_still_one_clear_line(tmp_path, text):
    from forcemap.host.workbench.errors import WorkbenchError

    path = tmp_path / "e.csv"
    path.write_text(text)
    with pytest.raises(WorkbenchError, match="empty|no rows"):
        load_survey(path)
