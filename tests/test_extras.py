"""A command needing a missing extra names the `pip install` that gives it, spelled for how forcemap was
installed (issue 33): from PyPI `"forcemap[live]"`, from a clone the clone itself."""

from __future__ import annotations

import re
from pathlib import Path

from forcemap.host.extras import ROOT, hint_for, install_hint

from tests.test_daemon_support import ROOT as REPO


def test_this_clone_is_named_not_pypi(monkeypatch, tmp_path):
    # the tests run from a clone, installed editable or from its folder (CI's `pip install ".[test]"`):
    # either way the hint names the clone; a PyPI spelling would fetch another forcemap
    dash_e = "-e " if ROOT == REPO else ""
    monkeypatch.chdir(REPO)
    assert install_hint("live") == f'pip install {dash_e}".[live]"'
    monkeypatch.chdir(tmp_path)
    assert install_hint("gis") == f'pip install {dash_e}"{REPO}[gis]"'


def test_each_way_of_installing(tmp_path):
    clone = tmp_path / "forcemap"
    # pip's direct_url.json (PEP 610) for `pip install .`, `pip install -e .`, from git, from PyPI
    folder = {"url": clone.as_uri(), "dir_info": {}}
    editable = {"url": clone.as_uri(), "dir_info": {"editable": True}}
    git = {
        "url": "https://github.com/lab/forcemap.git",
        "vcs_info": {"vcs": "git", "commit_id": "0" * 40, "requested_revision": "v0.1"},
    }
    assert hint_for("live", None, folder, clone) == 'pip install ".[live]"'
    assert hint_for("live", None, folder, tmp_path) == f'pip install "{clone}[live]"'
    assert hint_for("dask", None, editable, clone) == 'pip install -e ".[dask]"'
    assert hint_for("gis", None, git, tmp_path) == (
        'pip install "forcemap[gis] @ git+https://github.com/lab/forcemap.git@v0.1"'
    )
    assert hint_for("live", None, None, tmp_path) == 'pip install "forcemap[live]"'
    assert hint_for(
        "live", None, {"url": "https://x/forcemap.whl", "archive_info": {}}, tmp_path
    ) == ('pip install "forcemap[live]"')


def test_every_message_that_needs_an_extra_uses_the_one_helper():
    spelled = re.compile(r"pip install [\"']?forcemap\[")
    offenders = [
        str(p.relative_to(REPO))
        for folder in ("host", "api", "sim_devices")
        for p in (REPO / folder).rglob("*.py")
        if p.name != "extras.py" and spelled.search(p.read_text())
    ]
    assert offenders == []
    users = [p for p in (REPO / "host").rglob("*.py") if "install_hint(" in p.read_text()]
    assert len(users) >= 7, users  # live (server, run, demo), gis (grid, report, need_gis), dask x2
    assert Path(REPO / "host" / "extras.py").exists()
