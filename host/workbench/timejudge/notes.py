"""What the revisits showed of a change in time, in words: how many pairs judged it, how much of their
differences it explains, how big it is, and on how many crossings it rests (the finding's note)."""

from __future__ import annotations


def revisit_note(verdict, held_rows: int) -> str:
    """How many revisit pairs judged time, and what they showed."""
    held = (
        f"; {held_rows} {'row' if held_rows == 1 else 'rows'} where the boat stayed in one place "
        f"{'is no revisit' if held_rows == 1 else 'are no revisits'}"
        if held_rows
        else ""
    )
    u = f" {verdict.unit}" if verdict.unit else ""
    return (
        f"judged on {verdict.pairs} revisit pairs ({verdict.crossings} crossings within "
        f"{verdict.radius_m:.0f} m, stretches of {verdict.stretch_s:.0f} s or more apart){held}: their "
        f"differences have an RMS of {verdict.rms_difference:.3g}{u}, of which a change in time explains "
        + (
            f"{verdict.rms_time:.3g}{u} RMS ({verdict.share:.0%} of their mean square, cross-validated)"
            if verdict.share > 0
            else "nothing (cross-validated)"
        )
        + change_note(verdict)
        + evidence_note(verdict)
    )


def change_note(verdict) -> str:
    """The size of the fitted change: a drift's from the first pass the revisits compare to the last (the
    survey's start and end when they span it), a period's amplitude."""
    if verdict.share <= 0 or verdict.change == 0:
        return ""
    size = f"{verdict.change:.3g}" + (f" ± {verdict.change_sd:.2g}" if verdict.change_sd > 0 else "")
    size += f" {verdict.unit}" if verdict.unit else ""
    if verdict.best.name != "drift":
        return f"; the change it fits has an amplitude of {size}"
    a, b = (x / 60.0 for x in verdict.change_span_s)
    turn = ""
    if verdict.departure > 0:
        turn = (
            f"; between them it turns: it departs from its value at the first by up to "
            f"{verdict.departure:.3g} ± {verdict.departure_sd:.2g}"
            + (f" {verdict.unit}" if verdict.unit else "")
        )
    if a < 0.5 and b > (verdict.start_s + verdict.span_s) / 60.0 - 0.5:
        return f"; from the survey's start to its end the change it fits is {size}{turn}"
    return (
        f"; from the first pass the revisits compare to the last ({a:.0f} and {b:.0f} min into the "
        f"survey) the change it fits is {size}{turn}"
    )


def evidence_note(verdict) -> str:
    """Where the fitted change is seen: how many crossings it rests on, and the passes that carry most."""
    if verdict.evidence_crossings <= 0 or verdict.share <= 0:
        return ""
    a, b = (x / 60.0 for x in verdict.evidence_at_s)
    return (
        f"; the change it fits rests on about {verdict.evidence_crossings:.0f} of the "
        f"{verdict.crossings} crossings, most on the passes {a:.0f} and {b:.0f} min into the survey"
    )
