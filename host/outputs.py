"""Writing output files without losing data: checked before the work, written atomically.

Every command that writes a file goes through here, so that the rules hold everywhere:

- an output that is one of the inputs is refused;
- an existing output is replaced only with ``--force``;
- the output's folder must exist and be writable, checked *before* the heavy work;
- the file appears whole or not at all: it is written to a temporary file in the same folder
  and renamed over the target;
- its mode honours the umask (0644 under the usual 022), as any other tool's output: the temporary
  file is created with 0666 like ``open``, not 0600 like ``tempfile.mkstemp``.
"""

from __future__ import annotations

import contextlib
import os
import secrets
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import IO

from forcemap.host.errors import CliError


def check_output(
    out: str | os.PathLike[str],
    inputs: Iterable[str | os.PathLike[str]] = (),
    force: bool = False,
) -> Path:
    """Refuse an output that would destroy data or cannot be written; return it as a Path."""
    path = Path(out)
    for i in inputs:
        if path.exists() and Path(i).exists() and path.resolve() == Path(i).resolve():
            raise CliError(f"the output {path} is also an input; choose another output file")
    if path.is_dir():
        raise CliError(f"the output {path} is a folder; give a file name")
    if path.exists() and not force:
        raise CliError(f"{path} exists; pass --force to replace it, or choose another output file")
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise CliError(f"the folder {folder} does not exist; create it first")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise CliError(f"the folder {folder} is not writable")
    return path


class atomic_path(contextlib.AbstractContextManager):  # noqa: N801 - used like a function
    """A temporary path beside ``out``; renamed over ``out`` on success, removed on failure.

    For writers that want a file name (pyarrow, matplotlib, an MCAP writer).
    """

    def __init__(self, out: str | os.PathLike[str]):
        self.path = Path(out)
        self.tmp = _new_file(self.path)

    def __enter__(self) -> Path:
        return self.tmp

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            os.replace(self.tmp, self.path)
        else:
            with contextlib.suppress(FileNotFoundError):
                self.tmp.unlink()


def _new_file(out: Path) -> Path:
    """A new, empty file beside ``out`` with a name no one else has; mode 0666 less the umask."""
    while True:
        tmp = out.with_name(f".{out.name}.{secrets.token_hex(4)}.part{out.suffix}")
        try:
            os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
        except FileExistsError:
            continue
        return tmp


@contextlib.contextmanager
def atomic_write(out: str | os.PathLike[str], mode: str = "w") -> Iterator[IO]:
    """``open(out, mode)`` that leaves ``out`` whole or untouched (see ``atomic_path``)."""
    kwargs = {} if "b" in mode else {"encoding": "utf-8", "newline": ""}
    with atomic_path(out) as tmp, open(tmp, mode, **kwargs) as f:
        yield f
        f.flush()
        os.fsync(f.fileno())
