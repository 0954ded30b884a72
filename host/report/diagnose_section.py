"""The report's section on the rounds of `diagnose`: each step with the error falling, what is confounded, and
the survey advice."""

from __future__ import annotations

import html

from forcemap.host.workbench.diagnose.result import round_steps


def rounds_section(diagnoses: dict[str, dict]) -> list[str]:
    """HTML for every target's diagnosis rounds (the workspace's diagnosis-TARGET.json files)."""
    if not diagnoses:
        return []
    parts = [
        "<h2>Diagnosis, round by round</h2>",
        "<p>Each round adds the effect the previous one found and diagnoses again, until nothing more is "
        "found. A candidate is a finding only if it beats its null (the same term on time-shifted copies "
        "of it) and is identifiable: the map's own picture of it over position does not keep its gain.</p>",
    ]
    for target, d in diagnoses.items():
        parts.append(f"<h3>{html.escape(target)}</h3><ol>")
        parts += [f"<li>{html.escape(s)}</li>" for s in round_steps(d)]
        parts.append("</ol>")
        confounded = [c for c in d.get("candidates", [])[:10] if c.get("identifiable") is False]
        if confounded:
            parts.append(
                "<p>Confounded on this survey (their gain cannot be told from the map's):</p><ul>"
            )
            parts += [
                f"<li>{html.escape(c['covariate'])} with {html.escape(', '.join(c['confounded_with']))}"
                f" ({c['improvement']:+.0%})</li>"
                for c in confounded
            ]
            parts.append("</ul>")
        if d.get("advice"):
            parts.append(f"<p class=found>survey advice: {html.escape(d['advice'])}</p>")
    return parts
