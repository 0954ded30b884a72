"""`forcemap bridge monitor`: decoded frames, rates and reject counters from an emulated bridge."""

from __future__ import annotations

import io
import threading
import time

import serial
from forcemap.host.cli import bridge as bridge_cli
from forcemap.host.cli import main
from forcemap.protocol import wire
from forcemap.sim_devices.bridge_emu import EmulatedBridge, pulse_times, vane_voltage
from forcemap.sim_devices.usb_cdc import UsbCdc


def _emu_with_pulses(write, writable=None):
    emu = EmulatedBridge(write, writable=writable, seed=2)
    emu.set_vane_voltage(vane_voltage(90.0))
    emu.add_edges(0, pulse_times(15.0, 0, 60_000_000)[0])
    emu.add_edges(3, pulse_times(4.0, 0, 60_000_000)[0])
    return emu


def test_monitor_decodes_and_counts_rejects():
    with UsbCdc(host_buffer=1 << 16) as port:
        ser = serial.Serial(port.path, timeout=0.2)
        emu = _emu_with_pulses(port.write)
        emu.advance_to(3_000_000)
        port.write(b"\x00garbage\x00")  # one bad frame on the wire
        emu.advance_to(5_000_000)
        out = io.StringIO()
        mon = bridge_cli.monitor(ser, out=out, max_frames=1 + 21 + 5)
        ser.close()
    text = out.getvalue()
    assert mon.frames == 27
    assert mon.dec.rejected() == 1
    assert text.count("SAMPLE") == 21 and text.count("STATUS boot=") == 5
    assert "HELLO boot=" in text
    last = [ln for ln in text.splitlines() if ln.startswith("SAMPLE")][-1]
    assert "(+90.0deg)" in last
    assert "anemo  15.00Hz 10.00m/s" in last and "w3   4.00Hz" in last
    assert text.splitlines()[-1].startswith("== frames=27")


def test_monitor_ctrl_c_exits_cleanly():
    frames = []
    emu = EmulatedBridge(lambda b: frames.append(b) or len(b))
    emu.advance_to(1_000_000)

    class Ser:
        chunks = list(frames)

        def read(self, n):
            if not self.chunks:
                raise KeyboardInterrupt
            return self.chunks.pop(0)

    out = io.StringIO()
    mon = bridge_cli.monitor(Ser(), out=out)
    assert mon.frames == len(frames)
    assert out.getvalue().splitlines()[-1].startswith(f"== frames={len(frames)}")


def test_monitor_command_on_a_pty(capsys):
    """The CLI opens the port itself; the emulator streams until the monitor has its frames."""
    with UsbCdc(host_buffer=1 << 16) as port:
        emu = _emu_with_pulses(port.write)
        rc = []
        th = threading.Thread(
            target=lambda: rc.append(
                main(["bridge", "monitor", "--port", port.path, "--frames", "12"])
            )
        )
        th.start()
        t = 0
        while th.is_alive() and t < 600_000_000:
            t += 250_000
            emu.advance_to(t)
            time.sleep(0.01)
        th.join(timeout=10)
    assert rc == [0]
    out = capsys.readouterr().out
    decoded = [ln for ln in out.splitlines() if ln.startswith(("SAMPLE", "STATUS", "HELLO"))]
    assert len(decoded) == 12
    assert out.splitlines()[-1].startswith("== frames=12")


def test_monitor_bad_port_is_an_error(capsys):
    assert main(["bridge", "monitor", "--port", "/nonexistent/tty"]) == 2
    assert "cannot open" in capsys.readouterr().err
    assert wire.SAMPLE == 1
