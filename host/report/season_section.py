"""The report's season section: per-survey current scales against time, the static depth map and the current's
shared shape with their uncertainty, how long a map stays true, the depth CV and the logs left out. Built from
`forcemap season`'s season.json and figures; `season_page` is SEASON_DIR/season.html."""

from __future__ import annotations

import base64
import html

from forcemap.host.report.build import page


def _img(png: bytes, alt: str) -> str:
    return f"<img alt='{html.escape(alt)}' src='data:image/png;base64,{base64.b64encode(png).decode()}'>"


def _surveys(data: dict) -> list[str]:
    rows = ["<table><tr><th>survey</th><th>start (UTC)</th><th>samples</th><th>current scale</th>"
            "<th>offset e, n (m/s)</th><th>wind (m/s from deg)</th></tr>"]  # fmt: skip
    for s in data["surveys"]:
        sc = "" if s["current_scale"] is None else f"{s['current_scale']:.3f}"
        off = s["current_offset_mps"]
        off = "" if not off or not any(off) else f"{off[0]:+.3f}, {off[1]:+.3f}"
        wind = (
            ""
            if s["wind_mean_speed_mps"] is None
            else f"{s['wind_mean_speed_mps']:.1f} from {s['wind_mean_from_deg']:.0f}"
        )
        rows.append(
            f"<tr><td>{html.escape(s['path'])}</td><td>{s['start']}</td><td>{s['samples']}</td>"
            f"<td>{sc}</td><td>{off}</td><td>{wind}</td></tr>"
        )
    return rows + ["</table>"]


def _staleness(st: dict) -> str:
    d = st["doubling_age_days"]
    half = (
        f"a map's error doubles after <b>{d:.1f} days</b>"
        if d is not None
        else "a map's error did not grow with its age in this season"
    )
    return (
        f"<p>{st['pairs']} pairs of surveys: every survey's own current map predicts every later one. "
        f"A fresh map's error is {st['fresh_map_rmse_mps']:.3f} m/s and grows "
        f"{st['rmse_growth_mps_per_day']:.4f} m/s per day of age "
        f"({st['rmse_growth_mps_per_unit_scale_change']:.3f} m/s per unit change of the discharge scale): "
        f"{half}.</p>"
    )


def _cv(cv: list[dict]) -> list[str]:
    wins = sum(c["rmse_static"] < c["rmse_own"] for c in cv)
    rows = [f"<p>Depth in blocked CV: the season's static map beats the survey's own map on {wins} of "
            f"{len(cv)} surveys.</p><table><tr><th>survey</th><th>own map RMSE (m)</th>"
            "<th>static map RMSE (m)</th></tr>"]  # fmt: skip
    for c in cv:
        rows.append(
            f"<tr><td>{html.escape(c['path'])}</td><td>{c['rmse_own']:.3f}</td>"
            f"<td>{c['rmse_static']:.3f}</td></tr>"
        )
    return rows + ["</table>"]


def _levels(data: dict) -> list[str]:
    """The depth's datum, each survey's water level and the rating-curve check."""
    d = data.get("depth")
    if d is None:
        return []
    out = [f"<p>Depth map: {html.escape(d.get('datum', ''))}.</p>"]
    rows = [s for s in data["surveys"] if s.get("water_level_m") is not None]
    if rows:
        out.append(
            "<p>Water level per survey (m, season mean 0; the evidence gain of a level per survey "
            f"{d.get('levels_evidence_gain', 0.0):.1f} nats): "
            + ", ".join(
                f"{s['water_level_m']:+.3f} &plusmn; {s['water_level_sd_m']:.3f}" for s in rows
            )
            + ".</p>"
        )
    if "rating" in data:
        out.append(f"<p>Rating curve: {html.escape(data['rating']['verdict'])}.</p>")
    return out


def season_section(data: dict, figs: dict[str, bytes]) -> list[str]:
    parts = [
        "<h2>Season</h2>",
        f"<p>{len(data['surveys'])} surveys, {data['samples']} samples, in one frame around "
        f"({data['frame']['lat0']:.6f}, {data['frame']['lon0']:.6f}); computed by {html.escape(data['runner'])}.</p>",
    ]
    if "current" in data:
        c = data["current"]
        parts.append(
            "<p>Current: one spatial shape times a per-survey scale (1 = the season's mean), "
            + ("with a per-survey offset (the evidence asked for it, gain "
               f"{c['offsets_evidence_gain']:.1f} nats)." if c["with_offsets"] else
               f"no per-survey offset (the evidence gain, {c['offsets_evidence_gain']:.1f} nats, did not pay for it).")
            + "</p>"
        )  # fmt: skip
    parts += _levels(data)
    for name, alt in (("scales.png", "scales"), ("rating.png", "rating curve"), ("depth.png", "depth"),
                      ("current.png", "current")):  # fmt: skip
        if name in figs:
            parts.append(_img(figs[name], alt))
    parts += _surveys(data)
    if "staleness" in data:
        parts += ["<h3>How long a map stays true</h3>", _staleness(data["staleness"])]
        if "staleness.png" in figs:
            parts.append(_img(figs["staleness.png"], "staleness"))
    if data.get("depth_cv"):
        parts += ["<h3>Static depth against each survey's own</h3>"] + _cv(data["depth_cv"])
    if data["rejected"]:
        parts.append("<h3>Logs left out</h3><ul>")
        parts += [f"<li>{html.escape(r['reason'])}</li>" for r in data["rejected"]]
        parts.append("</ul>")
    return parts


def season_page(data: dict, figs: dict[str, bytes]) -> str:
    return page("season", season_section(data, figs))
