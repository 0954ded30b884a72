"""The survey workspace `<table>.forcemap/` beside a table: saved models, the fit history and diagnoses."""

from __future__ import annotations

import json
import time
from pathlib import Path

HISTORY = "history.json"


def workspace_dir(table: str | Path, create: bool = True) -> Path:
    table = Path(table)
    ws = table.with_name(table.name + ".forcemap")
    if create:
        (ws / "models").mkdir(parents=True, exist_ok=True)
    return ws


def load_history(ws: Path) -> list[dict]:
    path = ws / HISTORY
    if not path.exists():
        return []
    try:
        return json.loads(path.read_text())
    except json.JSONDecodeError:
        return []


def record_fit(ws: Path, entry: dict, model: dict) -> dict:
    """Append a fit to the history and save its model; returns the entry with its number and model file."""
    history = load_history(ws)
    entry = dict(entry)
    entry["fit"] = len(history) + 1
    entry["time"] = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
    name = f"models/fit-{entry['fit']:03d}-{entry['target']}.json"
    entry["model_file"] = name
    (ws / name).write_text(
        json.dumps({**model, "target": entry["target"], "terms": entry["terms"]}, indent=2)
    )
    history.append(entry)
    tmp = ws / (HISTORY + ".tmp")
    tmp.write_text(json.dumps(history, indent=2))
    tmp.replace(ws / HISTORY)
    return entry


def current_terms(ws: Path, target: str) -> list[str] | None:
    """Terms of the latest fit of `target`, if any."""
    for entry in reversed(load_history(ws)):
        if entry.get("target") == target:
            return list(entry["terms"])
    return None


def save_diagnosis(ws: Path, target: str, details: dict) -> Path:
    path = ws / f"diagnosis-{target}.json"
    path.write_text(json.dumps(details, indent=2, default=float))
    return path


def load_diagnoses(ws: Path) -> dict[str, dict]:
    out = {}
    for path in sorted(ws.glob("diagnosis-*.json")):
        try:
            data = json.loads(path.read_text())
        except json.JSONDecodeError:
            continue
        out[data.get("target", path.stem)] = data
    return out
