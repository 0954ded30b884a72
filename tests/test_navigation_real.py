"""Navigation smoothed on every real NMEA log that imports (issue 29): no row lost, and positions that
agree with the speed over ground.

Two properties per log, each checked by hand on the logs:
- every row the pipeline made is still there, at the same time, with every column it had;
- the speed from successive positions agrees with the table's SOG within 0.5 m/s at p95 (the
  data-quality check's own measure, host/workbench/data_quality.speed_mismatch), and agrees with
  the receiver's own SOG (the logged rows') better than the logged positions did: one receiver's
  RMC, GGA and GLL interleaved (PacCup, irene), a slow receiver's last fix held (the simulator,
  tests/test_navigation.py) are what the smoothing removes.

``irene_2013-07-31_flensburg_checksums.nmea`` does not import until its checksum variant is read
(issue 28); the tlogs and the DataFlash log have no position or no measurement, so no rows.
"""

from __future__ import annotations

import numpy as np
import pytest
from forcemap.host.convert.export import samples_table
from forcemap.host.convert.importers import import_to_mcap
from forcemap.host.workbench import data_quality
from forcemap.host.workbench.table import survey_from_columns

from tests.tools import real_data

REAL = real_data()
LOGS = [
    "nmea/PacCupStartNMEA.txt",
    "nmea/NeutronDance.log",
    "nmea/bundg_zeus_9.log",
    "nmea/plaka.log",
    "nmea/irene/irene_2008-08-20_geneva.nmea",
    "nmea/irene/irene_2013-08-03_flensburg.nmea",
    "nmea/irene/irene_2014-06-27_geneva.nmea",
]
MAX_MISMATCH = 0.5  # m/s at p95 (issue 29)


def _columns(table) -> dict[str, np.ndarray]:
    return {
        c: np.array([np.nan if v is None else v for v in table.column(c)]) for c in table.columns
    }


def _against_logged_sog(cols: dict[str, np.ndarray], sog: np.ndarray) -> float:
    """p95 of |speed from successive rows - the logged rows' SOG| (m/s)."""
    from forcemap.host.vessel.geodesy import LocalFrame

    frame = LocalFrame(float(np.nanmedian(cols["lat"])), float(np.nanmedian(cols["lon"])))
    x, y = frame.to_local(cols["lat"], cols["lon"])
    dt = np.diff(cols["t"])
    speed = np.hypot(np.diff(x), np.diff(y)) / dt
    d = np.abs(speed - 0.5 * (sog[1:] + sog[:-1]))
    return float(np.nanpercentile(d[dt > 0.05], 95))


@pytest.mark.parametrize("name", LOGS)
def test_real_log_smoothed(name, tmp_path):
    out = tmp_path / "log.mcap"
    import_to_mcap(REAL / name, out)
    logged = samples_table([out], navigation="logged")
    smoothed = samples_table([out])
    lc, sc = _columns(logged), _columns(smoothed)
    assert np.array_equal(lc["t"], sc["t"])
    assert set(logged.columns) <= set(smoothed.columns)
    for c in ("lat", "lon"):
        assert np.isfinite(sc[c]).sum() >= np.isfinite(lc[c]).sum()
    survey = survey_from_columns(out, sc)
    mismatch = data_quality.speed_mismatch(survey)
    assert mismatch is not None and mismatch <= MAX_MISMATCH
    # against the receiver's own SOG, the smoothed positions do better than the logged ones
    assert _against_logged_sog(sc, lc["sog"]) < _against_logged_sog(lc, lc["sog"])
