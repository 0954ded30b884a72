"""A real tidal current, from the pipeline's own current: San Francisco Bay's City Front on a flood.

tests/data/real/nmea/sfbay/PROVENANCE.md: a racing yacht inside the Golden Gate, 2014-05-17, 16:37
to 24:00 UTC, the instruments (speed log, compass) on until about 21:30. From the table the user
gets (``forcemap import`` with its calibration, ``forcemap export``; shared for the run by
tests/real_cases.py), two properties any correct pipeline has on a flood tide there:

- the stream sets along the channel, into the bay: every half hour from 17:30 to 21:00 UTC, the mean
  current is within 30 deg of the channel's axis (070 deg: the Golden Gate's axis, the Gate running
  340/160), and its along-axis part is positive and clear of its own noise (the mean over more than
  three of its standard errors, from the rows' own scatter and correlation);
- the stream changes with time where the boat comes back: at the same place (within 200 m) and on
  the same heading (within 20 deg: the same leeway), minute means of the current more than an hour
  apart differ more than those less than ten minutes apart (a one-sided Mann-Whitney test on pairs
  that share no minute, p < 0.01).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from forcemap.host.vessel.geodesy import LocalFrame

from bench.inject_verify import lag1, read_table

SFBAY = "nmea/sfbay/swift-day1.nmea.gz"
CHANNEL_DEG = 70.0
UNDER_WAY = 1.0  # m/s through the water: a heading and a speed log that say where the water goes


@pytest.fixture(scope="module")
def sfbay(real_case):
    built = real_case(SFBAY)
    assert built.import_rc == 0, built.import_text
    t = read_table(str(built.csv))
    ok = (t["stw"] > UNDER_WAY) & np.isfinite(t["current_east"]) & np.isfinite(t["lat"])
    return {k: v[ok] for k, v in t.items()}


@pytest.mark.slow
def test_the_flood_sets_along_the_channel_every_half_hour(sfbay):
    t, e, n = sfbay["t"], sfbay["current_east"], sfbay["current_north"]
    day = t[0] - t[0] % 86400.0
    ua = (math.sin(math.radians(CHANNEL_DEG)), math.cos(math.radians(CHANNEL_DEG)))
    windows = 0
    for start in np.arange(17.5, 21.0, 0.5):
        m = (t >= day + start * 3600) & (t < day + (start + 0.5) * 3600)
        assert m.sum() > 900, (start, m.sum())  # under way for most of each half hour
        me, mn = e[m].mean(), n[m].mean()
        off = (math.degrees(math.atan2(me, mn)) - CHANNEL_DEG + 180) % 360 - 180
        along = e[m] * ua[0] + n[m] * ua[1]
        rho = min(max(lag1(along), 0.0), 0.999)
        n_eff = m.sum() * (1 - rho) / (1 + rho)
        se = along.std() / math.sqrt(n_eff)
        assert abs(off) < 30 and along.mean() > 3 * se, (start, off, along.mean(), se)
        windows += 1
    assert windows == 7


@pytest.mark.slow
def test_the_stream_changes_where_the_boat_comes_back(sfbay):
    from scipy.spatial import cKDTree
    from scipy.stats import mannwhitneyu

    t = sfbay["t"]
    k = np.floor((t - t[0]) / 60.0).astype(int)
    _, inv, cnt = np.unique(k, return_inverse=True, return_counts=True)

    def minute(v):
        return np.bincount(inv, v) / cnt

    hs, hc = (minute(f(np.radians(sfbay["heading"]))) for f in (np.sin, np.cos))
    frame = LocalFrame(float(np.median(sfbay["lat"])), float(np.median(sfbay["lon"])))
    x, y = frame.to_local(sfbay["lat"], sfbay["lon"])
    keep = (cnt >= 30) & (np.hypot(hs, hc) > 0.95)  # most of the minute, on one steady heading
    tm, e, n, xm, ym = (
        minute(v)[keep] for v in (t, sfbay["current_east"], sfbay["current_north"], x, y)
    )
    head = np.degrees(np.arctan2(hs[keep], hc[keep]))
    pairs = cKDTree(np.c_[xm, ym]).query_pairs(200.0, output_type="ndarray")
    same = np.abs((head[pairs[:, 0]] - head[pairs[:, 1]] + 180) % 360 - 180) < 20
    pairs = pairs[same]
    gap = np.abs(tm[pairs[:, 0]] - tm[pairs[:, 1]])
    diff = np.hypot(*(np.c_[e, n][pairs[:, 0]] - np.c_[e, n][pairs[:, 1]]).T)
    apart = np.hypot(xm[pairs[:, 0]] - xm[pairs[:, 1]], ym[pairs[:, 0]] - ym[pairs[:, 1]])

    def independent(sel):
        """The closest pairs first, each minute in one pair at most."""
        used, out = set(), []
        for i in np.flatnonzero(sel)[np.argsort(apart[sel])]:
            a, b = pairs[i]
            if a not in used and b not in used:
                used |= {a, b}
                out.append(diff[i])
        return np.array(out)

    short, long = independent(gap < 600), independent(gap > 3600)
    assert len(short) >= 20 and len(long) >= 20, (len(short), len(long))
    p = mannwhitneyu(long, short, alternative="greater").pvalue
    assert p < 0.01, (p, np.sqrt(np.mean(short**2)), np.sqrt(np.mean(long**2)))
