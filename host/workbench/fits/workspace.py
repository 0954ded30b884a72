"""The survey workspace `<table>.forcemap/` beside a table: saved models, the fit history and diagnoses.

Nothing here is silently reset or overwritten: a corrupt file is an error naming the file and the way
out (``--reset-history`` moves the history aside, it never deletes it), and every fit gets a model file
of its own, numbered past any fit the folder has ever held.
"""

from __future__ import annotations

import json
import math
import os
import re
import time
from pathlib import Path

from forcemap.host.outputs import atomic_write
from forcemap.host.workbench.errors import WorkbenchError

HISTORY = "history.json"
_FIT_FILE = re.compile(r"fit-(\d+)-")


def workspace_dir(table: str | Path, create: bool = True) -> Path:
    """`TABLE.forcemap/` beside the table; with `create`, made (with models/) if it is not there."""
    table = Path(table)
    ws = table.with_name(table.name + ".forcemap")
    if create:
        check_workspace(ws)
        try:
            (ws / "models").mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise WorkbenchError(
                f"cannot create the workspace {ws} ({exc.strerror or exc}); copy the table to a "
                "folder you can write to"
            ) from None
    return ws


def check_workspace(ws: Path) -> None:
    """The workspace is a writable folder, or can be made: checked before any work, creating nothing."""
    if ws.exists() and not ws.is_dir():
        raise WorkbenchError(
            f"{ws} is a file, where forcemap keeps the table's workspace folder; move it away"
        )
    for d in (ws, ws / "models") if ws.exists() else (ws.parent,):
        if d.exists() and not os.access(d, os.W_OK | os.X_OK):
            raise WorkbenchError(
                f"cannot create the workspace {ws}: {d} is not writable; copy the table to a "
                "folder you can write to"
            )


def _read_json(path: Path, what: str, way_out: str):
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise WorkbenchError(f"{path}: the {what} is corrupt ({exc}); {way_out}") from None
    except OSError as exc:
        raise WorkbenchError(f"{path}: cannot read the {what} ({exc.strerror or exc})") from None


def load_history(ws: Path) -> list[dict]:
    """Every recorded fit; a corrupt history is an error, never an empty one."""
    path = ws / HISTORY
    if not path.exists():
        return []
    way_out = "fix it by hand, or pass --reset-history to start a new one (the old file is kept)"
    history = _read_json(path, "fit history", way_out)
    if not isinstance(history, list) or not all(_is_entry(h) for h in history):
        raise WorkbenchError(f"{path}: the fit history is corrupt (not a list of fits); {way_out}")
    return history


def _is_entry(h: object) -> bool:
    """A fit as `record_fit` writes it (the fields `history` and the report read, with their types)."""
    if not isinstance(h, dict):
        return False
    number = (int, float)
    return (
        isinstance(h.get("fit"), int)
        and isinstance(h.get("time"), str)
        and isinstance(h.get("target"), str)
        and isinstance(h.get("terms"), list)
        and all(isinstance(t, str) for t in h["terms"])
        and all(isinstance(h.get(k), number) for k in ("cv_rmse", "cv_mae", "coverage95"))
    )


def reset_history(ws: Path) -> Path | None:
    """Move the history aside to `history.json.bak-N` (never deleted); returns the backup, if any."""
    path = ws / HISTORY
    if not path.exists():
        return None
    n = 1
    while (backup := ws / f"{HISTORY}.bak-{n}").exists():
        n += 1
    path.rename(backup)
    return backup


def _next_fit_number(ws: Path, history: list[dict]) -> int:
    """One past every fit in the history and every model file in the folder, so none is overwritten."""
    numbers = [h["fit"] for h in history]
    numbers += [
        int(m.group(1)) for p in (ws / "models").glob("fit-*") if (m := _FIT_FILE.match(p.name))
    ]
    return max(numbers, default=0) + 1


def record_fit(ws: Path, entry: dict, model: dict) -> dict:
    """Append a fit to the history and save its model; returns the entry with its number and model file."""
    if not all(math.isfinite(entry[k]) for k in ("cv_rmse", "cv_mae")):
        raise WorkbenchError(
            f"the cross-validated error of {entry['target']} is not a number; the fit is not saved "
            "(a term gave NaN or inf: check user functions and the table's values)"
        )
    history = load_history(ws)
    (ws / "models").mkdir(parents=True, exist_ok=True)
    entry = dict(entry)
    entry["fit"] = _next_fit_number(ws, history)
    entry["time"] = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
    name = f"models/fit-{entry['fit']:03d}-{entry['target']}.json"
    entry["model_file"] = name
    text = json.dumps({**model, "target": entry["target"], "terms": entry["terms"]}, indent=2)
    with open(ws / name, "x", encoding="utf-8") as f:  # "x": another fit's file is never replaced
        f.write(text)
    history.append(entry)
    with atomic_write(ws / HISTORY) as f:
        f.write(json.dumps(history, indent=2))
    return entry


def current_terms(ws: Path, target: str) -> list[str] | None:
    """Terms of the latest fit of `target`, if any."""
    for entry in reversed(load_history(ws)):
        if entry.get("target") == target:
            return list(entry["terms"])
    return None


def save_diagnosis(ws: Path, target: str, details: dict) -> Path:
    (ws / "models").mkdir(parents=True, exist_ok=True)
    path = ws / f"diagnosis-{target}.json"
    with atomic_write(path) as f:
        f.write(json.dumps(details, indent=2, default=float))
    return path


def load_diagnoses(ws: Path) -> dict[str, dict]:
    out = {}
    for path in sorted(ws.glob("diagnosis-*.json")):
        target = path.stem.removeprefix("diagnosis-")
        way_out = f"delete it, or run `forcemap diagnose --target {target}` again to rewrite it"
        data = _read_json(path, "diagnosis", way_out)
        if not isinstance(data, dict):
            raise WorkbenchError(f"{path}: the diagnosis is corrupt (not a table); {way_out}")
        out[data.get("target", target)] = data
    return out
