"""Fit on one day, predict the other: San Francisco Bay's two real days against NOAA's stations (issue 60).

    python -m bench.bench_reference_current [--effects tide] [--no-reference] [--cases-dir DIR]

The two logs of tests/data/real/nmea/sfbay (2014-05-17, City Front, a spring flood; 2014-05-10, a neap,
a wider course north to Raccoon Strait) are imported as a user imports them (tests/real_cases.py). Each
day in turn is the training day: `fit --target current_speed --effects EFFECTS` on it (with
`--reference-current` NOAA's 12 stations, tests/data/real/tides/noaa_sfbay_currents.json, unless
`--no-reference`), then the other day is predicted at each of its rows' places and times. Scored on
15-minute means while under way (SOG > 1 m/s, at least MIN_ROWS rows with a current in the bin): the
vector RMSE (east and north together) of

- the model's prediction (`SurveyModel.predict_grid` at each row, as `grid --at` maps it);
- the station nearest each bin's median position (its prediction along its flood axis);
- the training day's mean current vector (under way), for every bin;

on every bin, and on the bins whose median position is within NEAR_M of the training day's track.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from forcemap.host.vessel.geodesy import LocalFrame
from forcemap.host.workbench.survey.reference import load_reference, with_reference
from forcemap.host.workbench.survey.table import Survey, load_survey
from forcemap.host.workbench.targets.target_model import SurveyModel
from forcemap.host.workbench.terms.spec import BASELINE

DAYS = {"05-17": "nmea/sfbay/swift-day1.nmea.gz", "05-10": "nmea/sfbay/duxbury.nmea.gz"}
REFERENCE = Path(__file__).resolve().parents[1] / "tests/data/real/tides/noaa_sfbay_currents.json"
BIN_S = 900.0
UNDER_WAY = 1.0  # m/s over ground
MIN_ROWS = 60
NEAR_M = 500.0


@dataclass
class Bins:
    """15-minute means of a day under way: measured current, median place, and each row's bin."""

    rows: np.ndarray  # the day's rows that are binned
    bin_of: np.ndarray  # each of those rows' bin (0..nb-1)
    east: np.ndarray
    north: np.ndarray
    lat: np.ndarray
    lon: np.ndarray

    def mean(self, v: np.ndarray) -> np.ndarray:
        """Per-bin means of a value at the binned rows."""
        return np.bincount(self.bin_of, v) / np.bincount(self.bin_of)


def under_way(s: Survey) -> np.ndarray:
    c = s.columns
    ok = np.isfinite(c["current_east"]) & np.isfinite(c["current_north"])
    return np.flatnonzero(ok & (np.nan_to_num(c["sog"]) > UNDER_WAY))


def bins_of(s: Survey) -> Bins:
    """The day's 15-minute bins under way with at least MIN_ROWS rows."""
    c = s.columns
    rows = under_way(s)
    k = np.floor((c["t"][rows] - c["t"][0]) / BIN_S).astype(int)
    keys, inv, counts = np.unique(k, return_inverse=True, return_counts=True)
    keep = counts[inv] >= MIN_ROWS
    rows, k = rows[keep], k[keep]
    _, bin_of = np.unique(k, return_inverse=True)
    b = Bins(rows, bin_of, *(np.zeros(0),) * 4)
    b.east, b.north = b.mean(c["current_east"][rows]), b.mean(c["current_north"][rows])
    nb = bin_of.max() + 1
    b.lat = np.array([np.median(c["lat"][rows][bin_of == i]) for i in range(nb)])
    b.lon = np.array([np.median(c["lon"][rows][bin_of == i]) for i in range(nb)])
    return b


def rmse(e: np.ndarray, n: np.ndarray, b: Bins, mask: np.ndarray | None = None) -> float:
    m = np.ones(len(b.east), bool) if mask is None else mask
    return float(np.sqrt(np.mean((e[m] - b.east[m]) ** 2 + (n[m] - b.north[m]) ** 2)))


def station_prediction(ref, test: Survey, b: Bins) -> tuple[np.ndarray, np.ndarray]:
    """The station nearest each bin's median position, at each binned row's time, averaged per bin."""
    idx = ref.station_index(b.lat, b.lon)[b.bin_of]
    t = test.columns["t"][b.rows]
    e, n = np.zeros(len(t)), np.zeros(len(t))
    for i in np.unique(idx):
        st = ref.stations[ref.ids[i]]
        m = idx == i
        v, a = st.speed(t[m]), np.radians(st.flood_dir)
        e[m], n[m] = v * np.sin(a), v * np.cos(a)
    return b.mean(e), b.mean(n)


def model_prediction(sm: SurveyModel, test: Survey, b: Bins) -> tuple[np.ndarray, np.ndarray]:
    """The fitted model at each binned row's place and time, averaged per bin."""
    train = sm.survey
    x, y = LocalFrame(train.lat0, train.lon0).to_local(
        test.columns["lat"][b.rows], test.columns["lon"][b.rows]
    )
    p = sm.predict_grid(np.column_stack([x, y]), at=test.columns["t"][b.rows])
    return b.mean(p["east"]), b.mean(p["north"])


def near_track(train: Survey, b: Bins) -> np.ndarray:
    """Bins whose median position is within NEAR_M of the training day's track (under way)."""
    from scipy.spatial import cKDTree

    frame = LocalFrame(train.lat0, train.lon0)
    rows = under_way(train)
    tree = cKDTree(
        np.column_stack(frame.to_local(train.columns["lat"][rows], train.columns["lon"][rows]))
    )
    d, _ = tree.query(np.column_stack(frame.to_local(b.lat, b.lon)))
    return d <= NEAR_M


def direction(train_day: str, test_day: str, tables: dict, terms: list[str], ref) -> dict:
    """One direction's figures: the three predictors' RMSE on every bin and on the near ones."""
    train, test = load_survey(tables[train_day]), load_survey(tables[test_day])
    if ref is not None:
        with_reference(train, ref)
    cpu = time.process_time()
    sm = SurveyModel(train, "current_speed", terms).fit()
    cpu = time.process_time() - cpu
    b = bins_of(test)
    me, mn = model_prediction(sm, test, b)
    se, sn = station_prediction(ref or load_reference(REFERENCE), test, b)
    tr = under_way(train)
    ae = np.full(len(b.east), train.columns["current_east"][tr].mean())
    an = np.full(len(b.east), train.columns["current_north"][tr].mean())
    near = near_track(train, b)
    out = {"train": train_day, "test": test_day, "terms": sm.terms, "bins": len(b.east),
           "near_bins": int(near.sum()), "fit_cpu_s": cpu}  # fmt: skip
    for name, (e, n) in (("model", (me, mn)), ("station", (se, sn)), ("mean", (ae, an))):
        out[name] = rmse(e, n, b)
        out[f"{name}_near"] = rmse(e, n, b, near) if near.any() else float("nan")
    return out


def tables_of(cases: Path) -> dict:
    from tests.real_cases import Cases

    built = Cases(cases)
    return {day: built(name).csv for day, name in DAYS.items()}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--effects", nargs="*", default=["tide"])
    p.add_argument("--terms", nargs="*", default=None, help="exactly these terms (no baseline)")
    p.add_argument("--no-reference", action="store_true", help="fit without the reference current")
    p.add_argument("--station", default=None, help="one station for every place")
    p.add_argument("--cases-dir", type=Path, default=Path("/tmp/forcemap-cases"))
    a = p.parse_args()
    a.cases_dir.mkdir(parents=True, exist_ok=True)
    tables = tables_of(a.cases_dir)
    ref = None if a.no_reference else load_reference(REFERENCE, a.station)
    print(f"effects {' '.join(a.effects) or '(baseline)'}; reference "
          f"{'none' if ref is None else REFERENCE.name}")  # fmt: skip
    for train_day, test_day in (("05-17", "05-10"), ("05-10", "05-17")):
        terms = a.terms if a.terms is not None else [*BASELINE, *a.effects]
        r = direction(train_day, test_day, tables, terms, ref)
        print(
            f"{r['train']} -> {r['test']} ({', '.join(r['terms'])}; fit {r['fit_cpu_s']:.0f} s CPU): "
            f"{r['bins']} bins: model {r['model']:.3f}, station {r['station']:.3f}, mean "
            f"{r['mean']:.3f} m/s; {r['near_bins']} within {NEAR_M:.0f} m of the training track: "
            f"model {r['model_near']:.3f}, station {r['station_near']:.3f}, mean {r['mean_near']:.3f}",
            flush=True,
        )


if __name__ == "__main__":
    main()
