"""A samples table's cells by column, from CSV, Parquet or the daemon's MCAP (chosen by the extension), and
who fed each column of an MCAP log."""

from __future__ import annotations

import csv
import itertools
from collections.abc import Iterator
from pathlib import Path

import numpy as np
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.survey.cleaning import NumericColumn, to_numeric

# rows read at a time: a million-row table is never held as Python strings (25 columns of them: ~2 GB, estimated)
CHUNK_ROWS = 65_536


def _csv_chunks(path: Path, rows: int = CHUNK_ROWS) -> Iterator[tuple[list[str], list[list[str]]]]:
    """(header, the next `rows` data rows' cells by column) through the file, blank rows skipped."""
    try:
        # utf-8-sig: a byte-order mark (spreadsheets write one) is read, not taken for part of `t`
        with path.open(newline="", encoding="utf-8-sig") as f:
            reader = csv.reader(f)
            header = next(reader, None)
            if header is None:
                raise WorkbenchError(f"{path}: the file is empty")
            header = [h.strip() for h in header]
            dup = sorted({h for h in header if header.count(h) > 1})
            if dup:
                raise WorkbenchError(
                    f"{path}: column name(s) {', '.join(repr(d) for d in dup)} appear more than once in the header"
                )
            line = 1
            while True:
                block = list(itertools.islice(reader, rows))
                good = []
                for row in block:
                    line += 1
                    if len(row) != len(header):
                        if not any(cell.strip() for cell in row):
                            continue
                        raise WorkbenchError(
                            f"{path}: row {line} has {len(row)} cells, the header has {len(header)}"
                        )
                    good.append(row)
                yield (
                    header,
                    [list(c) for c in zip(*good, strict=True)] if good else [[] for _ in header],
                )
                if len(block) < rows:
                    return
    except UnicodeDecodeError:
        raise WorkbenchError(
            f"{path}: not UTF-8 text; is it a CSV? (save it from the spreadsheet as CSV UTF-8)"
        ) from None
    except csv.Error as exc:
        raise WorkbenchError(f"{path}: not a readable CSV ({exc})") from None


def _read_csv(path: Path) -> dict[str, list[str]]:
    cols: dict[str, list[str]] = {}
    for header, chunk in _csv_chunks(path):
        for h, cells in zip(header, chunk, strict=True):
            cols.setdefault(h, []).extend(cells)
    return cols


def _read_parquet(path: Path) -> dict[str, list]:
    import pyarrow as pa
    import pyarrow.parquet as pq

    try:
        table = pq.read_table(path)
    except Exception as exc:  # pyarrow raises many types for a bad file
        raise WorkbenchError(f"{path}: not a readable Parquet file ({exc})") from None
    out: dict[str, list] = {}
    for name in table.column_names:
        col = table.column(name)
        # numeric columns as arrays (nulls as NaN): `to_numeric` takes them whole, not cell by cell
        if pa.types.is_floating(col.type) or pa.types.is_integer(col.type):
            out[name] = col.to_numpy(zero_copy_only=False).astype(float)  # type: ignore[assignment]
        else:
            out[name] = col.to_pylist()
    return out


class RawColumns(dict):
    """A table's cells by column, with notes on how it was read (a truncated log: how much of it)."""

    def __init__(self, columns: dict[str, list], notes: list[str] | None = None):
        super().__init__(columns)
        self.notes = list(notes or [])


def _read_mcap(path: Path) -> dict[str, list]:
    """The ``/samples`` rows through `forcemap export`'s reader: truncated logs are read up to their
    last complete chunk, and rows repeated (same ``t``) are kept once."""
    from forcemap.host.convert.export import check_logs, samples_table
    from forcemap.host.errors import CliError

    try:
        check_logs([path])
    except CliError as exc:
        raise WorkbenchError(str(exc)) from None
    table = samples_table([path])
    if not len(table):
        raise WorkbenchError(
            f"{path}: the MCAP log has no /samples messages; was it written by `forcemap run`?"
        )
    return RawColumns({c: table.column(c) for c in table.columns}, notes=table.notes())


def mcap_provenance(path: Path) -> dict[str, str]:
    """Who fed each column: the last ``columns`` metadata record of an MCAP log (from its summary when
    the file is complete, else by reading it through); empty when there is none."""
    from forcemap.host.log.mcap import FileScan, iter_records
    from mcap.reader import make_reader
    from mcap.records import Metadata

    found: dict[str, str] = {}
    try:
        with open(path, "rb") as f:
            for m in make_reader(f).iter_metadata():
                if m.name == "columns":
                    found = dict(m.metadata)
        return found
    except Exception:  # no summary (a killed or truncated log): read the records themselves
        pass
    for record in iter_records(path, FileScan(path)):
        if isinstance(record, Metadata) and record.name == "columns":
            found = dict(record.metadata)
    return found


def mcap_latencies(path: Path) -> dict[str, dict]:
    """Each navigation source's measured latency in an MCAP log (docs/NAVIGATION.md)."""
    from forcemap.host.convert.navigation_table import latencies

    try:
        return latencies([path])
    except Exception:  # a log the smoother cannot read: no latencies, the table still loads
        return {}


def read_raw(path: str | Path) -> dict[str, list]:
    """The table's cells by column, from CSV, Parquet or MCAP (chosen by the file's extension)."""
    path = Path(path)
    if not path.exists():
        raise WorkbenchError(f"{path}: no such file")
    if path.is_dir():
        raise WorkbenchError(f"{path} is a folder; give a samples table (.csv, .parquet or .mcap)")
    suffix = path.suffix.lower()
    if suffix == ".parquet" or suffix == ".pq":
        return _read_parquet(path)
    if suffix == ".mcap":
        return _read_mcap(path)
    return _read_csv(path)


class _Numbers:
    """One column's numbers gathered chunk by chunk, with the cells made missing (by data row)."""

    def __init__(self) -> None:
        self.parts: list[np.ndarray] = []
        self.not_numbers: list[tuple[int, str]] = []
        self.infinite: list[int] = []
        self.rows = 0

    def add(self, cells) -> None:
        """The next chunk's cells: parsed as a whole where every cell is a number (numpy reads them as Python's
        float does), else cell by cell (`to_numeric`, which names what it made missing)."""
        if isinstance(cells, np.ndarray) and cells.dtype.kind == "f":
            col = to_numeric(cells)
        else:
            try:
                values = np.asarray(cells, dtype=str).astype(float)
                col = to_numeric(values)
            except (
                ValueError
            ):  # words in this chunk: numbers elsewhere may still make the column numeric
                col = to_numeric(cells, words=True)
        self.parts.append(col.values)
        self.not_numbers += [(i + self.rows, t) for i, t in col.not_numbers]
        self.infinite += [i + self.rows for i in col.infinite]
        self.rows += len(cells)

    def column(self) -> NumericColumn | None:
        """The whole column, or None for a column of words (as `to_numeric` judges one)."""
        values = np.concatenate(self.parts) if self.parts else np.zeros(0)
        numbers = int(np.count_nonzero(np.isfinite(values))) + len(self.infinite)
        if self.not_numbers and len(self.not_numbers) >= numbers:
            return None
        return NumericColumn(values, self.not_numbers, self.infinite)


def _parquet_chunks(path: Path) -> Iterator[tuple[list[str], list]]:
    """(names, cells by column) of each row group: numeric columns as float arrays (nulls NaN)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    try:
        f = pq.ParquetFile(path)
        names = f.schema_arrow.names
        groups = range(f.num_row_groups)
    except Exception as exc:  # pyarrow raises many types for a bad file
        raise WorkbenchError(f"{path}: not a readable Parquet file ({exc})") from None
    for g in groups:
        try:
            table = f.read_row_group(g)
        except Exception as exc:
            raise WorkbenchError(f"{path}: not a readable Parquet file ({exc})") from None
        cols = []
        for name in names:
            col = table.column(name)
            if pa.types.is_floating(col.type) or pa.types.is_integer(col.type):
                cols.append(col.to_numpy(zero_copy_only=False).astype(float))
            else:
                cols.append(col.to_pylist())
        yield names, cols


def read_numeric(path: str | Path) -> tuple[dict[str, NumericColumn], set[str], list[str]]:
    """A table's numeric columns (what `to_numeric` makes of each column of `read_raw`), the names of its
    columns of words, and notes on how it was read. A CSV or Parquet file is read a chunk of rows (a Parquet
    row group) at a time, so that only the numbers are ever held whole (8 MB per column per million rows);
    an MCAP log through `read_raw`."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".csv", ".parquet", ".pq") or not path.is_file():
        raw = read_raw(path)
        cols = {name: to_numeric(cells) for name, cells in raw.items()}
        words = {name for name, c in cols.items() if c is None}
        return (
            {k: c for k, c in cols.items() if c is not None},
            words,
            list(getattr(raw, "notes", [])),
        )
    chunks = _parquet_chunks(path) if suffix in (".parquet", ".pq") else _csv_chunks(path)
    acc: dict[str, _Numbers] = {}
    for names, cells in chunks:
        for name, c in zip(names, cells, strict=True):
            acc.setdefault(name, _Numbers()).add(c)
    cols = {name: a.column() for name, a in acc.items()}
    words = {name for name, c in cols.items() if c is None}
    return {k: c for k, c in cols.items() if c is not None}, words, []
