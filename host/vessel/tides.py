"""The astronomical tide: the constituents, their frequencies, the equilibrium argument V and the nodal
corrections f and u at any UTC time, and which constituents a record can separate (the Rayleigh criterion).

The constituent table is UTide's (Codiga 2011; T_TIDE, Pawlowicz et al. 2002; Foreman 1977), shipped as
`tide_constituents.json` beside this module. The formulas are UTide's `ut_FUV` and `ut_astron`, at exact
times (UTide's default): a constituent's signal is `A f(t) cos(2 pi (V(t) + u(t)) - g)` with the amplitude
A and the Greenwich phase lag g. UTide itself is not a dependency: it requires numpy 2, which the boat's
Pi may not have; the test suite checks these numbers against it (tests/test_tides.py).
"""

from __future__ import annotations

import functools
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

# the Explanatory Supplement's polynomials for s, h, p, N' and p1 (degrees, days since 1899-12-31 12:00)
_ASTRO = np.array(
    [
        [270.434164, 13.1763965268, -0.0000850, 0.000000039],
        [279.696678, 0.9856473354, 0.00002267, 0.000000000],
        [334.329556, 0.1114040803, -0.0007739, -0.00000026],
        [-259.183275, 0.0529539222, -0.0001557, -0.000000050],
        [281.220844, 0.0000470684, 0.0000339, 0.000000070],
    ]
)
# 1899-12-31 12:00 UTC in UNIX days
_EPOCH_DAYS = -25567.5
# Foreman's latitude factors are singular at the equator: T_TIDE and UTide take 5 degrees there
MIN_ABS_LAT = 5.0
# the constituents `tide` considers by default: the astronomical ones and the main shallow-water overtide
DEFAULT_COMPOUNDS = ("M4",)
PRIORITY = (
    "M2",
)  # a record too short for any constituent still gets this one (the semidiurnal band)


@dataclass(frozen=True)
class Constituent:
    name: str
    freq_cph: float
    df_cph: float
    doodson: tuple[int, ...] | None
    semi: float
    satellites: (
        np.ndarray
    )  # (k, 6): d_p, d_N', d_p1, phase correction, amplitude ratio, latitude kind
    shallow: tuple[tuple[str, float], ...]

    @property
    def period_h(self) -> float:
        return 1.0 / self.freq_cph if self.freq_cph > 0 else math.inf


@functools.lru_cache(maxsize=1)
def table() -> dict[str, Constituent]:
    """Every constituent of the table by name, in the table's order."""
    raw = json.loads((Path(__file__).with_name("tide_constituents.json")).read_text())
    out = {}
    for c in raw["constituents"]:
        out[c["name"]] = Constituent(
            c["name"],
            float(c["freq_cph"]),
            float(c["df_cph"]),
            tuple(c["doodson"]) if "doodson" in c else None,
            float(c.get("semi", 0.0)),
            np.array(c.get("satellites", []), float).reshape(-1, 6),
            tuple((a, float(b)) for a, b in c.get("shallow", [])),
        )
    return out


def constituent(name: str) -> Constituent:
    """One constituent by name (case-insensitive); ValueError naming the known ones otherwise."""
    t = table()
    key = {n.upper(): n for n in t}.get(name.strip().upper())
    if key is None:
        raise ValueError(
            f"unknown tidal constituent {name!r}; e.g. M2, S2, N2, K2, K1, O1, P1, Q1, M4, MS4 "
            f"(UTide's table of {len(t)})"
        )
    return t[key]


def astro(unix_s: np.ndarray) -> np.ndarray:
    """(6, n) astronomical arguments in cycles: lunar time tau, s, h, p, N', p1 (UTide's `ut_astron`)."""
    days = np.asarray(unix_s, float) / 86400.0
    d = days - _EPOCH_DAYS
    D = d / 10000.0
    args = np.vstack([np.ones_like(d), d, D * D, D**3])
    a = np.fmod(_ASTRO @ args / 360.0, 1.0)
    tau = np.mod(days, 1.0) + a[1] - a[0]
    return np.vstack([tau, a])


def _latitude_ratios(sat: np.ndarray, lat: float) -> np.ndarray:
    lat = math.copysign(max(abs(lat), MIN_ABS_LAT), lat if lat != 0 else 1.0)
    slat = math.sin(math.radians(lat))
    r = sat[:, 4].copy()
    r[sat[:, 5] == 1] *= 0.36309 * (1.0 - 5.0 * slat**2) / slat
    r[sat[:, 5] == 2] *= 2.59808 * slat
    return r


def _fuv_one(c: Constituent, a: np.ndarray, lat: float, cache: dict) -> tuple:
    if c.name in cache:
        return cache[c.name]
    if c.doodson is None:  # a compound: products and sums of its parts
        F, U, V = np.ones(a.shape[1]), np.zeros(a.shape[1]), np.zeros(a.shape[1])
        for part, coef in c.shallow:
            f, u, v = _fuv_one(table()[part], a, lat, cache)
            F, U, V = F * f ** abs(coef), U + coef * u, V + coef * v
    else:
        V = np.fmod(np.asarray(c.doodson, float) @ a + c.semi, 1.0)
        if len(c.satellites):
            sat = c.satellites
            uu = np.fmod(sat[:, :3] @ a[3:6] + sat[:, 3:4], 1.0)
            z = 1.0 + (_latitude_ratios(sat, lat)[:, None] * np.exp(2j * np.pi * uu)).sum(axis=0)
            F, U = np.abs(z), np.angle(z) / (2 * np.pi)
        else:
            F, U = np.ones(a.shape[1]), np.zeros(a.shape[1])
    cache[c.name] = (F, U, V)
    return cache[c.name]


def fuv(
    unix_s: np.ndarray, names: list[str] | tuple[str, ...], lat: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nodal amplitude factor f, nodal phase u (cycles) and equilibrium argument V (cycles) of each
    constituent at each time: three (n, k) arrays."""
    a = astro(np.atleast_1d(unix_s))
    cache: dict = {}
    parts = [_fuv_one(constituent(n), a, lat, cache) for n in names]
    return tuple(np.column_stack([p[i] for p in parts]) for i in range(3))  # type: ignore[return-value]


def basis(unix_s: np.ndarray, names, lat: float) -> np.ndarray:
    """(n, 2k) features `f cos(2 pi (V + u))`, `f sin(...)` per constituent: weights (a, b) on them are the
    amplitude hypot(a, b) and the Greenwich phase lag atan2(b, a)."""
    F, U, V = fuv(unix_s, names, lat)
    arg = 2 * np.pi * (V + U)
    out = np.empty((len(F), 2 * F.shape[1]))
    out[:, 0::2], out[:, 1::2] = F * np.cos(arg), F * np.sin(arg)
    return out


@dataclass
class Selection:
    """The constituents a record of `span_h` hours can separate, and why each other one was left out."""

    names: list[str]
    span_h: float
    rayleigh: float
    left_out: dict[str, str]

    def describe(self) -> str:
        """In words: which constituents, why, and the next ones the record was too short for."""
        text = (
            f"constituents {', '.join(self.names)} (Rayleigh criterion R = {self.rayleigh:g} over the "
            f"record's {self.span_h:.1f} h)"
        )
        if self.left_out:
            first = list(self.left_out.items())[:3]
            text += "; " + "; ".join(f"{n}: {why}" for n, why in first)
        return text


def candidates() -> list[Constituent]:
    """The default candidates in Foreman's priority order (largest Rayleigh separation first): every
    astronomical constituent and the overtides of DEFAULT_COMPOUNDS."""
    cs = [c for c in table().values() if c.doodson is not None or c.name in DEFAULT_COMPOUNDS]
    return sorted((c for c in cs if c.freq_cph > 0), key=lambda c: -c.df_cph)


def select(span_h: float, rayleigh: float = 1.0, requested: list[str] | None = None) -> Selection:
    """Constituents by the Rayleigh criterion `df * T >= R`: `df` is each constituent's separation from
    the one it is compared with in Foreman's decision tree (UTide's `const.df`), T the record's span.
    Given `requested` names, those (with a note on any the record cannot separate). A record too short
    for any still gets M2, the semidiurnal band, said so."""
    left: dict[str, str] = {}
    if requested:
        names = [constituent(n).name for n in requested]
        for n in names:
            need = rayleigh / constituent(n).df_cph
            if span_h < need:
                left[n] = f"kept as asked, though the record needs {_hours(need)} to separate it"
        return Selection(names, span_h, rayleigh, left)
    names = []
    for c in candidates():
        need = rayleigh / c.df_cph
        if span_h >= need:
            names.append(c.name)
        elif len(left) < 8:
            left[c.name] = f"needs {_hours(need)} to be told from its neighbour"
    if not names:
        names = list(PRIORITY)
        left = {
            "M2": f"the record is shorter than the {_hours(1 / constituent('M2').df_cph)} that "
            "separate it from the mean: fitted as the semidiurnal band (S2, N2 and the rest are in "
            "it; their sd says how well the record fixes amplitude and phase)",
            **{k: v for k, v in left.items() if k != "M2"},
        }
    return Selection(names, span_h, rayleigh, left)


def _hours(h: float) -> str:
    return f"{h:.1f} h" if h < 48 else f"{h / 24:.1f} days"
