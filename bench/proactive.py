"""What control faster than once per line would add (issue 22, item 4): the lawnmower flown with a
feed-forward crab angle and a through-the-water speed target computed at every step from the TRUE
current (an upper bound: a perfect map, guided setpoints at 20 Hz), against the plain mission.

    python bench/proactive.py
"""

from __future__ import annotations

import math

import numpy as np
from forcemap.host.plan.metrics import score_lines, summary
from forcemap.sim_devices import modes as md
from forcemap.sim_devices.engine import Simulation

from bench.inflight_loop import JUDGED_FROM, mission


def fly(crab: bool, speed: bool, seed: int = 2) -> dict:
    m = mission("river")
    sim = Simulation("river", m, [], seed=seed, instruments=False)
    sim.start(1200.0, lambda *a: None)
    nav = sim.nav
    update, nav_speed = nav.update, nav.speed

    def along_across() -> tuple[float, float]:
        ax, ay, bx, by, tx, ty, *_ = nav._geometry()
        p = sim.p
        return (
            p.current_east * tx + p.current_north * ty,
            p.current_east * ty - p.current_north * tx,
        )

    def guided(x: float, y: float) -> tuple[float, float]:
        psi, xte = update(x, y)
        if crab:
            _, right = along_across()
            psi -= math.asin(max(-0.9, min(0.9, right / sim.cruise)))
        return psi, xte

    def ground_speed(cruise: float) -> float:
        c, _ = along_across()
        return max(cruise, cruise + c) if speed else nav_speed(cruise)

    nav.update, nav.speed = guided, ground_speed  # type: ignore[method-assign]
    while sim.t < 1200.0 and not (sim.nav.done and sim.mode == md.AUTO):
        sim.advance(sim.t + 5.0)
    sim.finish()
    tr = sim.track
    sc = score_lines(tr["t"], np.column_stack([tr["x"], tr["y"]]), m.lines)
    return {"all": summary(sc), "judged": summary(sc[JUDGED_FROM:]), "lines": [s.p95 for s in sc],
            "cov": [s.coverage for s in sc], "time": float(tr["t"][-1])}  # fmt: skip


if __name__ == "__main__":
    for name, c, s in (("plain", False, False), ("speed through water", False, True),
                       ("crab feed-forward", True, False), ("both", True, True)):  # fmt: skip
        r = fly(c, s)
        print(f"| {name} | {r['all']['p95_worst_line']:.2f} | {r['all']['coverage']:.1%} | "
              f"{r['judged']['p95_worst_line']:.2f} | {r['judged']['coverage']:.1%} | "
              f"{' · '.join(f'{p:.2f}/{v:.0%}' for p, v in zip(r['lines'], r['cov'], strict=True))} | {r['time']:.0f} |",
              flush=True)  # fmt: skip
