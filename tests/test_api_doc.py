"""docs/API.md runs: its Python blocks, in order, in one namespace, in a fresh folder."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

DOC = Path(__file__).resolve().parents[1] / "docs" / "API.md"


def blocks() -> list[str]:
    return re.findall(r"```python\n(.*?)```", DOC.read_text(encoding="utf-8"), flags=re.S)


def test_the_api_page_has_the_issues_example():
    code = "\n".join(blocks())
    for call in (
        "forcemap.read_survey(",
        "survey.fit(",
        "fit.cv_rmse",
        "fit.diagnose()",
        "fit.to_xarray(",
    ):
        assert call in code


@pytest.mark.slow
def test_every_block_of_the_api_page_runs(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    for i, code in enumerate(blocks()):
        exec(compile(code, f"{DOC.name} block {i + 1}", "exec"), namespace)  # noqa: S102
    out = capsys.readouterr().out
    assert "Survey('survey.csv', n=900)" in out
    assert "EPSG:32617 (UTM zone 17N)" in out
    assert (tmp_path / "current.tif").exists()
    assert (tmp_path / "survey.csv.forcemap").exists() is False  # nothing recorded unless asked
