"""The astronomical tide, the Rayleigh criterion, the time terms' strings, `--at` times and `estimate_period`:
the parts of the time terms that need no survey.

UTide (Codiga 2011) is the reference for the nodal corrections and the equilibrium argument: forcemap carries
its own copy of the formulas and the constituent table (UTide needs numpy 2, which the boat's Pi may not
have), and they must agree to rounding."""

from __future__ import annotations

import math

import numpy as np
import pytest
from forcemap.host.vessel import tides
from forcemap.host.workbench.engine.periodogram import estimate_period
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.survey.at_time import parse_at
from forcemap.host.workbench.survey.table import is_circular
from forcemap.host.workbench.terms.registry import build_term, parse_term
from forcemap.host.workbench.terms.tide import TideTerm

NAMES = [
    "M2",
    "S2",
    "N2",
    "K2",
    "K1",
    "O1",
    "P1",
    "Q1",
    "M4",
    "MS4",
    "MN4",
    "M6",
    "MSF",
    "MF",
    "SA",
]


@pytest.mark.parametrize("lat", [-41.3, 0.0, 3.0, 37.8, 63.4])
def test_nodal_corrections_and_arguments_are_utides(lat: float) -> None:
    import utide.harmonics as utide  # in the test extra: a missing one fails
    from utide._ut_constants import constit_index_dict

    unix = np.array([0.0, 946_684_800.0, 1_780_322_400.0, 1_780_322_400.0 + 12345.6, 2.2e9])
    ut_lat = (
        lat if lat != 0.0 else 5.0
    )  # UTide divides by sin(0) at the equator; both take 5 deg there
    F, U, V = utide.FUV(
        unix / 86400 + 719163, 0, [constit_index_dict[n] for n in NAMES], ut_lat, [0] * 4
    )
    f, u, v = tides.fuv(unix, NAMES, lat)
    assert np.abs(f - F).max() < 1e-12
    assert np.abs((u - U + 0.5) % 1 - 0.5).max() < 1e-12
    assert np.abs((v - V + 0.5) % 1 - 0.5).max() < 1e-8  # cycles: 4e-6 deg


def test_the_basis_is_f_cos_and_sin_of_v_plus_u() -> None:
    t = np.linspace(1.7e9, 1.7e9 + 86400, 50)
    f, u, v = tides.fuv(t, ["M2", "K1"], 50.0)
    b = tides.basis(t, ["M2", "K1"], 50.0)
    assert np.allclose(b[:, 0], f[:, 0] * np.cos(2 * np.pi * (v[:, 0] + u[:, 0])))
    assert np.allclose(b[:, 3], f[:, 1] * np.sin(2 * np.pi * (v[:, 1] + u[:, 1])))
    # V advances at the constituent's frequency (cycles per hour) between the samples
    dv = np.diff(np.unwrap(2 * np.pi * v[:, 0])) / (2 * np.pi) / np.diff(t / 3600)
    assert np.allclose(dv, tides.constituent("M2").freq_cph, rtol=1e-4)


def test_rayleigh_criterion_for_a_four_hour_and_a_three_day_record() -> None:
    four = tides.select(4.0)
    assert four.names == ["M2"]  # one semidiurnal constituent, said to be the band
    assert "semidiurnal band" in four.left_out["M2"] and "K1" in four.left_out
    three = tides.select(72.0)
    assert three.names[:2] == ["M2", "K1"] and "M4" in three.names
    # S2 and O1 need the spring-neap cycle to be told from M2 and K1: 14.8 and 13.7 days
    assert "S2" not in three.names and "O1" not in three.names
    assert "14.8 days" in three.left_out["S2"] and "13.7 days" in three.left_out["O1"]
    month = tides.select(30 * 24.0)
    assert {"M2", "S2", "K1", "O1", "N2"} <= set(month.names)
    # the criterion is df * T >= R: a stricter R keeps fewer
    assert set(tides.select(30 * 24.0, rayleigh=2.0).names) < set(month.names)


def test_the_term_chooses_its_constituents_from_the_record_it_is_set_up_on() -> None:
    t0 = 1_780_322_400.0
    for hours, expect in ((4.0, ("M2",)), (72.0, ("M2", "K1"))):
        term = TideTerm()
        utc = np.linspace(t0, t0 + hours * 3600, 200)
        term.setup(np.column_stack([utc, np.full(200, 33.8)]))
        assert term.names[: len(expect)] == expect
        assert term.features(np.column_stack([utc, np.full(200, 33.8)])).shape == (
            200,
            2 * len(term.names),
        )
    named = TideTerm(("S2", "M2"))
    named.setup(np.column_stack([utc, np.full(200, 33.8)]))
    assert named.names == ("S2", "M2")  # as asked, in that order
    assert "separate" in named.selection.left_out["S2"]  # with the note that 3 days cannot


@pytest.mark.parametrize(
    "text, canonical, inputs",
    [
        ("tide", "tide", ("utc", "lat")),
        ("tide(m2, K1)", "tide(M2, K1)", ("utc", "lat")),
        ("tide(position)", "tide(position)", ("utc", "lat", "position")),
        ("seiche", "seiche", ("t",)),
        ("seiche(74 min)", "seiche(4440 s)", ("t",)),
        ("seiche(4440 s, 2)", "seiche(4440 s, 2)", ("t",)),
    ],
)
def test_time_term_strings(text: str, canonical: str, inputs: tuple) -> None:
    spec = parse_term(text, is_circular)
    assert str(spec) == canonical and spec.inputs == inputs
    assert build_term(spec, is_circular).describe() == canonical


@pytest.mark.parametrize(
    "text", ["tide(X9)", "tide(M2; K1)", "seiche(-3 s)", "seiche(abc)", "seiche(60 s, 9)"]
)
def test_bad_time_terms_are_one_clear_error(text: str) -> None:
    with pytest.raises(WorkbenchError) as e:
        parse_term(text, is_circular)
    assert "\n" not in str(e.value) and len(str(e.value)) < 200


def test_at_times() -> None:
    assert parse_at("2026-06-02T14:00Z") == 1_780_408_800.0
    assert parse_at("2026-06-02T16:00:00+02:00") == 1_780_408_800.0
    assert parse_at("1780408800") == parse_at(1_780_408_800) == 1_780_408_800.0
    assert parse_at("2026-06-02") == 1_780_358_400.0  # a date is its 00:00 UTC
    assert abs(parse_at("now") - __import__("time").time()) < 5
    for bad, why in (
        ("2026-06-02T14:00", "time zone"),
        ("tomorrow", "cannot read"),
        ("1e12", "1970"),
    ):
        with pytest.raises(WorkbenchError, match=why):
            parse_at(bad)


def test_estimate_period_finds_a_period_in_uneven_correlated_noise() -> None:
    rng = np.random.default_rng(4)
    t = np.sort(rng.uniform(0, 3.5 * 3600, 6000))
    noise = np.zeros(len(t))
    for i in range(1, len(t)):  # AR(1) over ~20 s: a track's correlated error
        noise[i] = noise[i - 1] * math.exp(-(t[i] - t[i - 1]) / 20) + rng.normal(0, 0.05)
    y = 0.1 * np.sin(2 * np.pi * t / 4440 + 1.0) + noise
    est = estimate_period(t, y)
    assert abs(est.period_s - 4440) <= 2 * est.period_sd_s and est.period_sd_s < 100
    assert est.fap < 1e-6 and est.power > 0.1
    # pure noise: no confident period
    null = estimate_period(t, noise)
    assert null.fap > 0.01
    p, sd, power, fap = est  # the tuple diagnose unpacks
    assert (p, sd, power, fap) == tuple(est)
