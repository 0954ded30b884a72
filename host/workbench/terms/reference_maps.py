"""What a fitted tide on a reference current says: each place's ratio and time offset to its station, flood
and ebb, with their sd (from posterior draws of the term's weights), as maps and in words.

For a vector the along and across components (the station's flood axis and its normal) both carry the
term: at a place the current is `A r(t) + B r'(t)/w` with A, B vectors. The local flood sets along A
(`turn_deg`: its angle from the station's flood axis, clockwise; 0 where nothing across is modelled,
targets/reference_part.py); along it, `ratio` and `offset_s` are
those of the projected weights (`reference_tide.relation`). A scalar target (one component) has its own.
"""

from __future__ import annotations

import math

import numpy as np
from forcemap.host.workbench.terms.reference_tide import OMEGA, ReferenceTideTerm, flood_ebb
from forcemap.host.workbench.terms.tide import term_block, weight_posterior

DRAWS = 200


def reference_block(model) -> int | None:
    """The index of a fitted model's tide-on-a-reference term among its feature terms, or None."""
    return term_block(model, ReferenceTideTerm)


def weight_draws(model, xy: np.ndarray, draws: int = DRAWS, seed: int = 0) -> np.ndarray | None:
    """(draws + 1, n, 4) weights on the term's features at positions `xy` (`weights_at`): the posterior
    mean first, then draws; None without the term."""
    k = reference_block(model)
    if k is None:
        return None
    term = model.feat_terms_[k]
    mu, cov = weight_posterior(model, k)
    rng = np.random.default_rng(seed)
    w = np.vstack([mu, rng.multivariate_normal(mu, cov, draws, method="eigh")])
    return np.stack([term.weights_at(xy, wi) for wi in w])


def _relation(A_al, A_ac, B_al, B_ac) -> dict[str, np.ndarray]:
    """ratio, offset (s) and turn (deg) of vector weights A, B (along and across the station's axis)."""
    amp = np.hypot(A_al, A_ac)
    d_al, d_ac = A_al / np.maximum(amp, 1e-12), A_ac / np.maximum(amp, 1e-12)
    b = B_al * d_al + B_ac * d_ac
    return {
        "ratio": np.hypot(amp, b),
        "offset_s": -np.arctan2(b, amp) / OMEGA,
        # the across axis is the along one turned 90 deg anticlockwise: clockwise is negative there
        "turn_deg": -np.degrees(np.arctan2(A_ac, A_al)),
    }


def relation_maps(
    along, across, xy: np.ndarray, base: float | np.ndarray = 0.0, draws: int = DRAWS
) -> dict[str, np.ndarray] | None:
    """At positions `xy`: `ratio`, `offset_s`, `turn_deg` for the flood and `ebb_ratio`,
    `ebb_offset_s`, `ebb_turn_deg`, each with its sd (`*_sd`, over posterior draws), from the along
    model and the across one (None: a scalar target, its own component alone). `base` is the relation
    the along weights depart from (1 where the model fits the departure from its station,
    targets/reference_part.py; a scalar component's share of the flood axis there)."""
    wa = weight_draws(along, xy, draws)
    if wa is None:
        return None
    wc = weight_draws(across, xy, draws, seed=1) if across is not None else np.zeros_like(wa)
    if wc is None:
        wc = np.zeros_like(wa)
    out: dict[str, np.ndarray] = {}
    (fa, ea), (fc, ec) = flood_ebb(wa), flood_ebb(wc)
    for tag, al, ac in (("", fa, fc), ("ebb_", ea, ec)):
        rel = _relation(base + al[..., 0], ac[..., 0], al[..., 1], ac[..., 1])
        for key, v in rel.items():
            out[tag + key] = v[0]
            if key == "ratio":
                out[tag + key + "_sd"] = v[1:].std(axis=0)
            else:  # an angle or an offset wraps: the spread about the estimate
                period = 360.0 if key == "turn_deg" else 2 * math.pi / OMEGA
                d = (v[1:] - v[0][None] + period / 2) % period - period / 2
                out[tag + key + "_sd"] = np.sqrt((d**2).mean(axis=0))
    return out


def describe_relation(along, across, xy: np.ndarray, base: float | np.ndarray = 0.0) -> list[str]:
    """The relation in words over the places `xy` (the survey's track): its median and range."""
    maps = relation_maps(along, across, xy, base, draws=100)
    if maps is None:
        return []
    lines = []
    for tag, words in (("", "flood"), ("ebb_", "ebb")):
        r, o, u = maps[tag + "ratio"], maps[tag + "offset_s"] / 60.0, maps[tag + "turn_deg"]
        rs, os_ = maps[tag + "ratio_sd"], maps[tag + "offset_s_sd"] / 60.0
        lines.append(
            f"  {words}: ratio {np.median(r):.2f} +- {np.median(rs):.2f} (5-95 % over the track "
            f"{np.percentile(r, 5):.2f}-{np.percentile(r, 95):.2f}), the place later than its station by "
            f"{np.median(o):+.0f} +- {np.median(os_):.0f} min ({np.percentile(o, 5):+.0f} to "
            f"{np.percentile(o, 95):+.0f}), its flood turned {np.median(u):+.0f} deg from the station's axis"
        )
    return lines
