"""The workbench's exception for bad input: a CliError, so the CLI prints one line and exits 2."""

from forcemap.host.errors import CliError


class WorkbenchError(CliError):
    """A problem with the user's data or request, explained in one line."""
