"""Simulator surveys made once per test run and shared by every test, module and xdist worker asking
for the same one (tests/cache.py).

`simulated(factory, scenario, effects, seed, duration_s, **kw)` is
`forcemap.sim_devices.offline.make_survey` with the same arguments: the table's path, with ``truth/``
and ``logs/`` beside it. A simulated second costs about 10 ms of CPU (the instruments, the bridge's
firmware, the daemon's pipeline), so a 20-minute survey is 12 s: made twice, by two modules or by
the two workers running one module's tests, it costs that twice.

The folder is shared: a test that writes beside the table (``forcemap fit`` records its history in
``TABLE.forcemap/``) takes `private_copy` of it first.
"""

from __future__ import annotations

import hashlib
import shutil
from pathlib import Path
from typing import Any

import pytest

from tests.cache import shared_dir


def simulated(
    factory: pytest.TempPathFactory,
    scenario: str,
    effects: list[str] | tuple[str, ...],
    seed: int,
    duration_s: float,
    **kw: Any,
) -> Path:
    """``make_survey(scenario, effects, seed, duration_s, folder, **kw)``, once per test run."""
    from forcemap.sim_devices.offline import make_survey

    parts = [scenario, "+".join(effects) or "none", str(seed), f"{duration_s:g}"]
    for name, value in sorted(kw.items()):
        if name == "mission" and value is not None:  # a file: its content names it
            value = hashlib.sha1(Path(value).read_bytes()).hexdigest()[:12]
        parts.append(f"{name}={value}")
    fmt = kw.get("fmt", "csv")

    def build(folder: Path) -> None:
        make_survey(scenario, list(effects), seed, duration_s, folder, **kw)

    return shared_dir(factory, "survey-" + "-".join(parts), build) / f"samples.{fmt}"


def private_copy(table: Path, folder: Path) -> Path:
    """A copy of a shared survey (its table and ``truth/``) in ``folder``, to write beside."""
    folder.mkdir(parents=True, exist_ok=True)
    if (table.parent / "truth").is_dir():
        shutil.copytree(table.parent / "truth", folder / "truth", dirs_exist_ok=True)
    return Path(shutil.copy2(table, folder / table.name))
