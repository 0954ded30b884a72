"""`forcemap plan` against the simulator's truth: map a survey from its measurements, plan, fly both missions.

The maps come from measurements only: the simulator's bytes go through the daemon's pipeline into MCAP
and are exported to a samples table (`make_survey`), then fitted. The missions are flown from the
written waypoint files, with another seed, and scored with the true track on the intended lines.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from forcemap.host.cli import main
from forcemap.host.plan.planner import STRESS
from forcemap.host.report.mission_section import mission_section
from forcemap.host.vessel import waypoints as wp
from forcemap.host.workbench.survey.table import load_survey

from bench.closed_loop import SURVEY_S, fly, low_discharge_scenario, plan_files, survey
from tests.sim_surveys import private_copy, simulated

SEED_A, SEED_B = 1, 2
Measured = Callable[[str], Path]
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def work(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("plan")


@pytest.fixture(scope="module")
def measured(tmp_path_factory: pytest.TempPathFactory, work: Path) -> Measured:
    """``measured(scenario)``: bench/closed_loop.py's survey of the scenario (seed A), made once per run
    (tests/sim_surveys.py: test_terms_doc and test_workbench_effects map the same river) and copied
    into this module's folder, where the plan writes beside it."""

    def get(scenario: str) -> Path:
        folder = work / f"survey-{scenario}"
        if not (folder / "samples.csv").exists():
            private_copy(simulated(tmp_path_factory, scenario, [], SEED_A, SURVEY_S), folder)
        return folder / "samples.csv"

    return get


def flights(work: Path, table: Path, scenario: str):  # type: ignore[no-untyped-def]
    result, orig, planned = plan_files(table, "lawnmower", work / f"plan-{scenario}", scenario)
    dur = 1.5 * max(result.original.track.duration, result.planned.track.duration) + 120
    return (
        result,
        orig,
        planned,
        fly(orig, scenario, SEED_B, [], dur),
        fly(planned, scenario, SEED_B, [], dur),
    )


def test_river_plan_holds_the_lines_the_original_misses(work: Path, measured: Measured) -> None:
    result, orig, planned, fo, fp = flights(work, measured("river"), "river")
    # the original blows its downstream turns out by 7-25 m (the paper's Fig. 2) and leaves lines uncovered
    assert 7.0 <= fo.summary["miss"] <= 25.0
    assert fo.turn_errors.min() > 5.0 and fo.summary["coverage"] < 0.9
    # the planned mission, flown in the true river: p95 distance <= 3 m on every line, coverage >= 95 %
    assert fp.summary["p95_worst_line"] <= 3.0
    assert fp.summary["coverage"] >= 0.95
    assert all(s["coverage"] >= 0.95 for s in fp.lines)
    # the prediction saw it coming, on both missions
    assert result.original.to_json()["miss"] > 7.0 and result.planned.to_json()["coverage"] >= 0.95
    # the written mission changes speed per leg, and keeps its intended lines beside it
    _, items = wp.read_wpl(planned)
    assert any(i.command == wp.DO_CHANGE_SPEED for i in items)
    assert planned.with_suffix(".json").exists() and not result.unchanged


def test_lake_plan_changes_nothing_and_loses_nothing(work: Path, measured: Measured) -> None:
    result, orig, planned, fo, fp = flights(work, measured("lake"), "lake")
    assert result.unchanged
    _, a = wp.read_wpl(orig)
    _, b = wp.read_wpl(planned)
    assert [(i.command, i.lat_e7, i.lon_e7) for i in a] == [
        (i.command, i.lat_e7, i.lon_e7) for i in b
    ]
    assert fp.summary["coverage"] >= fo.summary["coverage"] - 1e-9 >= 0.95
    assert fp.duration_s <= 1.01 * fo.duration_s
    assert np.isfinite(fp.summary["p95_worst_line"]) and fp.summary["p95_worst_line"] <= 3.0


def test_wrong_map_is_reported_honestly(work: Path) -> None:
    """Mapped on a dry day (current x 0.6), flown on a dam-release day (x 1.0 rising to x 1.6): the map is
    1.7-2.7 times too weak, so every prediction from it must be optimistic, and the plan must say so."""
    table = survey(str(low_discharge_scenario(work)), SEED_A, work / "survey-low")
    result, orig, planned = plan_files(table, "lawnmower", work / "plan-wrong", "river")
    dur = 1.5 * max(result.original.track.duration, result.planned.track.duration) + 120
    fo = fly(orig, "river", SEED_B, ["dam_release"], dur)
    fp = fly(planned, "river", SEED_B, ["dam_release"], dur)
    predicted = result.planned.to_json()["p95_worst_line"]
    flown = fp.summary["p95_worst_line"]
    # the original was predicted to hold its lines, and missed them
    assert result.original.to_json()["coverage"] >= 0.95
    assert fo.summary["miss"] > 7.0 and fo.summary["coverage"] < 0.9
    # the planned mission's prediction was far too good ...
    assert flown > 3.0 * predicted
    # ... the map's own uncertainty (+-2 sd) does not warn of another day, the higher-discharge one does
    own = [v["p95_worst_line"] for k, v in result.sensitivity.items() if k.startswith("current_x")]
    assert len(own) == 2 and all(abs(p - predicted) < 0.25 * (flown - predicted) for p in own)
    stress = result.sensitivity[f"discharge_x{STRESS:g}"]["p95_worst_line"]
    assert abs(stress - flown) < abs(predicted - flown)
    # ... and the plan still did far better than the original, holding its lines
    assert flown < fo.summary["p95_worst_line"] and fp.summary["coverage"] >= fo.summary["coverage"]
    assert flown <= 3.0 and fp.summary["coverage"] >= 0.95


def test_plan_command_and_report_section(
    work: Path, measured: Measured, capsys: pytest.CaptureFixture[str]
) -> None:
    table = measured("river")
    out = work / "cli" / "planned"
    out.parent.mkdir()
    args = ["plan", str(table), "--mission", "lawnmower", "-o", str(out), "--json", "-", "--quiet"]
    assert main(args) == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out)["planned"][
        "lines"
    ]  # with --json -, stdout holds nothing but the JSON
    text = captured.err  # the table goes to stderr
    assert "per intended line" in text and "higher-discharge day" in text
    for suffix in (".waypoints", ".toml", ".json"):
        assert out.with_name("planned" + suffix).exists()
    # the outputs are not replaced without --force
    assert main(args) == 2
    assert "--force" in capsys.readouterr().err
    # the report's mission section: the tracks on the map and one row per intended line
    parts = "\n".join(mission_section(table, load_survey(table)))
    assert "<h2>Mission</h2>" in parts and 'alt="mission tracks"' in parts
    assert parts.count("<tr><td>") == 5
