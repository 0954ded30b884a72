"""The `forcemap` entry point: the subcommand table, --help, and behaviour in a pipeline."""

from __future__ import annotations

import importlib
import os
import sys

import pytest
from forcemap.host.cli import COMMANDS, main


def test_help_lists_every_subcommand(capsys):
    assert main([]) == 0
    out = capsys.readouterr().out
    for name in COMMANDS:
        assert name in out


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_every_subcommand_module_exists_and_has_help(name, capsys):
    module = importlib.import_module(COMMANDS[name][0])
    assert callable(module.add_arguments) and callable(module.run)
    with pytest.raises(SystemExit) as e:
        main([name, "--help"])
    assert e.value.code == 0
    assert "usage: forcemap " + name in capsys.readouterr().out


class ClosedPipe:
    """A stdout whose reader has gone away, as in `forcemap log info F | head -1`."""

    def __init__(self, fd: int):
        self.fd = fd

    def write(self, text: str) -> int:
        raise BrokenPipeError(32, "Broken pipe")

    def flush(self) -> None:
        pass

    def fileno(self) -> int:
        return self.fd


def test_closed_pipe_ends_quietly(monkeypatch, tmp_path):
    fd = os.open(tmp_path / "stdout", os.O_WRONLY | os.O_CREAT)
    monkeypatch.setattr(sys, "stdout", ClosedPipe(fd))
    assert main(["sim", "--list"]) == 0  # no BrokenPipeError escapes
    os.close(fd)
