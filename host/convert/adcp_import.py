"""`forcemap import FILE.PD0`: a moving-boat ADCP transect into an MCAP log like any survey's.

Writes ``/samples`` (``AdcpSample``: the samples table's columns plus the ADCP's; one row per ensemble
with a depth-averaged current over ground, so a map's target has no gaps), ``/adcp/profile``
(every ensemble's profile over ground), ``/fix`` (the rows' positions), and metadata: ``config`` (file,
format, reference, clock and compass), ``columns`` (who fed each column) and one ``qa.*`` record per
quality finding (forcemap.host.log.qa_records), which ``check`` reads. Without the ``adcp`` extra the
import stops with a one-line message naming the pip install.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from forcemap.host.convert.importers import ImportFailed, ImportResult
from forcemap.host.log.adcp_records import PROFILE_TOPIC, AdcpProfile, AdcpSample
from forcemap.host.log.mcap import McapLog
from forcemap.host.log.messages import LocationFix
from forcemap.host.log.qa_records import QaFinding
from forcemap.host.outputs import atomic_path


def _opt(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None


def _vector(e: float, n: float) -> tuple[float | None, float | None, float | None, float | None]:
    """(speed, direction TO, east, north), all None unless both components are numbers."""
    if not (math.isfinite(e) and math.isfinite(n)):
        return None, None, None, None
    return math.hypot(e, n), math.degrees(math.atan2(e, n)) % 360.0, float(e), float(n)


def row_ensembles(s) -> np.ndarray:  # type: ignore[no-untyped-def]
    """The ensembles that become rows: those with a depth-averaged current over ground, else (no
    ensemble has one) all of them, without current columns. The others stay in /adcp/profile."""
    has = np.isfinite(s.davg_e)
    return np.flatnonzero(has) if has.any() else np.arange(s.raw.n)


def sample_rows(s) -> list[AdcpSample]:  # type: ignore[no-untyped-def]
    """The samples-table rows (AdcpSurvey from forcemap.host.convert.adcp; see ``row_ensembles``)."""
    rows = []
    raw = s.raw
    for i in row_ensembles(s):
        sog, cog, be, bn = _vector(s.boat_e[i], s.boat_n[i])
        cs, cd, ce, cn = _vector(s.ns_e[i], s.ns_n[i])
        ds, dd, de, dn = _vector(s.davg_e[i], s.davg_n[i])
        rows.append(
            AdcpSample(
                t=float(s.t[i]),
                lat=_opt(s.lat[i]),
                lon=_opt(s.lon[i]),
                heading=_opt(s.heading[i]),
                sog=sog,
                cog=cog,
                depth=_opt(s.depth_filled[i]),
                water_temp=_opt(raw.temp[i]),
                current_speed=cs,
                current_dir=cd,
                current_east=ce,
                current_north=cn,
                current_speed_davg=ds,
                current_dir_davg=dd,
                current_east_davg=de,
                current_north_davg=dn,
                boat_east=be,
                boat_north=bn,
                pitch=_opt(raw.pitch[i]),
                roll=_opt(raw.roll[i]),
                position_dr=_opt(s.position_dr[i]),
                boat_vel_filled=1.0 if s.filled[i] else (0.0 if be is not None else None),
            )
        )
    return rows


def _profile(s, i: int) -> AdcpProfile:  # type: ignore[no-untyped-def]
    return AdcpProfile(
        t=float(s.t[i]),
        ensemble=int(s.raw.number[i]),
        reference=s.reference,
        depth=_opt(s.depth[i]),
        cell_depth=[round(float(d), 3) for d in s.cell_depth],
        east=[_opt(v) for v in s.cur_e[:, i]],
        north=[_opt(v) for v in s.cur_n[:, i]],
        up=[_opt(v) for v in s.cur_u[:, i]],
    )


def _config(s, path: str | Path) -> dict[str, str]:  # type: ignore[no-untyped-def]
    c = s.compass
    return {
        "import": str(path),
        "format": "adcp",
        "instrument": f"TRDI {s.raw.model}",
        "coord_sys": s.raw.coord_sys,
        "reference": s.reference,
        "timing": (
            f"instrument clock + {s.clock.offset_s:.3f} s = GPS UTC ({s.clock.fixes} fixes"
            + (
                f"; {s.clock.without_fix} GGA without a fix not used"
                if s.clock.without_fix
                else ""
            )
            + ")"
            if s.clock.fixes
            else "instrument clock (no GPS: not UTC-checked)"
        ),
        "heading_offset_deg": repr(s.offset_applied),
        "compass_fit": f"{c.offset_deg!r} sd {c.sd_deg!r} on {c.intervals} intervals",
    }


def _columns(s) -> dict[str, str]:  # type: ignore[no-untyped-def]
    name = f"adcp TRDI {s.raw.model}"
    ref = "bottom track" if s.reference == "bt" else "GPS"
    out = {c: name for c in ("heading", "water_temp", "pitch", "roll")}
    out["depth"] = f"{name} bottom-track beams"
    for c in ("sog", "cog", "boat_east", "boat_north"):
        out[c] = f"{name} {ref}"
    for c in ("current_speed", "current_dir", "current_east", "current_north"):
        out[c] = f"{name} near-surface cell, {ref}-referenced"
        out[c + "_davg"] = f"{name} depth average (1/6 power law), {ref}-referenced"
    if s.raw.has_gps:
        out["lat"] = out["lon"] = f"{name} GPS (GGA), dead-reckoned on bottom track between gaps"
    return out


def write(s, log: McapLog, path: str | Path, found: list[QaFinding]) -> int:  # type: ignore[no-untyped-def]
    """Every record of the transect into ``log``; the number of samples written."""
    log.metadata("config", _config(s, path))
    log.metadata("columns", _columns(s))
    for f in found:
        log.metadata(f.name, f.to_metadata())
    for i in range(s.raw.n):
        log.write(PROFILE_TOPIC, int(round(s.t[i] * 1e9)), _profile(s, i))
    rows = sample_rows(s)
    for row in rows:
        ns = int(round(row.t * 1e9))
        log.write("/samples", ns, row)
        if row.lat is not None and row.lon is not None:
            log.write("/fix", ns, LocationFix.at(ns, row.lat, row.lon, frame_id="adcp"))
    return len(rows)


def summary_lines(s, found: list[QaFinding]) -> list[str]:  # type: ignore[no-untyped-def]
    """What the import found, for the terminal."""
    raw = s.raw
    span = f"{raw.range[0]:.2f}-{raw.range[-1]:.2f} m" if raw.range.size else "no cells"
    out = [
        f"  ADCP: TRDI {raw.model}, {raw.n} ensembles, {raw.range.size} cells ({span}), "
        f"{raw.t_gps.size} GPS fixes, reference {s.reference}",
        f"  clock: {_config(s, raw.path)['timing']}",
    ]
    if raw.skipped_bytes:
        out.append(
            f"  {raw.skipped_bytes} damaged bytes left out (outside ensembles whose checksum holds)"
        )
    n_cur = int(np.isfinite(s.davg_e).sum())
    out.append(
        f"  current over ground in {n_cur} of {raw.n} ensembles"
        + (f" (the table's rows; all {raw.n} in /adcp/profile)" if n_cur else "")
    )
    out.extend(f"  qa {f.verdict:6} {f.category}.{f.check}: {f.message}" for f in found)
    return out


def import_adcp_to_mcap(
    path: str | Path,
    out: str | Path,
    reference: str = "bt",
    compass_offset: float | None = None,
) -> tuple[ImportResult, list[QaFinding]]:
    """Import a PD0 file into the MCAP ``out`` (whole or not at all); ImportFailed on a bad file."""
    from forcemap.host.convert.adcp import process
    from forcemap.host.convert.adcp_qa import findings
    from forcemap.host.convert.adcp_read import AdcpUnavailable, count_ensembles, read_pd0

    whole = count_ensembles(path)
    if whole < 2:
        raise ImportFailed(
            f"{Path(path).name}: {whole} complete PD0 ensemble(s) in it; at least 2 are needed"
        )
    try:
        raw = read_pd0(path)
    except AdcpUnavailable as e:
        raise ImportFailed(str(e)) from None
    except Exception as e:  # dolfyn on bytes that are not PD0 ensembles
        raise ImportFailed(
            f"{Path(path).name}: not a readable TRDI PD0 file (dolfyn stopped: {type(e).__name__} {e})"
        ) from None
    if raw.n == 0:
        raise ImportFailed(f"{Path(path).name}: no complete PD0 ensemble in it")
    s = process(raw, reference, compass_offset)
    found = findings(s)
    with atomic_path(out) as tmp:
        log = McapLog(
            Path(tmp).parent, first_path=tmp, rotate_bytes=1 << 62, rotate_seconds=float("inf")
        )
        try:
            n = write(s, log, path, found)
        finally:
            log.close()
    res = ImportResult(str(path), "adcp", raw.n, {"samples": {"emitted": n}})
    res.notes.extend(line.strip() for line in summary_lines(s, found))
    return res, found
