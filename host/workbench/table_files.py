"""A samples table's cells by column, from CSV, Parquet or the daemon's MCAP (chosen by the extension), and
who fed each column of an MCAP log."""

from __future__ import annotations

import csv
from pathlib import Path

from forcemap.host.workbench.errors import WorkbenchError


def _read_csv(path: Path) -> dict[str, list[str]]:
    try:
        # utf-8-sig: a byte-order mark (spreadsheets write one) is read, not taken for part of `t`
        with path.open(newline="", encoding="utf-8-sig") as f:
            reader = csv.reader(f)
            header = next(reader, None)
            if header is None:
                raise WorkbenchError(f"{path}: the file is empty")
            header = [h.strip() for h in header]
            rows = list(reader)
    except UnicodeDecodeError:
        raise WorkbenchError(
            f"{path}: not UTF-8 text; is it a CSV? (save it from the spreadsheet as CSV UTF-8)"
        ) from None
    except csv.Error as exc:
        raise WorkbenchError(f"{path}: not a readable CSV ({exc})") from None
    dup = sorted({h for h in header if header.count(h) > 1})
    if dup:
        raise WorkbenchError(
            f"{path}: column name(s) {', '.join(repr(d) for d in dup)} appear more than once in the header"
        )
    cols: dict[str, list[str]] = {h: [] for h in header}
    for i, row in enumerate(rows):
        if len(row) != len(header):
            if not any(cell.strip() for cell in row):
                continue
            raise WorkbenchError(
                f"{path}: row {i + 2} has {len(row)} cells, the header has {len(header)}"
            )
        for h, cell in zip(header, row, strict=True):
            cols[h].append(cell)
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
