"""A capture file's bytes, gunzipped as they are read when the file is gzipped (users' logs often
come as ``capture.nmea.gz``): the one place an importer opens a capture, so every format and every
command that imports (``import``, ``check`` on a raw capture) reads a gzipped file as the file it
holds, with no temporary file.

gzip is recognised by its first two bytes, whatever the file's name. A gzip stream cut short (a copy
interrupted, a logger that lost power) gives the bytes it holds and says so in a note; a damaged one
is refused in one line, as is a gzipped DataFlash or PD0 file (their readers take a plain file).

Loggers often put something before each sentence: a time stamp of their own clock (`2013-07-31
10:00:00.123 $GPRMC,...`), a time and a source (`1596816412123;N;$GPRMC,...`), an NMEA 4
TAG block (`\\c:1596816412*5A\\$GPRMC,...`). A capture's lines are its sentences with any such
prefix left aside (and counted in a note); the sentence's own checksum still judges it.
"""

from __future__ import annotations

import re
import zlib
from collections.abc import Iterator
from pathlib import Path
from typing import BinaryIO

from forcemap.host.decode.nmea import LineSplitter

GZIP_MAGIC = b"\x1f\x8b"
GZIP_WBITS = 16 + zlib.MAX_WBITS  # a gzip header and trailer around deflate data
CHUNK_BYTES = 1 << 20
# a sentence's start: "$" or "!", its address (a talker and a type, or a proprietary one), a comma
SENTENCE_START = re.compile(rb"[$!][A-Z][A-Z0-9]{3,8},")
MAX_PREFIX = 120  # the bytes a logger may put before a sentence


class ImportFailed(ValueError):
    """A file that cannot be imported: the message is one line for the user."""


def is_gzip(path: str | Path) -> bool:
    """True when the file starts with gzip's magic bytes (OSError if it cannot be read)."""
    with open(path, "rb") as f:
        return f.read(len(GZIP_MAGIC)) == GZIP_MAGIC


def _gunzipped(f: BinaryIO, name: str, notes: list[str] | None) -> Iterator[bytes]:
    """The decompressed bytes of a gzip file (every member of it), as they come."""
    z = zlib.decompressobj(GZIP_WBITS)
    fed = False  # the current member has been given compressed bytes
    read = 0
    while chunk := f.read(CHUNK_BYTES):
        while chunk:
            try:
                out = z.decompress(chunk)
            except zlib.error as e:
                raise ImportFailed(
                    f"{name}: damaged gzip data after {read:,} bytes ({e}); `gzip -t` says "
                    "the same, `gunzip -c` recovers what it can"
                ) from None
            fed, chunk = True, b""
            read += len(out)
            if out:
                yield out
            if z.eof:  # a member ends: another may follow (a log appended to, or cat-ed)
                chunk, z, fed = z.unused_data, zlib.decompressobj(GZIP_WBITS), False
    if fed and not z.eof and notes is not None:
        notes.append(
            f"{name}: the gzip stream ends early (the file is cut short): read the {read:,} "
            "bytes it holds"
        )


def capture_chunks(
    path: str | Path, notes: list[str] | None = None, limit: int | None = None
) -> Iterator[bytes]:
    """The capture's bytes in chunks, decompressed when gzipped; at most ``limit`` bytes when
    given. A gzip stream that ends early stops the chunks and appends a note to ``notes``;
    damaged compressed data raises ImportFailed."""
    name = Path(path).name
    gz = is_gzip(path)
    read = 0
    with open(path, "rb") as f:
        source = _gunzipped(f, name, notes) if gz else iter(lambda: f.read(CHUNK_BYTES), b"")
        for chunk in source:
            if limit is not None and read + len(chunk) >= limit:
                yield chunk[: limit - read]
                return
            read += len(chunk)
            yield chunk


def capture_head(path: str | Path, n: int = 4096) -> bytes:
    """The first ``n`` bytes of the capture (decompressed when gzipped), to tell its format."""
    return b"".join(capture_chunks(path, [], limit=n))


def capture_bytes(path: str | Path, notes: list[str] | None = None) -> bytes:
    """The whole capture (decompressed when gzipped), for readers that need it at once."""
    return b"".join(capture_chunks(path, notes))


def capture_lines(path: str | Path, notes: list[str] | None = None) -> list[bytes]:
    """Every line of a text capture (without CR/LF), streamed through the splitter, each sentence
    without a logger's prefix (`without_prefixes`)."""
    splitter = LineSplitter()
    lines: list[bytes] = []
    for chunk in capture_chunks(path, notes):
        lines += splitter.feed(chunk)
    return without_prefixes(lines + splitter.flush(), Path(path).name, notes)


def sentence_offset(line: bytes) -> int:
    """Where the line's sentence starts: 0 for a sentence as a line, past a logger's prefix otherwise,
    -1 when no sentence starts within MAX_PREFIX bytes."""
    if line[:1] in (b"$", b"!"):
        return 0
    m = SENTENCE_START.search(line, 0, MAX_PREFIX + 12)
    return m.start() if m and m.start() <= MAX_PREFIX else -1


def without_prefixes(lines: list[bytes], name: str, notes: list[str] | None) -> list[bytes]:
    """The lines with any prefix before their sentence left aside (a ``#`` comment stays as it is);
    how many had one goes into ``notes``, with the first prefix as an example."""
    out: list[bytes] = []
    prefixed, example = 0, b""
    for line in lines:
        i = 0 if line[:1] == b"#" else sentence_offset(line)
        if i > 0:
            prefixed += 1
            example = example or line[:i]
            line = line[i:]
        out.append(line)
    if prefixed and notes is not None:
        shown = example[:40].decode("ascii", "replace")
        notes.append(
            f"{name}: {prefixed:,} of {len(lines):,} lines carry a prefix before their sentence (a "
            f"logger's time stamp, a source or an NMEA 4 TAG block; the first: {shown!r}): the "
            "sentences are read, their prefixes left aside"
        )
    return out


def plain_file_format(path: Path, fmt: str) -> str:
    """``fmt``, unless the file is gzipped: the DataFlash and PD0 readers take a plain file."""
    if is_gzip(path):
        raise ImportFailed(
            f"{path.name}: a gzipped {fmt} file; forcemap reads gzipped NMEA captures and tlogs, "
            f"gunzip this one first (gunzip -k {path.name})"
        )
    return fmt
