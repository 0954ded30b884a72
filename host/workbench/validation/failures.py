"""Where a model fails most: residuals summarised by region, time span, heading sector and turning, in words."""

from __future__ import annotations

import numpy as np
from forcemap.host.workbench.survey.table import Survey
from forcemap.host.workbench.validation.cv import spatial_blocks

SECTORS = ("N", "NE", "E", "SE", "S", "SW", "W", "NW")


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2))) if len(x) else float("nan")


def failure_summary(survey: Survey, resid: np.ndarray, unit: str = "") -> list[str]:
    """Sentences naming the regions, time spans and headings with the largest residual RMS."""
    total = _rms(resid)
    lines = [f"overall residual RMS {total:.3g}{unit}"]
    if total == 0 or not np.isfinite(total):
        return lines
    blocks = spatial_blocks(survey.xy, 25)
    xy = survey.xy
    worst = sorted(range(blocks.max() + 1), key=lambda b: -_rms(resid[blocks == b]))[:3]
    for b in worst:
        m = blocks == b
        cx, cy = xy[m].mean(axis=0)
        lines.append(
            f"region around {abs(cx):.0f} m {'east' if cx >= 0 else 'west'}, {abs(cy):.0f} m "
            f"{'north' if cy >= 0 else 'south'} of the survey centre: RMS {_rms(resid[m]):.3g}{unit} "
            f"({_rms(resid[m]) / total:.1f}x overall, {m.sum()} samples)"
        )
    t = survey.trel
    edges = np.linspace(t.min(), t.max() + 1e-9, 11)
    idx = np.clip(np.digitize(t, edges) - 1, 0, 9)
    span = max(range(10), key=lambda i: _rms(resid[idx == i]) if (idx == i).any() else -1)
    m = idx == span
    lines.append(
        f"time span {edges[span] / 60:.0f}-{edges[span + 1] / 60:.0f} min after the start: RMS "
        f"{_rms(resid[m]):.3g}{unit} ({_rms(resid[m]) / total:.1f}x overall)"
    )
    if "heading" in survey.columns:
        h = survey.columns["heading"]
        ok = np.isfinite(h)
        sector = (np.round(h[ok] / 45.0).astype(int)) % 8
        r = resid[ok]
        best = max(range(8), key=lambda s: _rms(r[sector == s]) if (sector == s).sum() > 10 else -1)
        m = sector == best
        lines.append(
            f"heading {SECTORS[best]} ({best * 45} deg): RMS {_rms(r[m]):.3g}{unit} ({_rms(r[m]) / total:.1f}x overall)"
        )
    if "yaw_rate" in survey.columns:
        turning = np.abs(np.nan_to_num(survey.columns["yaw_rate"])) > 5.0
        if 10 < turning.sum() < len(turning) - 10:
            lines.append(
                f"in turns (|yaw rate| > 5 deg/s): RMS {_rms(resid[turning]):.3g}{unit}; "
                f"on straight legs: {_rms(resid[~turning]):.3g}{unit}"
            )
    return lines
