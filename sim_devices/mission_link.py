"""The autopilot's side of the ground station's commands: the mission it holds, a new one written
during AUTO, MISSION_SET_CURRENT, mode changes and what steers in each mode, as ArduPilot Rover does them
(a Simulation mixin)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from forcemap.host.vessel import mission as ms
from forcemap.host.vessel import waypoints as wpl
from forcemap.host.vessel.control import Navigator

from . import modes as md


class MissionLink:
    """Mixed into Simulation: uses its mission, nav, boat, geo, autopilot, gains and queues."""

    mission: Any
    nav: Any
    boat: Any
    geo: Any
    autopilot: Any
    gains: Any
    uart_mav: Any
    mav_latency_ns: int
    t: float
    mode: int
    pilot: Any
    mode_log: list
    mode_changes: list
    ctl: Any
    cruise: float
    psi_d: float
    xte: float

    def _mission_items(self) -> list[wpl.Item]:
        """The mission as the autopilot holds it (home first); numbers each waypoint's item."""
        m = self.mission
        if m.items is not None and m.seqs is not None:  # a file's items, DO_ commands and all
            return list(m.items)
        lat, lon = self.geo.to_latlon(m.waypoints[:, 0], m.waypoints[:, 1])
        latlon = np.column_stack([lat, lon])
        items = wpl.items_for(latlon, m.speeds)
        if m.seqs is None:
            m.seqs = wpl.nav_points(items)[2]
        return [wpl.waypoint(*latlon[0]), *items]

    def _steer(self, dt: float) -> tuple[float, float]:
        """(throttle, steer) of the mode flown: the mission in AUTO, the mode's pilot otherwise."""
        s = self.boat.s
        while self.mode_changes and self.mode_changes[0].at_s <= self.t + 1e-9:
            self.set_mode(self.mode_changes.pop(0).mode)
        sog = math.hypot(s.ve, s.vn)
        if self.mode == md.AUTO:
            leg = self.nav.leg
            self.psi_d, self.xte = self.nav.update(s.x, s.y)
            if self.nav.leg != leg:  # Rover reports a new current item at once
                self.autopilot.report_now("MISSION_CURRENT")
            self.ctl.cruise = self.nav.speed(self.cruise)
            out = self.ctl.update(dt, s.psi, s.r, self.psi_d, sog)
            # Rover's HOLD at the end of a mission (MIS_DONE_BEHAVE 0): motor off, adrift
            return (0.0, 0.0) if self.nav.done else out
        psi_d = self.pilot.heading(self.mode, s.x, s.y)
        if psi_d is None:
            return 0.0, 0.0
        self.psi_d, self.ctl.cruise = psi_d, self.cruise
        return self.ctl.update(dt, s.psi, s.r, psi_d, sog)

    def set_mode(self, mode: int) -> None:
        """The operator (or a ground station) switches the flight mode."""
        if mode != self.mode:
            self.mode = self.autopilot.mode = mode
            self.pilot.entered(mode, self.boat.s.psi)
            self.mode_log.append((self.t, mode))
            self.autopilot.report_now("HEARTBEAT")

    def current_seq(self) -> int:
        """The mission item the boat is going for (MISSION_CURRENT)."""
        seqs = self.mission.seqs
        return int(seqs[self.nav.leg]) if seqs is not None else self.nav.leg + 1

    def uplink(self, data: bytes) -> None:
        """Bytes a ground station wrote to the autopilot's port. As Rover: a mission accepted during
        a mission keeps the current item number (the boat goes for the new mission's item at that
        number, from where it is); MISSION_SET_CURRENT sends it for another item."""
        replies = self.autopilot.receive(data, self.t)
        if replies:
            for t_ns, piece in self.uart_mav.send(self._ns(self.t), b"".join(replies)):
                self._push(t_ns + self.mav_latency_ns, "mavlink", piece)
        rx = self.autopilot.uplink
        if rx.new_mission and rx.accepted:
            rx.new_mission = False
            self._fly(rx.accepted, 1 if self.nav.done else self.current_seq())
        if rx.set_current is not None:
            seq, rx.set_current = rx.set_current, None
            if rx.accepted:
                self._fly(rx.accepted, seq)

    def _fly(self, items: list[wpl.Item], seq: int) -> None:
        """Go for the first waypoint at or after item ``seq`` of ``items`` (home first), from here."""
        s = self.boat.s
        try:
            m = ms.from_items(items, self.geo, (s.x, s.y))
        except ValueError:
            return  # nothing to fly: keep the current mission, as Rover does
        seqs = m.seqs
        k = int(np.searchsorted(seqs[1:], seq)) + 1  # type: ignore[index]
        if k >= len(seqs):  # type: ignore[arg-type]
            k = 1  # past the end: Rover starts the mission again
        keep = np.r_[0, np.arange(k, len(m.waypoints))]
        m.waypoints, m.seqs = m.waypoints[keep], seqs[keep]  # type: ignore[index]
        m.speeds = m.speeds[keep] if m.speeds is not None else None
        self.mission = m
        self.nav = Navigator(m.waypoints, self.gains, loop=False, speeds=m.speeds)
        self.autopilot.report_now("MISSION_CURRENT")
