"""The wheel installs one import package, `forcemap`, and carries every file the commands need."""

from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def build_wheel(tmp_path: Path) -> Path:
    src = tmp_path / "src"
    shutil.copytree(
        ROOT,
        src,
        ignore=shutil.ignore_patterns(".git", ".venv", "build", "*.egg-info", "__pycache__"),
    )
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q",
         "-w", str(tmp_path / "dist"), str(src)],
        check=True, capture_output=True,
    )  # fmt: skip
    (wheel,) = (tmp_path / "dist").glob("forcemap-*.whl")
    return wheel


def test_forcemap_is_the_only_top_level_package(tmp_path):
    wheel = zipfile.ZipFile(build_wheel(tmp_path))
    names = wheel.namelist()
    top = {n.split("/")[0] for n in names if ".dist-info/" not in n}
    assert top == {"forcemap"}
    for needed in (
        "forcemap/__init__.py",  # a regular package: `forcemap.read_survey` (from api/)
        "forcemap/host/api.py",
        "forcemap/host/gis/grid.py",
        "forcemap/host/cli/__init__.py",
        "forcemap/host/cli/__main__.py",
        "forcemap/protocol/wire.py",
        "forcemap/firmware_bridge/main.py",
        "forcemap/host/vessel/scenarios/river.toml",
        "forcemap/host/vessel/missions/lawnmower.toml",
        "forcemap/sim_devices/upy/bridge_harness.py",
        "forcemap/host/data/boat.example.toml",
    ):
        assert needed in names
    entry = next(n for n in names if n.endswith(".dist-info/entry_points.txt"))
    assert (
        "forcemap = forcemap.host.cli:main"
        in zipfile.ZipFile(build_wheel(tmp_path / "again")).read(entry).decode()
    )


def test_the_installed_wheel_imports_the_api(tmp_path):
    """Installed from the wheel (not the source tree), `import forcemap` is the API package, and its
    subpackages are found under it."""
    target = tmp_path / "site"
    subprocess.run(
        [sys.executable, "-m", "pip", "install", "--no-deps", "-q", "--target", str(target),
         str(build_wheel(tmp_path))],
        check=True, capture_output=True,
    )  # fmt: skip
    code = (
        "import forcemap, forcemap.host.gis.grid, forcemap.protocol.wire;"
        "print(forcemap.__file__); print(forcemap.read_survey.__module__)"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=tmp_path, env={"PYTHONPATH": str(target)},
        check=True, capture_output=True, text=True,
    ).stdout.split()  # fmt: skip
    assert out == [str(target / "forcemap" / "__init__.py"), "forcemap.host.api"]
