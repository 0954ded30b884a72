"""An ADCP transect graded as QRev grades one: each check a ``QaFinding`` with its threshold.

Categories and thresholds (QRev, USGS; /work/shared/design/estimation-and-qa.md):

- ensembles without bottom track, without GPS, and without the chosen reference: caution over 10 %
  of the ensembles, warning over 25 % (QRev's "all invalid ensembles"); no velocity over ground at
  all is red, with why;
- the compass against GPS: the heading offset that makes bottom track agree with GPS, estimated and
  applied (category ``heading``): caution over 1 deg;
- GPS: fix quality below 2 (differential) or HDOP over 2.5 (category ``position``): caution over
  10 % of the fixes, warning over 25 %;
- pitch and roll: mean |angle| caution over 4 deg, warning over 8 deg;
- temperature range: caution over 1 deg C, warning over 2 deg C;
- moving bed: the bed's steady velocity under the bottom track, where the track turns enough to
  separate it from the compass offset: caution over 0.012 m/s and 1 % of the mean water speed (QRev's
  moving-bed test). On a straight transect it cannot be told from the compass offset: caution, advice.
"""

from __future__ import annotations

import math

import numpy as np
from forcemap.host.convert.adcp import AdcpSurvey
from forcemap.host.log.qa_records import QaFinding

SRC = "adcp"
QREV = "(QRev)"


def _grade(value: float, caution: float, warning: float) -> str:
    if not math.isfinite(value):
        return "red"
    return "red" if value > warning else "yellow" if value > caution else "green"


def _share(missing: np.ndarray) -> float:
    return 100.0 * float(missing.mean()) if missing.size else math.nan


def ground_velocity(s: AdcpSurvey) -> list[QaFinding]:
    """Ensembles without bottom track, GPS, or the chosen reference, as shares of the total."""
    n = s.raw.n
    no_bt = ~np.isfinite(s.bt_e)
    no_gps = ~np.isfinite(s.gps_e)
    no_ref = ~np.isfinite(s.boat_e)
    out = []
    rule = "invalid ensembles <= 10 % caution, <= 25 % warning " + QREV
    for check, missing, what in (
        ("no_bottom_track", no_bt, "without bottom track"),
        ("no_gps", no_gps, "without a GPS velocity"),
    ):
        share = _share(missing)
        out.append(
            QaFinding(
                "adcp",
                check,
                _grade(share, 10, 25),
                f"{int(missing.sum())} of {n} ensembles ({share:.1f} %) {what}",
                SRC,
                value=share,
                unit="%",
                threshold=rule,
                evidence=f"{n} ensembles",
            )
        )
    if not s.has_ground_velocity:
        why = []
        if no_bt.all():
            why.append("no bottom-track lock in any ensemble")
        if not s.raw.has_gps:
            why.append("no GPS in the file")
        elif no_gps.all():
            why.append("no usable GPS fix")
        msg = (
            f"no velocity over ground ({', '.join(why) or 'reference ' + s.reference}): no current"
        )
        fix = "record with bottom track locked (depth in range) or with GPS"
        if s.reference == "bt" and not no_gps.all():
            fix = "reference to GPS: --reference gps"
        elif s.reference == "gps" and not no_bt.all():
            fix = "reference to bottom track: --reference bt"
        out.append(
            QaFinding("adcp", "no_ground_velocity", "red", msg, SRC, value=100.0, unit="%", fix=fix)
        )
        return out
    share = _share(no_ref)
    out.append(
        QaFinding(
            "adcp",
            "no_reference",
            _grade(share, 10, 25),
            f"{int(no_ref.sum())} of {n} ensembles ({share:.1f} %) without a boat velocity "
            f"({s.reference}, gaps up to 10 s filled in {int(s.filled.sum())})",
            SRC,
            value=share,
            unit="%",
            threshold=rule,
        )
    )
    return out


def compass(s: AdcpSurvey) -> QaFinding:
    """The heading offset that makes bottom track agree with GPS."""
    c = s.compass
    rule = "|offset| <= 1 deg (QRev compass evaluation)"
    if not math.isfinite(c.offset_deg):
        return QaFinding(
            "heading",
            "compass_offset",
            "yellow",
            "compass offset not estimated: it needs bottom track and GPS together "
            f"({c.intervals} fix-to-fix intervals with both)",
            SRC,
            threshold=rule,
            fix="none applied; check the compass against GPS course",
        )
    verdict = "green" if abs(c.offset_deg) <= 1.0 else "yellow"
    return QaFinding(
        "heading",
        "compass_offset",
        verdict,
        f"compass offset {c.offset_deg:+.1f} ± {c.sd_deg:.1f} deg makes bottom track agree with GPS",
        SRC,
        value=c.offset_deg,
        sd=c.sd_deg,
        unit="deg",
        threshold=rule,
        evidence=f"least squares on {c.intervals} fix-to-fix displacements, bottom track vs GPS",
        fix=f"applied: heading {s.offset_applied:+.2f} deg; calibrate the compass or enter the "
        "magnetic variation",
        applied=True,
    )


def gps(s: AdcpSurvey) -> list[QaFinding]:
    """Fix quality (differential, >= 2) and HDOP (<= 2.5) over the file's fixes."""
    raw = s.raw
    if not raw.has_gps:
        return []
    out = []
    rule = "{} (QRev); caution over 10 % of fixes, warning over 25 %"
    q = raw.fix[np.isfinite(raw.fix)]
    h = raw.hdop[np.isfinite(raw.hdop)]
    for check, bad, total, what, limit in (
        ("fix_quality", int((q < 2).sum()), q.size, "below differential quality", "quality >= 2"),
        ("hdop", int((h > 2.5).sum()), h.size, "with HDOP over 2.5", "HDOP <= 2.5"),
    ):
        share = 100.0 * bad / total if total else math.nan
        worst = f"; worst HDOP {h.max():.1f}" if check == "hdop" and h.size else ""
        out.append(
            QaFinding(
                "position",
                check,
                _grade(share, 10, 25),
                f"{bad} of {total} GPS fixes {what} ({share:.1f} %){worst}",
                SRC,
                value=share,
                unit="%",
                threshold=rule.format(limit),
            )
        )
    return out


def attitude_and_temperature(s: AdcpSurvey) -> list[QaFinding]:
    """Mean |pitch| and |roll|, and the water temperature's range."""
    raw = s.raw
    out = []
    for check, a in (("pitch", raw.pitch), ("roll", raw.roll)):
        m = float(np.nanmean(np.abs(a))) if np.isfinite(a).any() else math.nan
        out.append(
            QaFinding(
                "adcp",
                check,
                _grade(m, 4, 8),
                f"mean |{check}| {m:.1f} deg (max {np.nanmax(np.abs(a)):.1f})",
                SRC,
                value=m,
                unit="deg",
                threshold="mean |angle| <= 4 deg caution, <= 8 deg warning " + QREV,
            )
        )
    t = raw.temp[np.isfinite(raw.temp)]
    rng = float(np.ptp(t)) if t.size else math.nan
    out.append(
        QaFinding(
            "adcp",
            "temperature",
            _grade(rng, 1, 2),
            f"water temperature {t.min():.2f} to {t.max():.2f} deg C (range {rng:.2f})"
            if t.size
            else "no water temperature",
            SRC,
            value=rng,
            unit="degC",
            threshold="range <= 1 deg C caution, <= 2 deg C warning " + QREV,
        )
    )
    return out


def moving_bed(s: AdcpSurvey) -> QaFinding | None:
    """The bed's steady velocity under the bottom track, where the track lets it be told apart."""
    c = s.compass
    if not math.isfinite(c.offset_deg):
        return None
    rule = "moving bed <= 0.012 m/s or <= 1 % of the mean water speed (QRev moving-bed test)"
    if not c.turned:
        return QaFinding(
            "adcp",
            "moving_bed",
            "yellow",
            "moving bed not separable from the compass offset on a transect that does not turn "
            f"(track directions' mean resultant {c.track_r:.2f} >= 0.9)",
            SRC,
            threshold=rule,
            fix="a loop or stationary moving-bed test; or --reference gps if the bed moves",
        )
    speed = math.hypot(c.bed_east, c.bed_north)
    water = float(np.nanmean(np.hypot(s.davg_e, s.davg_n)))
    moving = speed > 0.012 and speed > 0.01 * water
    return QaFinding(
        "adcp",
        "moving_bed",
        "yellow" if moving else "green",
        f"bed velocity under the bottom track {speed:.3f} ± {c.bed_sd:.3f} m/s "
        f"({100 * speed / water:.1f} % of the mean water speed {water:.2f} m/s)",
        SRC,
        value=speed,
        sd=c.bed_sd,
        unit="m/s",
        threshold=rule,
        evidence=f"joint fit of scale, offset and bed velocity on {c.intervals} intervals",
        fix="reference to GPS: --reference gps" if moving else "",
    )


def findings(s: AdcpSurvey) -> list[QaFinding]:
    """Every check of the transect, in QRev's order."""
    out = ground_velocity(s)
    out.append(compass(s))
    out.extend(gps(s))
    out.extend(attitude_and_temperature(s))
    mb = moving_bed(s)
    if mb is not None:
        out.append(mb)
    return out
