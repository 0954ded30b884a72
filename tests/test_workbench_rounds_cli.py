"""`forcemap diagnose --rounds`, and the rounds in `history` and the report, on a synthetic survey with two
hidden effects (bench/synth_survey.py: a depth-driven current and a dam release)."""

from __future__ import annotations

import json
import re

import pytest
from forcemap.host.cli import main

from bench.synth_survey import make_survey


@pytest.fixture(scope="module")
def table(tmp_path_factory):
    return make_survey(
        "river", ["depth_current", "dam_release"], 3, 1200.0, tmp_path_factory.mktemp("two")
    )


def test_rounds_in_json_history_and_report(table, tmp_path, capsys):
    out_json = tmp_path / "d.json"
    argv = ["diagnose", str(table), "--target", "current_speed", "--json", str(out_json)]
    assert main([*argv, "--quiet", "--rounds", "2"]) == 0
    out = capsys.readouterr().out
    d = json.loads(out_json.read_text())
    rounds = d["rounds"]
    assert 1 <= len(rounds) <= 2
    assert rounds[0]["candidates"] == d["candidates"]
    assert d["missing_effect_found"] is rounds[0]["missing_effect_found"] is True
    assert rounds[0]["added"] in ("gp(depth, matern32)", "gp(t, matern32)")
    assert rounds[0]["cv_rmse_after"] < rounds[0]["baseline"]["cv_rmse"]
    if len(rounds) == 2:  # the second round starts from the first round's model
        assert rounds[1]["baseline"]["terms"][-1] == rounds[0]["added"]
        assert "== round 2" in out
    assert main(["history", str(table)]) == 0
    out = capsys.readouterr().out
    steps = [ln for ln in out.splitlines() if re.match(r"\s+round \d: blocked-CV RMSE", ln)]
    assert len(steps) == len(rounds) and rounds[0]["added"] in steps[0]
    report = tmp_path / "r.html"
    assert main(["report", str(table), "-o", str(report), "--quiet"]) == 0
    text = report.read_text()
    assert "Diagnosis, round by round" in text and "round 1: blocked-CV RMSE" in text


def test_rounds_must_be_positive(table, capsys):
    code = main(["diagnose", str(table), "--target", "current_speed", "--rounds", "0", "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err
    assert re.search(r"^forcemap diagnose: .*rounds", err.strip(), re.M), err


def test_a_correction_behind_a_leading_proxy_is_not_asked_for_a_column():
    """A proxy leads and the clock offset follows close behind: the check that a direct cause takes the
    proxy's place pairs real columns only (it asked the table for a column 'clock_offset', exit 2, on a
    shipped log's current_dir)."""
    from forcemap.host.workbench.diagnose.result import Candidate
    from forcemap.host.workbench.diagnose.rounds import _prefer_direct_cause

    def cand(name, gain):
        return Candidate(name, name, 1.0, gain, 1e-6, gain, None, False)

    asked = []

    def pair_gain(a, b):
        asked.append((a, b))
        if a == "clock_offset":
            raise AssertionError("asked for a column clock_offset")
        return 0.05

    ranked = _prefer_direct_cause(
        [cand("cog", 0.6), cand("clock_offset", 0.5), cand("depth", 0.45)], pair_gain
    )
    assert asked == [("depth", "cog")] and ranked[0].covariate == "depth"
