"""docs/TERMS.md's worked example is a term that works: built from the page's own code, registered, fitted
to a profile whose truth it knows, and accepted by `fit --effects` and `diagnose --effects`."""

from __future__ import annotations

import importlib.util
import json
import re
from pathlib import Path

import numpy as np
import pytest
from forcemap.host.cli import main
from forcemap.host.workbench.engine.model import Model
from forcemap.host.workbench.terms import registry

from tests.sim_surveys import private_copy, simulated

DOC = Path(__file__).resolve().parents[1] / "docs" / "TERMS.md"


@pytest.fixture(scope="module")
def loglaw(tmp_path_factory):
    """The page's module, written out as a lab would save it, imported and registered for this module."""
    code = re.search(r"```python\n(.*?)```", DOC.read_text(), re.S).group(1)
    path = tmp_path_factory.mktemp("lab") / "loglaw.py"
    path.write_text(code)
    spec = importlib.util.spec_from_file_location("lab_loglaw", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    registry.register(module.KIND)
    yield module
    registry.KINDS.pop(module.KIND.name)


def test_the_worked_example_recovers_a_log_law(loglaw):
    rng = np.random.default_rng(4)
    depth = rng.uniform(0.5, 12.0, 600)
    slope = 0.21  # m/s per e-fold of depth
    speed = 0.3 + slope * np.log(depth) + 0.03 * rng.standard_normal(600)
    m = Model(["const", "loglaw(depth)"]).fit({"depth": depth}, speed)
    assert m.params_["loglaw(depth)"]["per_e_fold"] == pytest.approx(slope, rel=0.05)
    assert m.noise_std_ < 0.04
    spec = registry.parse_term("loglaw(depth)", lambda c: False)
    assert not registry.in_time(spec) and not registry.caps(spec).is_level
    with pytest.raises(Exception, match="loglaw"):
        registry.parse_term("loglaw(depth, t)", lambda c: False)


@pytest.mark.slow
def test_fit_and_diagnose_accept_it(loglaw, tmp_path, tmp_path_factory, capsys):
    table = private_copy(simulated(tmp_path_factory, "river", [], 1, 1200.0), tmp_path / "s")
    assert main(["fit", str(table), "--target", "current_speed", "--effects", "loglaw(depth)"]) == 0
    out = capsys.readouterr().out
    assert "loglaw(depth)" in out and "per_e_fold" in out
    report = tmp_path / "d.json"
    args = ["diagnose", str(table), "--target", "current_speed", "--effects", "loglaw(depth)"]
    assert main([*args, "--rounds", "1", "--quiet", "--json", str(report)]) == 0
    result = json.loads(report.read_text())
    assert "loglaw(depth)" in json.dumps(result["rounds"][0])
