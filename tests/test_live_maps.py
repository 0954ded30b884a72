"""The growing maps: rank-one updates give the batch statistics, and the live map is `forcemap fit`'s map.

In process (the map process runs this same `LiveMaps`), on the synthetic survey: no clocks involved.
"""

from __future__ import annotations

import numpy as np
import pytest
from forcemap.host.live.growing import Component, live_survey
from forcemap.host.live.health import HealthMonitor
from forcemap.host.live.maps import TARGETS, LiveMaps
from forcemap.host.workbench.survey.spikes import without_spikes
from forcemap.host.workbench.survey.table import load_survey
from forcemap.host.workbench.targets.target_model import SurveyModel
from forcemap.host.workbench.terms.spec import BASELINE

from bench.synth_survey import make_survey, simulate


def _rows(cols, i):
    return {k: float(v[i]) for k, v in cols.items()}


def test_rank_one_updates_equal_the_batch_statistics():
    cols = simulate(duration_s=400, seed=3)
    half = len(cols["t"]) // 2
    first = {k: v[:half] for k, v in cols.items()}
    comp = Component.refit(live_survey(first, "depth"), "depth", list(BASELINE))
    # the second half in the first half's frame, one sample at a time
    from forcemap.host.vessel.geodesy import LocalFrame

    s0 = live_survey(first, "depth")
    x, y = LocalFrame(s0.lat0, s0.lon0).to_local(cols["lat"], cols["lon"])
    for i in range(half, len(cols["t"])):
        comp.add(np.array([[x[i], y[i]]]), np.array([cols["depth"][i]]))
    Phi = comp.features(np.column_stack([x, y]))
    r = cols["depth"] / comp.y_scale
    assert comp.n == len(r)
    np.testing.assert_allclose(comp.G, Phi.T @ Phi, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(comp.b, Phi.T @ r, rtol=1e-9, atol=1e-9)
    assert comp.rr == pytest.approx(float(r @ r), rel=1e-12)


@pytest.mark.slow
def test_final_live_maps_are_forcemap_fits_maps(tmp_path):
    table = make_survey("river", [], 5, 900.0, tmp_path)
    survey = load_survey(table)
    cols = {k: survey.columns[k] for k in survey.columns}
    maps = LiveMaps(every_s=60.0)
    for i in range(survey.n):
        maps.add(_rows(cols, i))
        maps.step()
    assert maps.updates >= 900 / 60 - 1 and maps.refits >= 3
    before = {t: g.n_samples for t, g in maps.latest.items()}
    maps.step(force="final", refit=True)
    for target, columns in TARGETS.items():
        g = maps.latest[target]
        # the final map is fitted on the rows `forcemap fit` uses: the target's spikes left out
        fitted = without_spikes(survey, columns[0])[0].n
        assert g.n_samples == fitted >= before[target] and fitted >= survey.n - 5
        ny, nx = g.shape
        gx, gy = np.meshgrid(g.x0 + g.step * np.arange(nx), g.y0 + g.step * np.arange(ny))
        xy = np.column_stack([gx.ravel(), gy.ravel()])
        for column in columns:
            # `forcemap fit TABLE --target COLUMN`'s model, on the same samples, in the same frame
            ref = SurveyModel(survey, column, list(BASELINE)).fit().primary
            mu, sd = ref.predict({"position": xy}, return_std=True)
            name = "depth" if target == "depth" else column.split("_")[-1]
            live = g.fields[name].ravel()
            span = float(np.ptp(mu))
            assert np.max(np.abs(live - mu)) <= 0.01 * span, (
                column,
                np.max(np.abs(live - mu)),
                span,
            )
            assert np.max(np.abs(g.fields[f"{name}_sd"].ravel() - sd)) <= 0.01 * float(np.max(sd))


def _near_cells(g, lat, lon, within_m=20.0):
    """The grid's cells (local xy) and which lie within ``within_m`` of a sample."""
    from forcemap.host.vessel.geodesy import LocalFrame
    from scipy.spatial import cKDTree

    ny, nx = g.shape
    gx, gy = np.meshgrid(g.x0 + g.step * np.arange(nx), g.y0 + g.step * np.arange(ny))
    xy = np.column_stack([gx.ravel(), gy.ravel()])
    sx, sy = LocalFrame(g.lat0, g.lon0).to_local(lat, lon)
    return xy, cKDTree(np.column_stack([sx, sy])).query(xy)[0] <= within_m


def _vs_same_hyper(maps, g, cols, i):
    """max |live - fresh fit with the live map's hyperparameters| / the fresh map's range, near samples."""
    sofar = {k: v[: i + 1] for k, v in cols.items()}
    survey = live_survey(sofar, "depth")
    assert (survey.lat0, survey.lon0) == (g.lat0, g.lon0)
    comp = maps.state["depth"].comps[0]
    fresh = SurveyModel(survey, "depth", list(BASELINE)).fit(
        theta=comp.model.theta_, n_basis=comp.model.n_basis_
    )
    xy, near = _near_cells(g, sofar["lat"], sofar["lon"])
    mu = fresh.primary.predict({"position": xy})[near]
    return float(np.max(np.abs(g.fields["depth"].ravel()[near] - mu)) / np.ptp(mu))


def test_between_refits_the_basis_covers_every_sample_and_only_the_hyperparameters_age():
    cols = simulate(duration_s=600, seed=4)
    n = len(cols["t"])
    maps = LiveMaps(every_s=60.0, refit_every_s=1e9)  # refits only when the samples double
    checked = []
    for i in range(n):
        maps.add(_rows(cols, i))
        for g in maps.step():
            assert g.basis_covers, (g.target, g.reason)
            if g.target != "depth":
                continue
            if "refitted" in g.reason:
                assert g.hyper_age_s == 0.0 and g.n_hyper == g.n_samples
                continue
            assert g.hyper_age_s > 0 and g.n_hyper < g.n_samples
            checked.append((g.reason, _vs_same_hyper(maps, g, cols, i)))
    rebuilt = [e for r, e in checked if "basis rebuilt" in r]
    assert rebuilt and maps.rebases >= len(rebuilt), checked
    # a rebuilt basis is the fresh fit's own basis: the same map up to rounding
    assert max(rebuilt) <= 1e-6, checked
    # the survey sailed back (time going on): samples inside the basis's box, rank-one updates
    # while a fresh fit would keep the basis, the map within 1 % of that fit's either way
    back = {k: np.concatenate([v, v[::-1]]) for k, v in cols.items()}
    back["t"][n:] = cols["t"][-1] + np.cumsum(np.diff(cols["t"], prepend=cols["t"][0] - 1.0))
    back["cog"][n:] = (cols["cog"][::-1] + 180.0) % 360.0
    rebases = maps.rebases
    ranked = []
    for i in range(n, len(back["t"])):
        maps.add(_rows(back, i))
        for g in maps.step():
            assert g.basis_covers
            if g.target == "depth" and "refitted" not in g.reason:
                ranked.append((g.reason, _vs_same_hyper(maps, g, back, i)))
    assert any("rebuilt" not in r for r, _ in ranked), ranked
    assert max(e for _, e in ranked) <= 0.01, (ranked, maps.rebases - rebases)


def test_line_ends_update_the_maps_between_periodic_updates():
    cols = simulate(duration_s=900, seed=2)
    maps = LiveMaps(every_s=1e9)  # only line ends (and the first update) are due
    reasons = []
    for i in range(len(cols["t"])):
        maps.add(_rows(cols, i))
        reasons += [g.reason for g in maps.step() if g.target == "depth"]
    assert sum(r.startswith("line end") for r in reasons) >= 3, reasons


def test_health_alerts_raise_and_clear_on_the_logs_clock():
    h = HealthMonitor()
    t0 = 1_700_000_000 * 10**9
    s = 10**9

    def status(t, depth_bytes):
        snap = {
            "sources": {"depth": {"connected": True, "bytes": depth_bytes}},
            "absent": ["bridge"],
        }
        h.observe("/daemon/status", t, snap)

    status(t0, 100)
    h.observe("/fix", t0, {"latitude": 1.0})
    h.observe("/depth", t0, {"depth": 3.0})
    health, logs = h.update(t0, {})
    assert logs == [] and health.sources["depth"]["state"] == "reading"
    assert health.sources["bridge"] == {"state": "not given"}
    status(t0 + 6 * s, 100)  # no new bytes for 6 s, no fix, no depth
    health, logs = h.update(t0 + 6 * s, {})
    texts = sorted(log.message for log in logs)
    assert any("source depth silent" in m for m in texts), texts
    assert any(m.startswith("fix lost") for m in texts), texts
    assert any(m.startswith("sounder out of range") for m in texts), texts
    assert health.sources["depth"]["state"] == "silent" and len(health.alerts) == 3
    status(t0 + 7 * s, 200)
    h.observe("/fix", t0 + 7 * s, {})
    h.observe("/depth", t0 + 7 * s, {"depth": 250.0})  # beyond the sounder's range
    health, logs = h.update(t0 + 7 * s, {})
    assert {log.message.split(":")[0] for log in logs} == {"cleared"}
    assert health.alerts == ["sounder out of range: 250.00 m (expected 0.3-100 m)"]
    h.disk_free = 10
    assert any(k == "disk" for k in h._conditions(t0 + 7 * s))


def test_live_records_are_valid_json_schemas_and_their_messages_match():
    import jsonschema
    from forcemap.host.live.layers import map_messages
    from forcemap.host.live.mission_layer import TOPIC, MissionLayer
    from forcemap.host.log.live_messages import LIVE_TOPIC_TYPES
    from forcemap.host.log.messages import as_json, record_type

    cols = simulate(duration_s=300, seed=6)
    maps = LiveMaps()
    for i in range(len(cols["t"])):
        maps.add(_rows(cols, i))
    messages = map_messages(maps.step(force="test"), maps)
    h = HealthMonitor()
    h.observe("/daemon/status", 0, {"sources": {"nmea": {"bytes": 1}}})
    health, logs = h.update(6 * 10**9, {})  # silent for 6 s: an alert
    messages += [("/health", health), *(("/alerts", log) for log in logs)]
    mission = MissionLayer()
    mission.set_plan([[[47.0, 8.0], [47.001, 8.0]]], [[47.0, 8.0], [47.001, 8.0]])
    messages.append((TOPIC, mission.message()))
    topics = {t for t, _ in messages}
    assert topics >= {"/map/current", "/map/info", "/map/layers/depth", "/map/layers/samples"}
    assert topics >= set(LIVE_TOPIC_TYPES)
    for topic, record in messages:
        schema = record_type(topic).json_schema()
        assert schema["title"] == type(record).NAME
        cls = jsonschema.validators.validator_for(schema)
        cls.check_schema(schema)
        cls(schema).validate(as_json(record))
