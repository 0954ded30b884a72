"""Board entry point (copied to ``/main.py``): builds the bridge from the board config and runs it.

Frames go to the USB-CDC REPL port (``sys.stdout.buffer``). Nothing else may print to it.
"""

import gc
import os
import select
import sys
import time

import machine
import micropython
from forcemap.firmware_bridge import config
from forcemap.firmware_bridge.bridge import Bridge, run
from forcemap.firmware_bridge.pulse import CounterPulses, PulseCounter
from forcemap.firmware_bridge.vane import Vane
from forcemap.firmware_bridge.watchdog import LoopWatchdog


def make_counters(board):
    b = config.BOARDS[board]
    counters = []
    for i, name in enumerate(b["pulse_pins"]):
        pin = machine.Pin(name, machine.Pin.IN, machine.Pin.PULL_UP)
        if i in b["hw_counter"] and hasattr(machine, "Counter"):
            unit = b["hw_counter"].index(i)
            hw = machine.Counter(unit, pin, edge=machine.Counter.FALLING)
            counters.append(CounterPulses(pin, time, hw))
        else:
            counters.append(PulseCounter(pin, time, config.LOCKOUT_US, hard=b["hard_irq"]))
    return counters


def make_adc(b):
    pin = machine.Pin(b["vane_pin"])
    if b.get("adc_11db"):
        # esp32 defaults to 0 dB (about 0-1 V); 11 dB reads up to about 2.45 V linearly
        return machine.ADC(pin, atten=machine.ADC.ATTN_11DB)
    return machine.ADC(pin)


def stdout_writable():
    p = select.poll()
    p.register(sys.stdout, select.POLLOUT)

    def writable():
        return bool(p.poll(0))

    return writable


def main():
    micropython.alloc_emergency_exception_buf(100)
    board = config.board_key(os.uname().machine)
    b = config.BOARDS[board]
    wdt = LoopWatchdog(
        machine.WDT(timeout=config.WDT_TIMEOUT_MS), machine.Timer(b["timer_id"]), time
    )
    bridge = Bridge(
        make_counters(board),
        Vane(make_adc(b), config.VANE_SAMPLES),
        sys.stdout.buffer,
        time,
        boot_id=int.from_bytes(os.urandom(4), "little"),
        reset_cause=machine.reset_cause(),
        writable=stdout_writable(),
        wdt=wdt,
        mem_free=gc.mem_free,
        board=board,
    )
    try:
        run(bridge, time.sleep_us)
    except KeyboardInterrupt:
        wdt.hold()
        raise


main()
