"""The one exception the workbench raises for bad input; the CLI prints it on one line and exits 2."""


class WorkbenchError(Exception):
    """A problem with the user's data or request, explained in one line."""
