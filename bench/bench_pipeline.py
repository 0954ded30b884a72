"""Replay a recorded hour of raw instrument bytes through parsing, alignment and compensation.

    python bench/bench_pipeline.py                 # an hour from the simulator (or --source synth)
    python bench/bench_pipeline.py --duration 600 --chunk-ms 20

The streams are made first (not timed): the simulator's river survey (``forcemap.sim_devices.engine``) with
its bridge at 4 Hz, the sounder's NMEA at 1 Hz and MAVLink at ArduPilot Rover rates, or the
synthetic survey in ``bench/synth_streams.py``. Bytes are coalesced per source into reads of
``--chunk-ms`` (what a reader polling the ports gets), stamped 2 ms after they leave the instrument.

Then, in one process, it times:
- the baseline: pymavlink's ``parse_buffer`` alone on the same MAVLink reads;
- the pipeline (``host.pipeline.Pipeline`` with a sink that discards): COBS/CRC frames, pulse rates,
  NMEA checks, MAVLink decoding, clock fits, boat-state interpolation, wind and both current
  estimators, the samples table rows, diagnostics.

It prints each as a multiple of real time and the share of one core that real-time operation needs.

Then it replays the real NMEA captures in ``../shared/data/real/nmea`` (line times from their UTC,
as ``forcemap import`` does; not timed) through the pipeline, each timed against its own duration.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # `bench.*` when run as a script

from forcemap.host.fuse.pipeline import NullSink, Pipeline  # noqa: E402
from pymavlink.dialects.v20 import ardupilotmega as mavlink  # noqa: E402

LATENCY_NS = 2_000_000


def from_sim(duration: float, seed: int) -> list[tuple[str, int, bytes]]:
    from forcemap.sim_devices.engine import Simulation

    out: list[tuple[str, int, bytes]] = []
    Simulation(seed=seed).run(
        duration, lambda src, t_ns, data: out.append((src, t_ns, bytes(data)))
    )
    return out


def from_synth(duration: float, seed: int) -> list[tuple[str, int, bytes]]:
    from bench.synth_streams import generate

    events, _ = generate(duration, seed=seed)
    return [(src, wall - LATENCY_NS, data) for src, _mono, wall, data in events]


def coalesce(
    events: list[tuple[str, int, bytes]], chunk_ms: float
) -> list[tuple[str, int, int, bytes]]:
    """Per source, everything that left the instrument within one read period becomes one read."""
    period = int(chunk_ms * 1e6)
    reads: list[tuple[str, int, int, bytes]] = []
    open_: dict[str, tuple[int, list[bytes]]] = {}
    for src, t, data in events:
        slot = t // period if period else t
        cur = open_.get(src)
        if cur is not None and cur[0] != slot:
            t_read = (cur[0] + 1) * period + LATENCY_NS if period else cur[0] + LATENCY_NS
            reads.append((src, t_read, t_read, b"".join(cur[1])))
            cur = None
        if cur is None:
            open_[src] = cur = (slot, [])
        cur[1].append(data)
    for src, (slot, parts) in open_.items():
        t_read = (slot + 1) * period + LATENCY_NS if period else slot + LATENCY_NS
        reads.append((src, t_read, t_read, b"".join(parts)))
    reads.sort(key=lambda r: r[1])
    return reads


def run_baseline(reads) -> tuple[float, int]:
    mav = mavlink.MAVLink(None)
    mav.robust_parsing = True
    n = 0
    t0 = time.process_time()
    for src, _, _, data in reads:
        if src == "mavlink":
            msgs = mav.parse_buffer(data)
            if msgs:
                n += len(msgs)
    return time.process_time() - t0, n


def run_pipeline(reads, sync: str) -> tuple[float, Pipeline, NullSink]:
    sink = NullSink()
    pipe = Pipeline(sink=sink, sync=sync)
    t0 = time.process_time()
    for r in reads:
        pipe.feed(*r)
    pipe.close()
    return time.process_time() - t0, pipe, sink


REAL_NMEA = Path(__file__).resolve().parents[1] / "tests" / "data" / "real" / "nmea"


def run_real_nmea(target: float) -> bool:
    """Each real NMEA capture through the pipeline; True if all meet ``target`` x real time."""
    from forcemap.host.convert.importers import nmea_line_times
    from forcemap.host.decode.nmea import LineSplitter

    ok = True
    for path in sorted(REAL_NMEA.glob("*.*")):
        if path.suffix in (".md", ".csv"):
            continue
        splitter = LineSplitter()
        lines = splitter.feed(path.read_bytes()) + splitter.flush()
        times, _ = nmea_line_times(lines)
        span = times[-1] - times[0]
        pipe = Pipeline(sink=NullSink())
        t0 = time.process_time()
        for line, t in zip(lines, times, strict=True):
            ns = int(t * 1e9)
            pipe.feed("nmea", ns, ns, line + b"\n")
        pipe.close()
        cpu = time.process_time() - t0
        c = pipe.counters()
        x = span / cpu if cpu > 0 else float("inf")
        ok = ok and x >= target and not c["errors"]
        print(
            f"real NMEA {path.name}: {len(lines):,} lines, {span:,.0f} s of log, "
            f"{c['samples']['emitted']:,} samples in {cpu:.2f} s CPU = {x:,.0f}x real time"
        )
    return ok


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--duration", type=float, default=3600.0, help="seconds of survey (default: an hour)"
    )
    ap.add_argument("--source", choices=("sim", "synth"), default="sim")
    ap.add_argument(
        "--chunk-ms", type=float, default=50.0, help="read period per port (default 50 ms)"
    )
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--sync", choices=("interpolate", "approximate"), default="interpolate")
    ap.add_argument("--target", type=float, default=500.0, help="required multiple of real time")
    args = ap.parse_args(argv)

    t0 = time.perf_counter()
    try:
        events = (
            from_sim(args.duration, args.seed)
            if args.source == "sim"
            else from_synth(args.duration, args.seed)
        )
        source = args.source
    except ImportError:
        events, source = from_synth(args.duration, args.seed), "synth"
    reads = coalesce(events, args.chunk_ms)
    sizes: dict[str, int] = {}
    for src, _, _, data in reads:
        sizes[src] = sizes.get(src, 0) + len(data)
    print(
        f"streams: {args.duration:.0f} s of survey from {source} in {time.perf_counter() - t0:.1f} s; "
        f"{len(reads)} reads of {args.chunk_ms:g} ms; bytes "
        + ", ".join(f"{k} {v:,}" for k, v in sorted(sizes.items()))
    )

    base_s, n_mav = run_baseline(reads)
    pipe_s, pipe, sink = run_pipeline(reads, args.sync)
    c = pipe.counters()
    d = args.duration
    print(
        f"baseline  pymavlink parse_buffer only: {n_mav:,} messages in {base_s:.2f} s CPU = "
        f"{d / base_s:,.0f}x real time ({100 * base_s / d:.3f}% of a core)"
    )
    print(
        f"pipeline  parse+align+compensate ({args.sync}): {c['samples']['emitted']:,} samples, "
        f"{sum(sink.counts.values()):,} messages out in {pipe_s:.2f} s CPU = {d / pipe_s:,.0f}x real time "
        f"({100 * pipe_s / d:.3f}% of a core); {pipe_s / base_s:.1f}x the baseline's cost"
    )
    ok = d / pipe_s >= args.target and not c["errors"]
    ok = run_real_nmea(args.target) and ok
    print(
        f"target {args.target:g}x real time: {'met' if ok else 'NOT met'}"
        + (f"; errors {c['errors']}" if c["errors"] else "")
    )
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
