"""What the live view costs: CPU of daemon + server + map process at 1x, and a map refit's CPU.

    python bench/bench_live.py cpu --duration 20m --speed 1     # two surveys side by side, 20 min
    python bench/bench_live.py refit                            # in process, a minute

`cpu` runs the simulator twice at once (same scenario, same seed): one daemon with `--live`, the
map process and a WebSocket client reading everything, one plain daemon: the baseline. CPU is each
process's own user+system time (psutil), the map process included, never wall time. `refit` feeds
a synthetic 20-minute survey at 4 Hz (the daemon's sample rate with a bridge) through `LiveMaps` as
the map process does, times one full hyperparameter refit of all maps (current, wind, depth), and
checks every depth map published between refits against fresh fits on the same samples.
"""

from __future__ import annotations

import argparse
import json
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def _cpu(proc) -> float:
    """User+system seconds of a process and its live children (the map process)."""
    import psutil

    total = 0.0
    try:
        p = psutil.Process(proc.pid)
        for q in [p, *p.children(recursive=True)]:
            t = q.cpu_times()
            total += t.user + t.system
    except psutil.NoSuchProcess:
        pass
    return total


def _daemon(out: Path, ports: Path, live: bool) -> subprocess.Popen:
    cmd = [sys.executable, "-m", "forcemap.host.cli", "run", "--quiet", "-o", str(out),
           "--bridge", str(ports / "bridge"), "--depth", str(ports / "depth"),
           "--mavlink", f"{ports / 'mavlink'},115200", "--clock", f"sim:{ports / 'clock'}",
           "--clock-wait", "60s"]  # fmt: skip
    if live:
        cmd += ["--live", "127.0.0.1:0", "--map-every", "60s"]
    return subprocess.Popen(
        cmd, cwd=ROOT, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True
    )


def _sim(ports: Path, duration: str, speed: float, truth: Path) -> subprocess.Popen:
    cmd = [sys.executable, "-m", "forcemap.host.cli", "sim", "--scenario", "river", "--faults", "none",
           "--speed", str(speed), "--duration", duration, "--ports", str(ports), "-o", str(truth),
           "--seed", "1"]  # fmt: skip
    return subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def cpu(duration: str, speed: float) -> dict:
    from bench.live_client import LiveClient

    tmp = Path(tempfile.mkdtemp(prefix="bench_live_"))
    runs = {}
    for name in ("live", "plain"):
        base = tmp / name
        runs[name] = {"ports": base / "ports", "out": base / "out", "truth": base / "truth"}
        runs[name]["daemon"] = _daemon(runs[name]["out"], runs[name]["ports"], name == "live")
    live = runs["live"]["daemon"]
    url = None
    for line in live.stderr:  # the daemon's JSON events: the live address comes first
        ev = json.loads(line)
        if ev.get("event") == "live":
            url = ev["connect"]
            break
    for r in runs.values():  # keep draining stderr, or a full pipe would stall a daemon
        threading.Thread(target=r["daemon"].stderr.read, daemon=True).start()
    client = LiveClient(url)
    client.wait_ready()
    t0 = time.monotonic()
    sims = {n: _sim(r["ports"], duration, speed, r["truth"]) for n, r in runs.items()}
    peak = {n: 0.0 for n in runs}
    while any(s.poll() is None for s in sims.values()):
        for n, r in runs.items():
            peak[n] = max(peak[n], _cpu(r["daemon"]))
        time.sleep(2.0)
    wall = time.monotonic() - t0
    for n, r in runs.items():
        peak[n] = max(peak[n], _cpu(r["daemon"]))
        r["daemon"].send_signal(signal.SIGTERM)
    for r in runs.values():
        r["daemon"].wait(120)
    client.close()
    res = {
        "survey_s": wall,
        "cpu_live_s": peak["live"],
        "cpu_plain_s": peak["plain"],
        "core_live": peak["live"] / wall,
        "core_plain": peak["plain"] / wall,
        "client_messages": len(client.messages),
        "client_topics": len(client.topics()),
        "map_updates": sum(1 for t, _, _ in client.messages if t == "/map/info"),
    }
    print(json.dumps(res, indent=1))
    return res


def _drift(g, sofar, comp) -> tuple[float, float, float]:
    """A depth map between refits against fresh fits on the same samples, on the cells within 20 m
    of a sample (the rest is extrapolation): max and median |live - fresh| / the fresh map's range
    there, for the fresh fit with the live map's hyperparameters (the basis's error), and the max for
    `forcemap fit`'s fresh fit (new hyperparameters: their age)."""
    import numpy as np
    from forcemap.host.live.growing import Component, live_survey
    from forcemap.host.live.layers import to_lonlat
    from forcemap.host.vessel.geodesy import LocalFrame
    from forcemap.host.workbench.terms.spec import BASELINE
    from scipy.spatial import cKDTree

    ny, nx = g.shape
    gx, gy = np.meshgrid(g.x0 + g.step * np.arange(nx), g.y0 + g.step * np.arange(ny))
    xy = np.column_stack([gx.ravel(), gy.ravel()])
    survey = live_survey(sofar, "depth")
    lon, lat = to_lonlat(xy[:, 0], xy[:, 1], g.lat0, g.lon0)
    at = np.column_stack(LocalFrame(survey.lat0, survey.lon0).to_local(lat, lon))
    sx, sy = LocalFrame(g.lat0, g.lon0).to_local(sofar["lat"], sofar["lon"])
    near = cKDTree(np.column_stack([sx, sy])).query(xy)[0] <= 20.0
    out = []
    for like in (comp, None):
        mu = Component.refit(survey, "depth", list(BASELINE), like=like).predict(at)[0]
        err = np.abs(g.fields["depth"].ravel() - mu)[near] / np.ptp(mu[near])
        out.append(err)
    return float(out[0].max()), float(np.median(out[0])), float(out[1].max())


def refit() -> dict:
    import numpy as np
    from forcemap.host.live.maps import LiveMaps

    from bench.synth_survey import simulate

    cols = simulate(duration_s=1200.0, seed=1, rate_hz=4.0)
    n = len(cols["t"])
    maps = LiveMaps(every_s=60.0)
    diffs = []  # _drift of every depth map published between hyperparameter refits
    t_checks = 0.0
    t_all = time.process_time()
    for i in range(n):
        maps.add({k: float(v[i]) for k, v in cols.items()})
        for g in maps.step():
            if g.target == "depth" and "refitted" not in g.reason:
                t = time.process_time()
                sofar = {k: v[: i + 1] for k, v in cols.items()}
                diffs.append((*_drift(g, sofar, maps.state["depth"].comps[0]), g.hyper_age_s,
                              g.n_hyper, g.n_samples, g.basis_covers))  # fmt: skip
                t_checks += time.process_time() - t
    t_incremental = time.process_time() - t_all - t_checks
    t = time.process_time()
    maps.step(force="refit", refit=True)
    t_refit = time.process_time() - t
    t = time.process_time()
    maps.step(force="update")
    t_update = time.process_time() - t
    from forcemap.host.live.growing import Component, live_survey

    t = time.process_time()
    for st in maps.state.values():  # a basis rebuilt over all samples, kept hyperparameters
        survey = live_survey(
            {k: np.asarray(v) for k, v in cols.items()}, [c.column for c in st.comps]
        )
        [Component.refit(survey, c.column, maps.terms, like=c) for c in st.comps]
    t_rebase = time.process_time() - t
    d = np.array([x[:6] for x in diffs]) if diffs else np.zeros((0, 6))
    res = {
        "samples": n,
        "refit_all_maps_cpu_s": t_refit,
        "update_all_maps_cpu_s": t_update,
        "basis_rebuild_all_maps_cpu_s": t_rebase,
        "whole_survey_incremental_cpu_s": t_incremental,
        "refits": maps.refits,
        "rebases": maps.rebases,
        "updates": maps.updates,
        "between_refit_checks": len(diffs),
        "all_basis_covers": all(x[6] for x in diffs),
        # |live - fresh| / the fresh map's range, cells within 20 m of a sample
        "same_hyper_max": float(d[:, 0].max()) if len(d) else None,
        "same_hyper_median_of_medians": float(np.median(d[:, 1])) if len(d) else None,
        "fresh_fit_max": float(d[:, 2].max()) if len(d) else None,
        "fresh_fit_median_of_max": float(np.median(d[:, 2])) if len(d) else None,
        "hyper_age_s_max": float(d[:, 3].max()) if len(d) else None,
        # per check: same-hyper max, same-hyper median, fresh-fit max, hyper age s, n_hyper, n
        "checks": [[round(float(v), 4) for v in row] for row in d],
    }
    print(json.dumps(res, indent=1))
    return res


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("what", choices=("cpu", "refit"))
    ap.add_argument("--duration", default="20m")
    ap.add_argument("--speed", type=float, default=1.0)
    ap.add_argument("--json", type=Path)
    a = ap.parse_args()
    res = cpu(a.duration, a.speed) if a.what == "cpu" else refit()
    if a.json:
        a.json.write_text(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
