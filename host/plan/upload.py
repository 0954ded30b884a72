"""Send a mission to an autopilot with MAVLink's mission protocol (the ground station's side).

    MISSION_COUNT(n) -> MISSION_REQUEST_INT(0) -> MISSION_ITEM_INT(0) -> ... -> MISSION_ACK(ACCEPTED)

A request not answered in ``timeout_s`` is retried: before the first request, MISSION_COUNT is sent
again; later, the vehicle re-requests (or the last item is sent again). A NAK (MISSION_ACK with an
error) restarts the upload from MISSION_COUNT, up to ``attempts`` times. The vehicle may ask for any
item at any time (a lost item is simply asked for again).
"""

from __future__ import annotations

import sys
from pathlib import Path

from forcemap.host.errors import CliError
from forcemap.host.vessel.mission import read_items
from forcemap.host.vessel.waypoints import Item
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as M

GCS_SYSTEM, GCS_COMPONENT = 255, 190


def item_message(seq: int, it: Item, target: tuple[int, int]):  # type: ignore[no-untyped-def]
    return M.MAVLink_mission_item_int_message(
        target[0], target[1], seq, it.frame, it.command, int(seq == 0), 1,
        *it.params, it.lat_e7, it.lon_e7, it.alt, M.MAV_MISSION_TYPE_MISSION,
    )  # fmt: skip


class Uploader:
    """One mission upload over a pymavlink connection."""

    def __init__(
        self,
        conn,  # type: ignore[no-untyped-def]
        items: list[Item],
        target: tuple[int, int] = (1, 1),
        timeout_s: float = 1.5,
        retries: int = 5,
        attempts: int = 3,
        log=None,  # type: ignore[no-untyped-def]
    ) -> None:
        self.conn, self.items, self.target = conn, items, target
        self.timeout_s, self.retries, self.attempts = timeout_s, retries, attempts
        self.log = log or (lambda s: None)
        self.naks = 0
        self.resent = 0

    def _send(self, msg) -> None:  # type: ignore[no-untyped-def]
        self.conn.mav.send(msg)

    def _count(self) -> None:
        self._send(
            M.MAVLink_mission_count_message(
                *self.target, len(self.items), M.MAV_MISSION_TYPE_MISSION
            )
        )

    def _attempt(self) -> bool:
        """One upload from MISSION_COUNT; True when accepted, False after a NAK (CliError on silence)."""
        self._count()
        last_seq: int | None = None
        silent = 0
        while True:
            msg = self.conn.recv_match(
                type=["MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"],
                blocking=True,
                timeout=self.timeout_s,
            )
            if msg is None:
                silent += 1
                if silent > self.retries:
                    raise CliError(
                        f"the autopilot stopped answering the mission upload after {self.retries} "
                        "retries; check the port, baud rate and that the autopilot is powered"
                    )
                self.resent += 1
                if last_seq is None:
                    self.log("no request yet: sending MISSION_COUNT again")
                    self._count()
                else:
                    self.log(f"no request after item {last_seq}: sending it again")
                    self._send(item_message(last_seq, self.items[last_seq], self.target))
                continue
            if getattr(msg, "mission_type", 0) != M.MAV_MISSION_TYPE_MISSION:
                continue
            silent = 0
            if msg.get_type() == "MISSION_ACK":
                if msg.type == M.MAV_MISSION_ACCEPTED and (
                    last_seq == len(self.items) - 1 or last_seq is None and not self.items
                ):
                    return True
                if msg.type != M.MAV_MISSION_ACCEPTED:
                    self.naks += 1
                    self.log(f"NAK (MISSION_ACK type {msg.type}) at item {last_seq}")
                    return False
                continue
            seq = int(msg.seq)
            if not 0 <= seq < len(self.items):
                continue
            self._send(item_message(seq, self.items[seq], self.target))
            last_seq = seq

    def run(self) -> int:
        """Upload; the number of items the vehicle acknowledged."""
        for attempt in range(self.attempts):
            if self._attempt():
                return len(self.items)
            self.log(f"upload attempt {attempt + 1} refused; starting again")
        raise CliError(
            f"the autopilot refused the mission {self.attempts} times (last MISSION_ACK was a NAK); "
            "check the mission in Mission Planner or QGroundControl"
        )


def connect(port: str, timeout_s: float = 10.0):  # type: ignore[no-untyped-def]
    """A pymavlink serial connection to ``PORT[,BAUD]`` that has heard the autopilot's heartbeat."""
    device, _, baud = port.partition(",")
    try:
        conn = mavutil.mavlink_connection(
            device, baud=int(baud or 115200), source_system=GCS_SYSTEM,
            source_component=GCS_COMPONENT,
        )  # fmt: skip
    except (OSError, ValueError) as e:
        raise CliError(f"cannot open {device}: {e}") from e
    # MAVLink 2 with ArduPilot's dialect on this connection only: mavutil's `dialect=` and the
    # MAVLINK20 variable would switch the dialect for the whole process
    conn.mav = M.MAVLink(conn, srcSystem=GCS_SYSTEM, srcComponent=GCS_COMPONENT)
    conn.mav.robust_parsing = True
    if conn.wait_heartbeat(timeout=timeout_s) is None:
        conn.close()
        raise CliError(f"no MAVLink heartbeat on {device} within {timeout_s:.0f} s")
    return conn


def upload_file(port: str, path: str | Path, progress: bool = True) -> int:
    """Upload a QGC WPL 110 or .plan file (home and items) to the autopilot on ``port``."""
    try:
        home, items = read_items(path)
    except ValueError as e:
        raise CliError(str(e)) from e
    conn = connect(port)
    try:
        target = (conn.target_system or 1, conn.target_component or 1)
        log = (lambda s: print(f"upload: {s}", file=sys.stderr)) if progress else None
        return Uploader(conn, [home, *items], target, log=log).run()
    finally:
        conn.close()


def download(
    conn, target: tuple[int, int] = (1, 1), timeout_s: float = 1.5, retries: int = 5
) -> list[Item]:  # type: ignore[no-untyped-def]
    """The mission the autopilot holds (home first), read with MISSION_REQUEST_LIST and one
    MISSION_REQUEST_INT per item (each asked again on silence, up to ``retries`` times)."""

    def ask(msg, want: str):  # type: ignore[no-untyped-def]
        for _ in range(retries + 1):
            conn.mav.send(msg)
            got = conn.recv_match(type=[want], blocking=True, timeout=timeout_s)
            if got is not None:
                return got
        raise CliError(
            f"the autopilot did not answer the mission download ({want}) after {retries} retries"
        )

    count = ask(
        M.MAVLink_mission_request_list_message(*target, M.MAV_MISSION_TYPE_MISSION), "MISSION_COUNT"
    )
    items = []
    for seq in range(int(count.count)):
        m = ask(
            M.MAVLink_mission_request_int_message(*target, seq, M.MAV_MISSION_TYPE_MISSION),
            "MISSION_ITEM_INT",
        )
        items.append(Item(int(m.command), m.x * 1e-7, m.y * 1e-7, float(m.z),
                          (m.param1, m.param2, m.param3, m.param4), int(m.frame)))  # fmt: skip
    conn.mav.send(
        M.MAVLink_mission_ack_message(*target, M.MAV_MISSION_ACCEPTED, M.MAV_MISSION_TYPE_MISSION)
    )
    return items


def same_mission(a: list[Item], b: list[Item]) -> bool:
    """Whether two missions (home first) fly the same: commands, positions to 1e-7 deg, speeds; the
    home item is not compared (the autopilot sets it where it was armed)."""

    def key(it: Item) -> tuple:
        return (it.command, it.lat_e7, it.lon_e7, round(float(it.params[1]), 2))

    return [key(i) for i in a[1:]] == [key(i) for i in b[1:]]


def set_current(conn, seq: int, target: tuple[int, int] = (1, 1)) -> None:  # type: ignore[no-untyped-def]
    """MISSION_SET_CURRENT: the autopilot goes for item ``seq``."""
    conn.mav.send(M.MAVLink_mission_set_current_message(*target, seq))
