"""Host-side pulse bookkeeping for the bridge's anemometer and paddle wheels.

The bridge sends cumulative pulse counts that wrap at ``wire.COUNT_MOD`` (2**30), the device time of
each channel's last accepted edge, and the period between its last two edges. From any two SAMPLE
frames of the same boot the pulses between them are exact, however many frames were lost between.

    tracker = PulseTracker()
    for frame in decoder.feed(data):
        for r in tracker.update(frame):      # one ChannelRate per channel for each SAMPLE
            print(r.channel, r.pulses, r.total, r.rate_hz)

Channel 0 is the anemometer, 1..4 the paddle wheels. A change of boot id is a board reset: the
tracker starts a new boot (``resets`` counts them) and totals restart from that boot's first frame.
"""

from __future__ import annotations

from collections import deque

from forcemap.protocol import wire

N_CHANNELS = 1 + wire.N_WHEELS


def pulses_between(earlier: wire.Frame, later: wire.Frame, channel: int) -> int:
    """Exact pulses on ``channel`` between two SAMPLE frames of the same boot."""
    if earlier.boot_id != later.boot_id:
        raise ValueError("frames from different boots: counts are not comparable")
    return wire.count_delta(channel_fields(earlier)[channel][0], channel_fields(later)[channel][0])


def channel_fields(frame: wire.Frame) -> list[tuple[int, int, int]]:
    """The five (count, last_edge_us, period_us) triples of a SAMPLE frame, anemometer first."""
    f = frame.fields
    return [f["anemo"], *f["wheels"]]


class ChannelRate:
    """One channel's state after a SAMPLE frame.

    - ``pulses``: exact pulses since the previous SAMPLE of this boot the tracker saw (None on the
      first frame of a boot).
    - ``total``: exact pulses since the first frame of this boot the tracker saw.
    - ``count``: the raw wrapped cumulative count from the frame.
    - ``rate_hz``: best estimate of the pulse rate: from counts between edge times over the window
      when at least ``min_pulses`` fell in it, else from the last period, decayed by the time since
      the last edge; 0 after ``stall_us`` without an edge.
    - ``rate_count_hz``: pulses over the window divided by the frame-time span (None without a span).
    - ``rate_period_hz``: 1e6 / last period (None before two edges).
    - ``last_edge_us``, ``period_us``: from the frame (0 = none yet); ``edge_age_us`` = frame time
      minus last edge time (None before the first edge).
    """

    __slots__ = (
        "channel",
        "t_us",
        "count",
        "pulses",
        "total",
        "rate_hz",
        "rate_count_hz",
        "rate_period_hz",
        "last_edge_us",
        "period_us",
        "edge_age_us",
    )

    def __init__(
        self,
        channel,
        t_us,
        count,
        pulses,
        total,
        rate_hz,
        rate_count_hz,
        rate_period_hz,
        last_edge_us,
        period_us,
        edge_age_us,
    ):
        self.channel = channel
        self.t_us = t_us
        self.count = count
        self.pulses = pulses
        self.total = total
        self.rate_hz = rate_hz
        self.rate_count_hz = rate_count_hz
        self.rate_period_hz = rate_period_hz
        self.last_edge_us = last_edge_us
        self.period_us = period_us
        self.edge_age_us = edge_age_us

    def __repr__(self):
        return (
            f"ChannelRate(ch={self.channel} t_us={self.t_us} pulses={self.pulses} "
            f"total={self.total} rate_hz={self.rate_hz:.3f})"
        )


class BootState:
    """What the tracker knows about one boot of the board."""

    def __init__(self, boot_id: int):
        self.boot_id = boot_id
        self.hello: dict | None = None
        self.last_seq: int | None = None
        self.last_counts: list[int] | None = None
        self.totals = [0] * N_CHANNELS
        self.samples = 0
        self.frames = 0
        self.lost_frames = 0
        self.stale_frames = 0
        # (t_us, totals, last_edge_us list) of recent samples, for windowed rates
        self.history: deque = deque()


class PulseTracker:
    """Unwraps counts per boot and estimates pulse rates. Feed it every decoded frame in order.

    ``window_us``: span of past samples used for count-based rates. ``min_pulses``: below this many
    pulses in the window the rate comes from the edge period instead. ``stall_us``: no edge for this
    long means a rate of 0.
    """

    def __init__(self, window_us: int = 2_000_000, min_pulses: int = 4, stall_us: int = 10_000_000):
        self.window_us = window_us
        self.min_pulses = min_pulses
        self.stall_us = stall_us
        self.boot: BootState | None = None
        self.resets = 0
        self.boots: list[int] = []

    @property
    def boot_id(self) -> int | None:
        return None if self.boot is None else self.boot.boot_id

    def _boot_for(self, frame: wire.Frame) -> BootState:
        if self.boot is None or self.boot.boot_id != frame.boot_id:
            if self.boot is not None:
                self.resets += 1
            self.boot = BootState(frame.boot_id)
            self.boots.append(frame.boot_id)
        return self.boot

    def update(self, frame: wire.Frame) -> list[ChannelRate]:
        """Account for one frame. Returns one ChannelRate per channel for a new SAMPLE, else []."""
        boot = self._boot_for(frame)
        if boot.last_seq is not None:
            gap = wire.seq_delta(boot.last_seq, frame.seq)
            if gap == 0 or gap >= wire.SEQ_MOD // 2:
                boot.stale_frames += 1
                return []
            boot.lost_frames += gap - 1
        boot.last_seq = frame.seq
        boot.frames += 1
        if frame.msg_type == wire.HELLO:
            boot.hello = frame.fields
            return []
        if frame.msg_type != wire.SAMPLE:
            return []
        return self._sample(boot, frame)

    def _sample(self, boot: BootState, frame: wire.Frame) -> list[ChannelRate]:
        chans = channel_fields(frame)
        counts = [c[0] for c in chans]
        first = boot.last_counts is None
        deltas = [None] * N_CHANNELS
        if not first:
            for i in range(N_CHANNELS):
                deltas[i] = wire.count_delta(boot.last_counts[i], counts[i])
                boot.totals[i] += deltas[i]
        boot.last_counts = counts
        boot.samples += 1
        t = frame.t_us
        edges = [c[1] for c in chans]
        hist = boot.history
        hist.append((t, list(boot.totals), edges))
        while len(hist) > 2 and t - hist[1][0] >= self.window_us:
            hist.popleft()
        old_t, old_totals, old_edges = hist[0]
        out = []
        for i, (count, last_edge, period) in enumerate(chans):
            n = boot.totals[i] - old_totals[i]
            span = t - old_t
            rate_count = n * 1e6 / span if span > 0 else None
            rate_period = 1e6 / period if period > 0 else None
            age = t - last_edge if (count or last_edge) and last_edge <= t else None
            out.append(
                ChannelRate(
                    i, t, count, deltas[i], boot.totals[i],
                    self._best_rate(n, last_edge, old_edges[i], rate_period, age),
                    rate_count, rate_period, last_edge, period, age,
                )
            )  # fmt: skip
        return out

    def _best_rate(self, n, last_edge, old_edge, rate_period, age) -> float:
        if age is None or age > self.stall_us:
            return 0.0
        if n >= self.min_pulses and 0 < old_edge < last_edge:
            # n pulses between the window's first edge and its last: n periods exactly
            rate = n * 1e6 / (last_edge - old_edge)
        elif rate_period is not None:
            rate = rate_period
        else:
            return 0.0
        # no edge for longer than a period: the rate is at most one pulse per elapsed time
        if age > 0:
            rate = min(rate, 1e6 / age)
        return rate

    def total(self, channel: int) -> int:
        """Exact pulses on ``channel`` since the first frame of the current boot."""
        return 0 if self.boot is None else self.boot.totals[channel]
