"""The `pip install` that adds an optional extra, spelled for how this forcemap was installed.

From PyPI it is `pip install "forcemap[live]"`; from a clone that name would fetch another forcemap
from PyPI, so it is the clone itself: `pip install -e ".[live]"` in the clone (editable, or run from
the tree), `pip install ".[live]"` for a clone installed with `pip install .`, with the clone's path
when the current folder is elsewhere; from git, the same URL. Every "needs an extra" message uses
`install_hint`.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from urllib.parse import unquote, urlparse

ROOT = Path(__file__).resolve().parents[1]  # the tree this module runs from


def _is_source_tree(path: Path) -> bool:
    try:
        text = (path / "pyproject.toml").read_text()
    except OSError:
        return False
    return 'name = "forcemap"' in text


def _direct_url() -> dict | None:
    """The installed distribution's PEP 610 record (pip writes it for a folder, a URL or git)."""
    from importlib.metadata import distributions

    # a build leaves forcemap.egg-info in the clone, found first from there: it has no record
    for dist in distributions(name="forcemap"):
        try:
            text = dist.read_text("direct_url.json")
            if text:
                return json.loads(text)
        except (ValueError, OSError):
            continue
    return None


def _folder(path: Path, extra: str, editable: bool, cwd: Path) -> str:
    here = cwd.resolve() == path.resolve()
    where = "." if here else os.fspath(path)
    return f'pip install {"-e " if editable else ""}"{where}[{extra}]"'


def install_hint(extra: str) -> str:
    """`pip install ...` giving ``extra`` (``live``, ``gis``, ``dask``) to this installation."""
    tree = ROOT if _is_source_tree(ROOT) else None
    try:
        cwd = Path.cwd()
    except OSError:  # the current folder was deleted
        cwd = Path("/")
    return hint_for(extra, tree, None if tree else _direct_url(), cwd)


def hint_for(extra: str, tree: Path | None, record: dict | None, cwd: Path) -> str:
    """The spelling, from where this code runs (``tree``: a clone's folder), pip's PEP 610 record of
    the installation (``direct_url.json``, None from an index) and the current folder."""
    if tree is not None:  # an editable install of a clone, or the clone on sys.path
        return _folder(tree, extra, True, cwd)
    record = record or {}
    url = str(record.get("url", ""))
    if "dir_info" in record and url.startswith("file:"):
        path = Path(unquote(urlparse(url).path))
        return _folder(path, extra, bool(record["dir_info"].get("editable")), cwd)
    vcs = record.get("vcs_info")
    if isinstance(vcs, dict) and url:
        ref = f"@{vcs['requested_revision']}" if vcs.get("requested_revision") else ""
        return f'pip install "forcemap[{extra}] @ {vcs.get("vcs", "git")}+{url}{ref}"'
    return f'pip install "forcemap[{extra}]"'
