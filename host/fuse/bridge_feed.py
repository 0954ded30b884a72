"""The bridge's frames: logged raw, timed by the bridge clock, SAMPLEs to apparent wind and wheels."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from forcemap.host.decode.pulses import PulseTracker
from forcemap.host.decode.vane import VaneDecoder
from forcemap.host.fuse import compensation as comp
from forcemap.host.fuse.timesync import SourceClock
from forcemap.host.log.messages import ApparentWind, BridgeFrame, BridgeHello, BridgeStatus
from forcemap.protocol import wire

if TYPE_CHECKING:
    from forcemap.host.fuse.feed import FeedContext


class BridgeDecoder:
    """Frames from the bridge's bytes; each SAMPLE goes to the assembler as one row."""

    def __init__(self, pipe: FeedContext, rate_window_s: float) -> None:
        self.pipe = pipe
        cal = pipe.cal
        self.ppm = [w.pulses_per_m for w in cal.wheels]
        self.frames = wire.StreamDecoder()
        self.pulses = PulseTracker(window_us=int(rate_window_s * 1e6))
        self.vane = VaneDecoder(
            cal.vane_table,
            cal.vane_vref,
            cal.vane_pullup_ohm,
            adc_ref=cal.vane_adc_ref,
            mounting_offset=cal.vane_offset_deg,
        )
        self.clock = SourceClock("bridge")
        self.hellos: dict[int, dict] = {}
        self.hello_mismatch: list[str] = []
        self.n_frames = 0
        self.n_samples = 0

    def feed(self, source: str, t_mono_ns: int, t_wall_ns: int, data: bytes) -> None:
        mono = t_mono_ns * 1e-9
        for fr in self.frames.feed(data):
            try:
                self._frame(fr, mono, t_mono_ns, t_wall_ns)
            except Exception:  # a bug on one frame must not lose the rest of the read
                self.pipe.internal("bridge")

    def gap(self, source: str = "bridge") -> None:
        """A fresh frame decoder (the partial frame is dropped) that keeps the counters."""
        old, new = self.frames, wire.StreamDecoder()
        new.rejects, new.frames, new.bytes_in = old.rejects, old.frames, old.bytes_in
        self.frames = new

    def counters(self) -> dict[str, Any]:
        rejects = self.frames.rejects
        boot = self.pulses.boot
        return {
            "frames": self.n_frames,
            "samples": self.n_samples,
            "rejected": dict(rejects) | {"total": sum(rejects.values())},
            "lost_frames": boot.lost_frames if boot else 0,
            "resets": self.pulses.resets,
            "vane_rejected": self.vane.rejected,
            "hello_differs_from_config": self.hello_mismatch,
        }

    def _frame(self, fr: wire.Frame, mono: float, t_mono_ns: int, t_wall_ns: int) -> None:
        pipe = self.pipe
        self.n_frames += 1
        host_mono, mapping = self.clock.observe(fr.t_us * 1e-6, mono, key=fr.boot_id)
        pipe.emit_mapping(mapping)
        t = pipe.wall.to_wall(host_mono)
        tname = wire.TYPE_NAMES.get(fr.msg_type, str(fr.msg_type))
        frame = BridgeFrame(fr.boot_id, fr.seq, fr.t_us, tname, fr.flags, fr.fields, t)
        frame.t_mono_ns, frame.t_wall_ns = t_mono_ns, t_wall_ns
        pipe.write("/bridge/frame", t, frame)
        rates = self.pulses.update(fr)
        if fr.msg_type == wire.HELLO:
            self.hellos[fr.boot_id] = fr.fields
            self._check_hello(fr.fields)
            pipe.write("/bridge/hello", t, BridgeHello(fr.boot_id, fr.fields, t_mono_ns, t_wall_ns))
            hello = {"boot_id": str(fr.boot_id), **{k: str(v) for k, v in fr.fields.items()}}
            pipe.metadata("hello", hello)
        elif fr.msg_type == wire.STATUS:
            msg = BridgeStatus(fr.boot_id, fr.fields, t_mono_ns, t_wall_ns)
            pipe.write("/bridge/status", t, msg)
        elif fr.msg_type == wire.SAMPLE and rates:
            self._sample(t, fr, rates)

    def _check_hello(self, hello: dict) -> None:
        """boat.toml is authoritative; a board that reports other constants is worth a warning."""
        cal = self.pipe.cal
        bad = []
        hz = hello.get("anemo_hz_per_mps") or 0.0
        if hz > 0 and abs(1.0 / hz - cal.anemo_mps_per_hz) > 0.01 * cal.anemo_mps_per_hz:
            bad.append("anemometer.mps_per_hz")
        for i, ppm in enumerate(hello.get("wheel_pulses_per_m") or ()):
            if (
                i < len(cal.wheels)
                and ppm > 0
                and abs(ppm - cal.wheels[i].pulses_per_m) > 0.01 * ppm
            ):
                bad.append(f"wheels[{i}].pulses_per_m")
        self.hello_mismatch = bad

    def _sample(self, t: float, fr: wire.Frame, rates: list) -> None:
        cal = self.pipe.cal
        self.n_samples += 1
        anemo_hz = rates[0].rate_hz
        vane_raw = fr.fields["vane_raw"]
        angle = self.vane.decode(vane_raw)
        speed = comp.apparent_wind_speed(anemo_hz, cal.anemo_mps_per_hz, cal.anemo_min_speed)
        wheels = [
            comp.wheel_speed(r.rate_hz, self.ppm[i], cal.wheel_min_speed)
            for i, r in enumerate(rates[1:5])
        ]
        msg = ApparentWind(self.pipe.utc_s(t), speed, angle, anemo_hz, vane_raw, "bridge")
        self.pipe.write("/wind/apparent", t, msg)
        self.pipe.assembler.bridge_sample(t, speed, angle, wheels)
