"""The Foxglove layout for the live view (host/data/foxglove_layout.json) and a schematic picture of it.

`build_layout()` makes it with foxglove-sdk's `foxglove.layouts`; the shipped JSON is its output
(tests/test_live_cli.py checks they agree), so `forcemap live-layout` needs no sdk.
"""

from __future__ import annotations

import json
from importlib import resources
from pathlib import Path
from typing import Any

LAYOUT_FILE = "foxglove_layout.json"
# (title, panel type, topics) in the order drawn: the schematic and the docs use the same list
PANELS: list[tuple[str, str, list[str]]] = [
    ("Map: track and live maps", "Map",
     ["/fix", "/map/mission", "/map/layers/current", "/map/layers/wind", "/map/layers/depth",
      "/map/layers/samples"]),
    ("Current (m/s) against time", "Plot", ["/current.speed", "/current/stw.speed"]),
    ("Wind (m/s) against time", "Plot", ["/wind/true.speed", "/wind/apparent.speed"]),
    ("Depth (m) against time", "Plot", ["/depth.depth"]),
    ("Health", "Table", ["/health"]),
    ("Alerts", "Log", ["/alerts"]),
]  # fmt: skip
COLOURS = {"/fix": "#000000", "/map/mission": "#d62728", "/map/layers/current": "#1f77b4", "/map/layers/wind": "#2ca02c",
           "/map/layers/depth": "#8c564b", "/map/layers/samples": "#ff7f0e"}  # fmt: skip


def layout_json() -> str:
    """The shipped layout file's text."""
    return resources.files("forcemap.host.data").joinpath(LAYOUT_FILE).read_text(encoding="utf-8")


def build_layout() -> dict[str, Any]:
    """The layout, built with foxglove.layouts (needs the sdk)."""
    import foxglove.layouts as fl

    def plot(title: str, paths: list[str]) -> Any:
        series = [fl.PlotSeries(value=p, label=p, enabled=True) for p in paths]
        return fl.PlotPanel(title=title, config=fl.PlotConfig(paths=series, show_legend=True))

    (mt, _, mtopics), (ct, _, cp), (wt, _, wp), (dt, _, dp), (ht, _, _), (at, _, _) = PANELS
    topic_config = {t: fl.MapTopicSettings(history_mode="all") for t in ["/fix"]}
    map_panel = fl.MapPanel(
        title=mt,
        config=fl.MapConfig(follow_topic="/fix", layer="map", zoom_level=17,
                            topic_colors=dict(COLOURS), topic_config=topic_config),
    )  # fmt: skip
    plots = fl.SplitContainer(
        direction="column",
        items=[fl.SplitItem(proportion=1, content=plot(t, p)) for t, p in ((ct, cp), (wt, wp), (dt, dp))],
    )  # fmt: skip
    side = fl.SplitContainer(
        direction="column",
        items=[
            fl.SplitItem(proportion=1, content=fl.TablePanel(title=ht, config=fl.TableConfig(topic_path="/health"))),
            fl.SplitItem(proportion=1, content=fl.LogPanel(title=at, config=fl.LogConfig(topic_to_render="/alerts", min_log_level=2))),
        ],
    )  # fmt: skip
    layout = fl.Layout(
        content=fl.SplitContainer(
            direction="row",
            items=[
                fl.SplitItem(proportion=2, content=map_panel),
                fl.SplitItem(proportion=1.2, content=plots),
                fl.SplitItem(proportion=1, content=side),
            ],
        )  # fmt: skip
    )
    return json.loads(layout.to_json())


def schematic_png(path: str | Path) -> Path:
    """A schematic of the layout (boxes, titles, topics), drawn with matplotlib: not a screenshot."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    boxes = [(0.0, 0.0, 0.475, 1.0), (0.48, 0.67, 0.28, 0.33), (0.48, 0.335, 0.28, 0.33),
             (0.48, 0.0, 0.28, 0.33), (0.765, 0.5, 0.235, 0.5), (0.765, 0.0, 0.235, 0.495)]  # fmt: skip
    fig, ax = plt.subplots(figsize=(12, 6.5))
    for (x, y, w, h), (title, kind, topics) in zip(boxes, PANELS, strict=True):
        ax.add_patch(Rectangle((x, y), w, h, fill=True, fc="#f4f4f4", ec="#333333", lw=1.5))
        ax.text(x + 0.01, y + h - 0.03, f"{kind} panel", fontsize=8, color="#777777", va="top")
        ax.text(x + 0.01, y + h - 0.07, title, fontsize=11, weight="bold", va="top")
        for k, t in enumerate(topics):
            ax.text(x + 0.015, y + h - 0.13 - 0.045 * k, t, fontsize=9, family="monospace",
                    color=COLOURS.get(t, "#222222"), va="top")  # fmt: skip
    ax.set_xlim(-0.01, 1.01)
    ax.set_ylim(-0.01, 1.01)
    ax.axis("off")
    ax.set_title(
        "forcemap live layout (host/data/foxglove_layout.json) - a schematic, not a screenshot"
    )
    out = Path(path)
    fig.savefig(out, dpi=90, bbox_inches="tight")
    plt.close(fig)
    return out
