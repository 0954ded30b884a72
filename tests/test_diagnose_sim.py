"""`diagnose` on surveys made by the simulator and logged through the daemon's real pipeline.

Each survey hides one world effect from the model; the diagnosis must rank its covariate first and
adding it must cut the blocked-CV error by at least 30 %.
"""

from __future__ import annotations

import pytest

from host.workbench.diagnose import diagnose
from host.workbench.table import load_survey
from sim_devices.offline import make_survey

DURATION_S = 1200.0


@pytest.mark.slow
@pytest.mark.parametrize(
    ("effect", "target", "covariate", "seed"),
    [
        ("depth_current", "current_speed", "depth", 1),
        ("dam_release", "current_speed", "t", 1),
        ("dam_release", "current_speed", "t", 2),
    ],
)
def test_simulated_hidden_effect_is_named(tmp_path, effect, target, covariate, seed):
    table = make_survey("river", [effect], seed=seed, duration_s=DURATION_S, out_dir=tmp_path)
    d = diagnose(load_survey(table), target, progress=False)
    best = d.candidates[0]
    assert d.missing_effect_found, d.summary()
    assert best.covariate == covariate, d.summary()
    assert best.improvement >= 0.30, d.summary()
