"""Board configuration for the bridge: pin map per board, sample period and sensor constants.

This is the one file to edit for a different wiring or sensor. Pin names are the board names from
MicroPython's ``pins.csv`` for each board, so ``machine.Pin(name)`` finds them.
"""

FW_VERSION = (0, 1, 0)

SAMPLE_PERIOD_US = 250_000  # SAMPLE at 4 Hz
STATUS_PERIOD_US = 1_000_000  # STATUS once a second
LOCKOUT_US = 1_500  # reed-switch bounce lockout after an accepted edge (bounce lasts up to ~300 us)
STALE_EDGE_US = 1 << 28  # forget the previous edge after this long, well inside ticks_diff's range
VANE_SAMPLES = 8  # read_u16 readings averaged into one SAMPLE value
WDT_TIMEOUT_MS = 5_000
TICKS_BITS = 30  # ticks_us wraps at 2**30 on rp2 and esp32

# SparkFun anemometer: 2.4 km/h per closure per second, so 1.5 Hz per m/s (0.6667 m/s per Hz)
ANEMO_HZ_PER_MPS = 1.5
# Airmar-style paddle wheels: ~20,000 pulses per nautical mile; calibrate each wheel in place
WHEEL_PULSES_PER_M = (10.8, 10.8, 10.8, 10.8)

# anemo, wheel1..wheel4 are pulse inputs (falling edge: the switch or open collector pulls low);
# vane is the ADC pin of the divider. Only A0-A3 are RP2040 ADC inputs on the Nano RP2040 Connect.
BOARDS = {
    "nano_rp2040": {
        "name": "Arduino Nano RP2040 Connect",
        "pulse_pins": ("D2", "D3", "D4", "D5", "D6"),
        "vane_pin": "A0",
        "hard_irq": True,
        "hw_counter": (),
        "timer_id": -1,
    },
    "nano_esp32": {
        "name": "Arduino Nano ESP32",
        "pulse_pins": ("D2", "D3", "D4", "D5", "D6"),
        "vane_pin": "A0",
        # esp32 Pin.irq is always scheduled (soft), so the hall wheels, which do not bounce, are
        # counted by PCNT units (machine.Counter). The reed anemometer keeps the software lockout:
        # the PCNT glitch filter (<= 12.8 us) is far shorter than reed bounce.
        "hard_irq": False,
        "hw_counter": (1, 2, 3, 4),
        "timer_id": 0,
        "adc_11db": True,
    },
}

CHANNEL_NAMES = ("anemo", "wheel1", "wheel2", "wheel3", "wheel4")


def board_key(machine_name):
    """Board key for ``os.uname().machine``; nano_rp2040 if nothing matches."""
    if "ESP32" in machine_name:
        return "nano_esp32"
    return "nano_rp2040"


def pin_map(board):
    """The pin map as the text sent in HELLO, e.g. ``anemo=D2 wheel1=D3 ... vane=A0``."""
    b = BOARDS[board]
    parts = []
    for i in range(len(CHANNEL_NAMES)):
        parts.append(CHANNEL_NAMES[i] + "=" + b["pulse_pins"][i])
    parts.append("vane=" + b["vane_pin"])
    return " ".join(parts)
