"""The one exception for bad input or usage: the CLI prints it on one line and exits with its code.

Raise ``CliError("what is wrong, and what to do")`` anywhere below a command; ``forcemap.host.cli.main``
prints ``forcemap CMD: what is wrong, and what to do`` and exits 2. Anything else that escapes a
command is a bug: the traceback is printed with a request to report it, and the exit code is 1.
"""

from __future__ import annotations


class CliError(Exception):
    """A problem with the user's data, files or request, explained in one line."""

    def __init__(self, message: str, code: int = 2):
        super().__init__(message)
        self.code = code
