"""Host pulse bookkeeping: exact totals across count wraps, lost frames and resets; rates."""

import random

import pytest
from forcemap.host.decode.pulses import PulseTracker, pulses_between
from forcemap.protocol import wire
from hypothesis import given, settings
from hypothesis import strategies as st


class Board:
    """A minimal model of the firmware's counters, producing SAMPLE frames."""

    def __init__(self, boot_id, start_counts=(0,) * 5):
        self.boot_id = boot_id
        self.seq = 0
        self.counts = list(start_counts)
        self.edges = [0] * 5
        self.periods = [0] * 5
        self.t = 0

    def pulse(self, ch, t):
        if self.edges[ch]:
            self.periods[ch] = t - self.edges[ch]
        self.edges[ch] = t
        self.counts[ch] = (self.counts[ch] + 1) % wire.COUNT_MOD

    def frame(self, t, msg=wire.SAMPLE):
        self.t = t
        if msg == wire.SAMPLE:
            ch = [(self.counts[i], self.edges[i], self.periods[i]) for i in range(5)]
            payload = wire.pack_sample(1000, ch)
        else:
            payload = wire.pack_status([self.seq, 0, 0, 0, 0, 0])
        f = wire.decode_frame(wire.encode(msg, self.boot_id, self.seq, t, payload))
        self.seq += 1
        return f


def test_exact_totals_with_wrap_and_lost_frames():
    rng = random.Random(1)
    b = Board(0xABCD, start_counts=(wire.COUNT_MOD - 50,) * 5)
    tr = PulseTracker()
    truth = [0] * 5
    kept = []
    t = 0
    for k in range(400):
        first = k == 0
        for ch in range(5):
            for _ in range(rng.randrange(0, 3 + 5 * ch)):
                t += 7
                b.pulse(ch, t)
                if not first:
                    truth[ch] += 1
        t += 250_000
        f = b.frame(t)
        if k and rng.random() < 0.3:
            continue  # lost on the link
        if first:
            truth = [0] * 5
        tr.update(f)
        kept.append(f)
    assert [tr.total(ch) for ch in range(5)] == truth
    assert b.counts[4] < wire.COUNT_MOD - 50  # counts did wrap
    assert tr.boot.lost_frames == 399 - (len(kept) - 1)
    assert sum(pulses_between(kept[0], kept[-1], ch) for ch in range(5)) == sum(truth)


def test_reset_starts_a_new_boot():
    tr = PulseTracker()
    a = Board(1)
    a.pulse(0, 10)
    tr.update(a.frame(100))
    a.pulse(0, 200)
    a.pulse(0, 300)
    rates = tr.update(a.frame(400))
    assert rates[0].pulses == 2 and rates[0].total == 2
    b = Board(2)
    b.pulse(0, 50)
    rates = tr.update(b.frame(100))
    assert tr.resets == 1 and tr.boot_id == 2
    assert rates[0].pulses is None and rates[0].total == 0
    with pytest.raises(ValueError):
        pulses_between(a.frame(500), b.frame(600), 0)


def test_duplicates_and_non_samples_are_ignored():
    tr = PulseTracker()
    b = Board(7)
    f = b.frame(1000)
    assert len(tr.update(f)) == 5
    assert tr.update(f) == []
    assert tr.boot.stale_frames == 1
    assert tr.update(b.frame(2000, msg=wire.STATUS)) == []


@pytest.mark.parametrize("hz", [0.3, 1.0, 10.0, 62.5])
def test_rate_from_counts_and_periods(hz):
    period = round(1e6 / hz)
    b = Board(3)
    tr = PulseTracker()
    next_edge = 123_457
    rates = []
    for k in range(1, 200):
        t = k * 250_000
        while next_edge <= t:
            b.pulse(0, next_edge)
            next_edge += period
        rates = tr.update(b.frame(t))
    assert rates[0].rate_hz == pytest.approx(1e6 / period, rel=1e-9)
    assert rates[1].rate_hz == 0.0


def test_rate_decays_when_pulses_stop():
    b = Board(4)
    tr = PulseTracker(stall_us=5_000_000)
    for i in range(1, 41):
        b.pulse(0, i * 100_000)
    tr.update(b.frame(4_000_000))
    r = tr.update(b.frame(6_000_000))[0]
    assert r.rate_hz == pytest.approx(1e6 / 2_000_000)
    assert tr.update(b.frame(9_500_000))[0].rate_hz == 0.0


@given(
    start=st.integers(0, wire.COUNT_MOD - 1),
    steps=st.lists(
        st.tuples(st.lists(st.integers(0, 5000), min_size=5, max_size=5), st.booleans()),
        min_size=2,
        max_size=60,
    ),
)
@settings(max_examples=120, deadline=None)
def test_totals_exact_for_any_losses(start, steps):
    """Any pulses, any wrap position, any frames lost: totals between received frames are exact."""
    b = Board(9, start_counts=(start,) * 5)
    tr = PulseTracker()
    true = [0] * 5  # unwrapped pulses since the start
    first = None
    t = 0
    for k, (pulses, lost) in enumerate(steps):
        t += 250_000
        for ch in range(5):
            if pulses[ch]:
                b.counts[ch] = (b.counts[ch] + pulses[ch] - 1) % wire.COUNT_MOD
                b.pulse(ch, t - 1000)
                true[ch] += pulses[ch]
        f = b.frame(t)
        if lost and k:
            continue
        if first is None:
            first = list(true)
        tr.update(f)
        last = list(true)
    assert [tr.total(ch) for ch in range(5)] == [last[ch] - first[ch] for ch in range(5)]


def test_first_window_after_boot_uses_periods_not_time_since_boot():
    """Before the window holds an edge from its start, n pulses are not n periods."""
    b = Board(5)
    tr = PulseTracker()
    tr.update(b.frame(250_000))  # no edge yet
    for k in range(10):
        b.pulse(1, 5_000_000 + k * 50_000)  # 20 Hz, starting 5 s after boot
    r = tr.update(b.frame(5_500_000))[1]
    assert r.pulses == 10
    assert r.rate_hz == pytest.approx(20.0)
