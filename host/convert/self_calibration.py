"""A log calibrated from its own redundancy before it is mapped: estimate, grade, apply where safe.

``import_calibrated`` runs the live pipeline twice: a first pass (in memory) gives the samples that the
estimators of ``forcemap.host.fuse.redundancy`` read (the speed log's gain and misalignment, the rate of
turn's unit, a dead speed log; the gain on the navigation an export of the log will have, so that
`check` of the exported table finds the same) and those of ``forcemap.host.convert.depth_findings`` (the bottom lost,
sounder against sounder, the transducer's tilt); the second pass writes the log with the estimates applied, and every
estimate as a ``qa.*`` metadata record (``forcemap.host.log.qa_records.QaFinding``) with its evidence. A
value pinned in ``boat.toml`` is used as pinned, and the estimate is only reported. Thresholds and their
sources are in docs/QA.md.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from forcemap.host.convert import depth_findings, nav_readings, nmea_prepass
from forcemap.host.convert import navigation_table as nt
from forcemap.host.convert.depth_findings import arrays
from forcemap.host.convert.importers import ImportResult, import_file, import_to_mcap
from forcemap.host.fuse import redundancy as rd
from forcemap.host.fuse.calibration import Calibration
from forcemap.host.fuse.sources import split_name
from forcemap.host.log.messages import Record, as_json
from forcemap.host.log.qa_records import QaFinding

# docs/QA.md: when an estimate is trusted enough to be applied
GAIN_SD_MAX = 0.03  # the correction must be surer than the error it removes (docs/QA.md)
BETA_SD_MAX = 2.0  # deg
SPREAD_MIN = 45.0  # deg of heading spread: one course cannot tell the gain from the current
GAIN_OK = 0.02  # |A - 1| within 2 % and |beta| within 2 deg: green
BETA_OK = 2.0
GAIN_RANGE = (0.7, 1.4)  # outside: a broken log, not a calibration
DEAD_RED = 0.0  # any dead stretch while moving is red
THRESH_GAIN = "|A-1| <= 2 %, |beta| <= 2 deg green; applied when sd(A) <= 3 %, sd(beta) <= 2 deg, headings spread >= 45 deg (Pollard & Read 1989)"
THRESH_ROT = "heading change / integrated rate within 0.5-2 (same unit); ~60: deg/s sent as deg/min (NMEA 0183 ROT)"
THRESH_DEAD = "constant (range < 0.001 m/s) over 60 s while SOG >= 1 m/s, and zero or SOG varying by >= 0.5 m/s: red, dropped"


class SamplesSink:
    """A pipeline sink that keeps only the ``/samples`` rows, every depth source's readings, the
    navigation readings the export's smoother reads, and the ``columns`` and ``sources`` metadata."""

    def __init__(self) -> None:
        self.rows: list[dict[str, Any]] = []
        self.columns: dict[str, str] = {}
        self.depth: dict[str, list[tuple[float, float]]] = {}
        self.depth_chosen = ""
        self.nav: list[tuple[str, int, dict[str, Any]]] = []  # (topic, log time ns, message)

    def write(self, topic: str, log_time_ns: int, message: Record) -> None:
        if topic == "/samples":
            self.rows.append(as_json(message))
        elif topic == "/source/reading" and getattr(message, "quantity", "") == "depth":
            v = message.value[0] if message.value else None  # type: ignore[attr-defined]
            if v is not None:
                self.depth.setdefault(message.source, []).append((log_time_ns * 1e-9, v))  # type: ignore[attr-defined]
        if _navigation(topic, message):
            self.nav.append((topic, log_time_ns, as_json(message)))

    def metadata(self, name: str, data: dict[str, str]) -> None:
        if name == "columns":
            self.columns = dict(data)
        elif name == "sources" and "depth" in data:
            try:
                self.depth_chosen = json.loads(data["depth"]).get("chosen", "")
            except ValueError:
                self.depth_chosen = ""

    def depth_readings(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Each depth source's readings: (UNIX s, m)."""
        return {k: tuple(np.array(v, float).T) for k, v in self.depth.items() if len(v) > 1}  # type: ignore[misc]


def _navigation(topic: str, message: Record) -> bool:
    """A message the export's smoother reads (forcemap.host.convert.nav_readings)."""
    if topic == "/source/reading":
        return getattr(message, "quantity", "") in nav_readings.QUANTITIES
    return topic == "/nmea/sentence" and getattr(message, "type", "") in nav_readings.TIME_FIELD


@dataclass
class Estimates:
    """What the estimators found, and the calibration to import with."""

    findings: list[QaFinding] = field(default_factory=list)
    calibration: Calibration = field(default_factory=Calibration)


def _stw_source(columns: Mapping[str, str]) -> str:
    return columns.get("stw", "").split(";")[0].strip()


def speed_log_findings(
    c: Mapping[str, np.ndarray],
    source: str,
    pinned: Calibration,
    table: Mapping[str, np.ndarray] | None = None,
) -> tuple[list[QaFinding], dict[str, Any]]:
    """Dead stretches (in ``c``, the rows as logged) and Pollard & Read's gain and misalignment of
    the speed log (in ``table``: the rows with the navigation the exported table will have; None:
    ``c``)."""
    out: list[QaFinding] = []
    upd: dict[str, Any] = {}
    t = c["t"]
    dead = rd.dead_stretches(t, c["stw"], c["sog"])
    if dead.intervals:
        mins = dead.seconds / 60
        out.append(
            QaFinding(
                "speed_through_water", "dead", "red",
                f"speed log dead: reads {dead.value:.2f} m/s for {mins:.1f} min "
                f"({100 * dead.fraction:.0f} % of the time under way) while SOG >= 1 m/s",
                source, dead.seconds, unit="s", threshold=THRESH_DEAD,
                evidence=f"{len(dead.intervals)} stretch(es), first at t={dead.intervals[0][0]:.0f}",
                fix="dropped: no current is computed from these readings", applied=True,
                extra={"intervals": ";".join(f"{a:.1f}-{b:.1f}" for a, b in dead.intervals)},
            )
        )  # fmt: skip
        upd["stw_dead"] = dead.intervals
    g = c if table is None else table
    stw = g["stw"].copy()
    for a, b in dead.intervals:
        stw[(g["t"] >= a) & (g["t"] <= b)] = np.nan
    fit = rd.fit_speed_log(g["t"], g["heading"], stw, g["sog"], g["cog"], g.get("yaw_rate"))
    if fit is None:
        why = "no heading" if not np.isfinite(g["heading"]).any() else "too few rows under way"
        out.append(
            QaFinding("speed_through_water", "gain", "yellow",
                      f"speed log gain not estimated ({why}): STW used as read", source,
                      threshold=THRESH_GAIN, fix="pin it in boat.toml [speed_log] gain")
        )  # fmt: skip
        return out, upd
    out.append(_gain_finding(fit, source, pinned, upd))
    return out, upd


def _gain_finding(
    fit: rd.SpeedLogFit, source: str, pinned: Calibration, upd: dict[str, Any]
) -> QaFinding:
    safe = (
        fit.gain_sd <= GAIN_SD_MAX
        and fit.misalignment_sd <= BETA_SD_MAX
        and fit.heading_spread_deg >= SPREAD_MIN
    )
    plausible = GAIN_RANGE[0] <= fit.gain <= GAIN_RANGE[1] and abs(fit.misalignment_deg) <= 20
    small = abs(fit.gain - 1) <= GAIN_OK and abs(fit.misalignment_deg) <= BETA_OK
    pin = pinned.stw_gain is not None or pinned.stw_misalignment_deg is not None
    verdict = "green" if small else ("yellow" if plausible else "red")
    msg = (
        f"speed log gain {fit.gain:.3f} ± {fit.gain_sd:.3f} (reads {100 * abs(1 - 1 / fit.gain):.1f} % "
        f"{'low' if fit.gain > 1 else 'high'}), misalignment {fit.misalignment_deg:+.1f} ± "
        f"{fit.misalignment_sd:.1f}°"
    )
    if not safe:  # one course, or too short: the gain is not told apart from the current
        verdict = "green" if small else "yellow"
        fix = "not applied: too uncertain (sail more headings); pin it in boat.toml [speed_log]"
    elif not plausible:
        fix = "not applied: outside any speed log's calibration; check the log's unit and paddle"
    elif pin:
        fix = f"pinned in boat.toml: gain {pinned.stw_gain}, misalignment {pinned.stw_misalignment_deg}"
    else:
        fix = f"applied: STW x {fit.gain:.3f}, heading {fit.misalignment_deg:+.1f}° for the current"
        upd["stw_gain"], upd["stw_misalignment_deg"] = fit.gain, fit.misalignment_deg
    if pin and not fix.startswith("pinned"):
        fix += f" (pinned in boat.toml: gain {pinned.stw_gain}, misalignment {pinned.stw_misalignment_deg})"
    ev = (
        f"v_ground = A R(beta) v_water + c on {fit.rows} rows, {fit.windows} windows of 10 min, "
        f"headings spread {fit.heading_spread_deg:.0f}°, rms {fit.rms_residual:.2f} m/s"
    )
    extra = {
        "misalignment_deg": repr(fit.misalignment_deg),
        "misalignment_sd": repr(fit.misalignment_sd),
        "current_raw_east": repr(fit.current_raw[0]),
        "current_raw_north": repr(fit.current_raw[1]),
        "current_fit_east": repr(fit.current_fit[0]),
        "current_fit_north": repr(fit.current_fit[1]),
    }
    return QaFinding(
        "speed_through_water", "gain", verdict, msg, source, fit.gain, fit.gain_sd, "1",
        THRESH_GAIN, ev, fix, fix.startswith("applied"), extra,
    )  # fmt: skip


def on_table(f: QaFinding) -> QaFinding:
    """A gain finding estimated on a samples table (CSV, Parquet), not on a log: its gain is of the
    table's ``stw``, which is the log's times the gain its import applied (the table does not say
    which, `forcemap check LOG.mcap` does); its misalignment is the whole (no column is turned by
    one), so the fix gives what to pin from both."""
    if (f.category, f.check) != ("speed_through_water", "gain") or not np.isfinite(f.value):
        return f
    beta = float(f.extra.get("misalignment_deg", "nan"))
    why = f.fix.split(";")[0] + "; " if f.fix.startswith("not applied") else ""
    fix = (
        f"{why}to pin in boat.toml [speed_log]: gain = {f.value:.3f} x the gain the log's import "
        f"applied (`forcemap check LOG.mcap`; 1 if none), misalignment_deg = {beta:+.1f}"
    )
    msg = f.message.replace("speed log gain", "speed log gain on the table's stw", 1)
    return dataclasses.replace(
        f, message=msg, fix="" if f.verdict == "green" else fix, applied=False
    )


def rate_findings(
    c: Mapping[str, np.ndarray], columns: Mapping[str, str], pinned: Calibration
) -> tuple[list[QaFinding], dict[str, Any]]:
    """The rate of turn against the heading's change: its scale, and the unit it was sent in."""
    rot_src = columns.get("yaw_rate", "").split(";")[0].strip()
    hdg_src = columns.get("heading", "").split(";")[0].strip()
    if not rot_src or not np.isfinite(c["yaw_rate"]).any():
        return [], {}
    fit = rd.fit_rate_scale(c["t"], c["heading"], c["yaw_rate"])
    if fit is None:
        return [
            QaFinding("rate_of_turn", "scale", "yellow",
                      "rate of turn not checked: the heading never changed enough", rot_src,
                      threshold=THRESH_ROT)
        ], {}  # fmt: skip
    own = rot_src == hdg_src
    ev = f"heading change vs integrated rate over {fit.windows} windows of 10 s, r = {fit.correlation:.2f}"
    base = f"rate of turn x {fit.scale:.2f} ± {fit.scale_sd:.2f} = heading change"
    upd: dict[str, Any] = {}
    if own:
        msg, verdict, fix = base + " (the heading's own slope, no rate sensor)", "green", ""
    elif fit.unit == "deg/min":
        msg, verdict, fix = base + ": same unit", "green", ""
    elif fit.unit == "deg/s" and "ROT" in rot_src:
        msg = base + ": ROT sent in deg/s, where NMEA 0183 says deg/min"
        verdict = "yellow"
        if pinned.rot_unit is not None:
            fix = f"pinned in boat.toml: rate_of_turn.unit = {pinned.rot_unit}"
        else:
            fix, upd["rot_unit"] = "applied: ROT read as deg/s (x 60)", "deg/s"
    else:
        msg = base + ": the rate of turn and the heading disagree"
        verdict, fix = "red", "check the rate sensor's unit and sign; pin rate_of_turn.unit"
    finding = QaFinding(
        "rate_of_turn", "unit", verdict, msg, rot_src, fit.scale, fit.scale_sd, "1", THRESH_ROT,
        ev, fix, fix.startswith("applied"), {"unit": fit.unit, "correlation": repr(fit.correlation)},
    )  # fmt: skip
    return [finding], upd


def estimate(
    rows: list[Mapping[str, Any]],
    columns: Mapping[str, str],
    pinned: Calibration,
    sink: SamplesSink | None = None,
) -> Estimates:
    """Findings of every estimator on a log's samples (``sink``: the first pass, for every depth
    source's readings), and ``pinned`` with the safe estimates applied."""
    names = ("t", "heading", "yaw_rate", "sog", "cog", "stw")
    c = arrays(rows, names)
    out = Estimates(calibration=pinned)
    upd: dict[str, Any] = {}
    rate, u = rate_findings(c, columns, pinned)
    upd.update(u)
    if np.isfinite(c["stw"]).any():
        unit = pinned.rot_unit or upd.get("rot_unit")
        table = _as_exported(rows, sink, pinned, unit) if sink is not None else None
        f, u = speed_log_findings(c, _stw_source(columns) or "speed log", pinned, table)
        out.findings += f
        upd.update(u)
    out.findings += rate
    readings = sink.depth_readings() if sink is not None else {}
    f, u = depth_findings.estimate(
        rows, columns, readings, sink.depth_chosen if sink else "", pinned
    )
    out.findings += f
    upd.update(u)
    pins = {
        "stw_gain": pinned.stw_gain,
        "stw_misalignment_deg": pinned.stw_misalignment_deg,
        "rot_unit": pinned.rot_unit,
        "sounder_beam_deg": pinned.sounder_beam_deg,
    }
    upd = {k: v for k, v in upd.items() if pins.get(k) is None}
    out.calibration = dataclasses.replace(pinned, **upd)
    return out


def _as_exported(
    rows: list[Mapping[str, Any]], sink: SamplesSink, cal: Calibration, rot_unit: str | None
) -> dict[str, np.ndarray] | None:
    """The first pass's rows as the export of the calibrated log will give them (boat.toml
    ``[sync] navigation``, ``latency``), the rate of turn read in the unit the second pass reads it
    in; None: as logged."""
    if cal.navigation == "logged" or not sink.nav:
        return None
    nav = sink.nav
    if rot_unit == "deg/s":  # as forcemap.host.fuse.nmea_feed reads ROT in the second pass
        nav = [(tp, ns, _per_s(m)) for tp, ns, m in nav]
    table = nt.as_exported([dict(r) for r in rows], nav, cal.latency != "keep")
    return arrays(table, ("t", "heading", "yaw_rate", "sog", "cog", "stw"))


def _per_s(m: dict[str, Any]) -> dict[str, Any]:
    """A ROT reading sent in deg/s, read as such (x 60)."""
    if m.get("quantity") != "yaw_rate" or split_name(str(m.get("source", "")))[2] != "ROT":
        return m
    return {**m, "value": [None if v is None else 60.0 * v for v in m.get("value") or []]}


def unpinned_first_pass(cal: Calibration) -> Calibration:
    """The calibration of the first pass: the raw instruments (nothing estimated is applied yet)."""
    return dataclasses.replace(
        cal, stw_gain=None, stw_misalignment_deg=None, rot_unit=None, stw_dead=(), depth_lost=()
    )


def import_calibrated(
    path: str | Path,
    out: str | Path,
    fmt: str | None = None,
    calibration: Calibration | None = None,
    sync: str | None = None,
    check: Callable[[ImportResult], None] | None = None,
    sample_rate_hz: float | None = None,
    nmea_checksum: str = "strict",
    day: float | None = None,
) -> tuple[ImportResult, list[QaFinding]]:
    """Import ``path`` to ``out`` with the log's own calibration applied and its findings recorded
    (``day``: the UTC midnight an NMEA log without a date starts on)."""
    pinned = calibration or Calibration()
    first = SamplesSink()
    with nmea_prepass.kept():  # the second pass reads the same lines at the same times
        raw = unpinned_first_pass(pinned)
        import_file(path, first, fmt, raw, sync, sample_rate_hz, nmea_checksum, day)
        est = estimate(first.rows, first.columns, pinned, first)
        meta = {f.name: f.to_metadata() for f in est.findings}
        res = import_to_mcap(
            path,
            out,
            fmt,
            est.calibration,
            sync,
            check,
            sample_rate_hz,
            nmea_checksum,
            metadata=meta,
            day=day,
        )
    # the calibration changes values, never which rows there are
    res.counters["self_calibration"] = {"first_pass_samples": len(first.rows)}
    return res, est.findings
