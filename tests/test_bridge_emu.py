"""The real firmware under the CPython stand-in, streaming to a pty that pyserial reads.

A 10 Hz anemometer with 0.3 ms reed bounce and four wheels at different rates for 20 simulated
minutes; the first boot crosses the ticks_us wrap (2**30 us), the host stops reading for 2 s, and
the board resets near the end. The host recovers exact pulse counts, edge times and rates.
"""

import random

import pytest
from forcemap.host.decode.vane import decode_vane
from forcemap.host.vessel.geodesy import wrap_to_180
from forcemap.protocol import wire
from forcemap.sim_devices.bridge_emu import EmulatedBridge, add_bounce, vane_voltage
from forcemap.sim_devices.usb_cdc import UsbCdc

from tests.bridge_scenario import RATES, Host, check_boot, true_edges

MIN = 60_000_000
T_END = 20 * MIN
T_RESET = 19 * MIN + 10_000_000  # after the first wrap at 1073.7 s
DEAF = (5 * MIN, 5 * MIN + 2_000_000)  # the host does not read
CHUNK = 500_000


@pytest.mark.parametrize("board", ["nano_rp2040", "nano_esp32"])
def test_twenty_minutes_wrap_drops_and_reset(board):
    rng = random.Random(5)
    edges = [true_edges(hz, T_END, 1_234 + 7_919 * ch) for ch, hz in enumerate(RATES)]
    fired = [add_bounce(edges[0], bounce_us=300, n=2, rng=rng), *edges[1:]]
    with UsbCdc(host_buffer=512) as port:
        host = Host(port.path)  # open the host side first: pyserial discards pending input
        emu = EmulatedBridge(port.write, writable=port.writable, board=board, seed=11)
        boots = [emu.boot_us]
        first_fw = emu.firmware
        pos = [0] * 5
        for t in range(CHUNK, T_END + 1, CHUNK):
            for ch in range(5):
                i = pos[ch]
                j = i
                while j < len(fired[ch]) and fired[ch][j] < t:
                    j += 1
                emu.add_edges(ch, fired[ch][i:j])
                pos[ch] = j
            if t - CHUNK < T_RESET <= t:
                emu.advance_to(T_RESET)
                emu.reset()
                boots.append(emu.boot_us)
            emu.advance_to(t)
            if not DEAF[0] <= t <= DEAF[1]:
                host.read_available()
        host.drain(done=lambda: port.unread() == 0)
        host.close()
        frames = host.frames

    # each write timeout cuts a frame short: the decoder rejects it and loses nothing else. Either
    # boot may time out: the kernel moves pty bytes to the reader from a worker thread, which a busy
    # machine runs late, so the host can find fewer bytes than were written and fall behind
    timeouts = first_fw.write_timeouts + emu.firmware.write_timeouts
    assert emu.firmware is not first_fw
    assert host.dec.rejected() <= timeouts
    boot_ids = []
    for f in frames:
        if f.boot_id not in boot_ids:
            boot_ids.append(f.boot_id)
    assert len(boot_ids) == 2 and host.tracker.resets == 1
    # a frame that does not fit times out; while the FIFO stays full frames are dropped
    lost = first_fw.write_timeouts + first_fw.frames_dropped
    assert lost > 0
    assert (
        host.tracker.boots
        and sum(1 for f in frames if f.boot_id == boot_ids[0]) == first_fw.seq - lost
    )
    assert any(f.flags & wire.FLAG_DROPPED_BEFORE for f in frames)
    assert host.tracker.boots == boot_ids

    per_boot = {
        b: [f for f in frames if f.boot_id == b and f.msg_type == wire.SAMPLE] for b in boot_ids
    }
    first = per_boot[boot_ids[0]]
    # the first boot's device time runs past the ticks_us period, and the link lost frames
    assert first[-1].t_us > 1 << 30
    assert any(wire.seq_delta(a.seq, b.seq) > 1 for a, b in zip(first, first[1:], strict=False))
    # exact totals per boot from the tracker (which saw every frame, lost ones missing)
    totals0 = _totals_between(first)
    check_boot(first, boots[0], edges, totals0, _rates_at(first))
    second = per_boot[boot_ids[1]]
    assert second[0].t_us < 1_000_000
    check_boot(
        second,
        boots[1],
        edges,
        [host.tracker.total(ch) for ch in range(5)],
        host.rates[boot_ids[1]],
    )

    hello = [f for f in frames if f.msg_type == wire.HELLO]
    assert [h.fields["reset_cause"] for h in hello] == [1, 1]
    status = [f for f in frames if f.msg_type == wire.STATUS and f.boot_id == boot_ids[0]]
    assert status[-1].fields["bounce_rejects"] > 0
    assert status[-1].fields["frames_dropped"] + status[-1].fields["write_timeouts"] > 0


def _totals_between(samples):
    from forcemap.host.decode.pulses import PulseTracker

    tr = PulseTracker()
    for f in samples:
        tr.update(f)
    return [tr.total(ch) for ch in range(5)]


def _rates_at(samples):
    from forcemap.host.decode.pulses import PulseTracker

    tr = PulseTracker()
    r = None
    for f in samples:
        r = tr.update(f)
    return r


@pytest.mark.parametrize("i", range(16))
def test_vane_positions_through_firmware(i):
    out = bytearray()
    emu = EmulatedBridge(lambda b: out.extend(b) or len(b), seed=i)
    emu.set_vane_voltage(vane_voltage(i * 22.5))
    emu.advance_to(1_000_000)
    samples = [f for f in wire.StreamDecoder().feed(bytes(out)) if f.msg_type == wire.SAMPLE]
    assert len(samples) == 5
    for f in samples[1:]:
        assert decode_vane(f.fields["vane_raw"]) == wrap_to_180(i * 22.5)


def test_usb_write_timeout_is_counted_and_sampling_goes_on():
    out = []
    state = {"fail": False}

    def write(b):
        if state["fail"]:
            return None
        out.append(b)
        return len(b)

    emu = EmulatedBridge(write)
    emu.add_edges(0, range(10_000, 3_000_000, 100_000))
    emu.advance_to(1_000_000)
    state["fail"] = True
    emu.advance_to(2_000_000)
    state["fail"] = False
    emu.advance_to(3_000_000)
    frames = [wire.decode_frame(b) for b in out]
    assert emu.firmware.write_timeouts == 5  # 4 SAMPLEs and a STATUS while failing
    after = [f for f in frames if f.t_us > 2_000_000]
    assert after[0].flags & wire.FLAG_DROPPED_BEFORE
    assert not after[1].flags & wire.FLAG_DROPPED_BEFORE
    assert after[-1].fields.get("anemo", (0,))[0] == 30 or after[-2].fields["anemo"][0] == 30


def test_watchdog_resets_a_stalled_firmware():
    emu = EmulatedBridge(lambda b: len(b))
    boot = emu.boot_id
    emu.firmware.poll = lambda: 100_000  # a hung main loop that never feeds the WDT
    emu.advance_to(6_000_000)
    assert emu.boot_id != boot
    assert emu.firmware.reset_cause == 3


def test_edges_in_the_past_are_refused():
    emu = EmulatedBridge(lambda b: len(b))
    emu.advance_to(1000)
    with pytest.raises(ValueError):
        emu.add_edges(1, [999])
