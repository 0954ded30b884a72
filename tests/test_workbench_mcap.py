"""The workbench reads an MCAP log through `forcemap export`'s reader: one path from log to table."""

from __future__ import annotations

import pytest
from forcemap.host.convert.export import samples_table
from forcemap.host.log.mcap import McapLog
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.survey.table import load_survey
from mcap.reader import make_reader

from tests.test_export import T0, _log, _row


def test_a_truncated_log_that_export_recovers_loads_in_the_workbench(tmp_path):
    path = _log(tmp_path, n=4000)
    cut = tmp_path / "cut.mcap"
    data = path.read_bytes()
    cut.write_bytes(data[: len(data) * 2 // 3])
    # the mcap library's own reader gives up on the cut file (what the workbench used before)
    with pytest.raises(Exception), cut.open("rb") as f:  # noqa: B017 - any of its errors
        list(make_reader(f).iter_messages(topics=["/samples"]))
    rows = len(samples_table([cut]))
    assert 1000 < rows < 4000
    survey = load_survey(cut)
    assert survey.n == rows
    assert survey.columns["t"][0] == T0 and survey.columns["t"][-1] == T0 + (rows - 1) * 0.25


def test_repeated_samples_are_read_once(tmp_path):
    with McapLog(tmp_path / "logs") as log:
        for i in list(range(40)) + list(range(20, 40)):  # a replayed stretch: rows 20-39 twice
            log.write("/samples", int((T0 + i * 0.25) * 1e9), _row(i))
    survey = load_survey(log.path)
    assert survey.n == 40 == len(samples_table([log.path]))


def test_a_table_named_mcap_is_one_clear_error(tmp_path):
    fake = tmp_path / "survey.mcap"
    fake.write_text("t,lat,lon\n1,47,8\n")
    with pytest.raises(WorkbenchError, match="not an MCAP log"):
        load_survey(fake)
