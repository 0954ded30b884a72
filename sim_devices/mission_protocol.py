"""The vehicle side of MAVLink's mission protocol, as ArduPilot Rover answers it.

    upload:   GCS: MISSION_COUNT(n)        vehicle: MISSION_REQUEST_INT(0)
              GCS: MISSION_ITEM_INT(0)     vehicle: MISSION_REQUEST_INT(1) ... MISSION_ACK(ACCEPTED)
    download: GCS: MISSION_REQUEST_LIST    vehicle: MISSION_COUNT(n)
              GCS: MISSION_REQUEST_INT(i)  vehicle: MISSION_ITEM_INT(i) ... GCS: MISSION_ACK
    GCS: MISSION_SET_CURRENT(seq)          vehicle: goes for item seq (``set_current``; the engine acts)

Item 0 is home. The vehicle re-requests an item it has waited ``retry_s`` for (virtual time), and
gives up after ``max_retries`` (MISSION_ACK(OPERATION_CANCELLED)). An item out of sequence is answered
with a request for the expected one. For tests of the ground side it can drop its first request for
a given item, answer one item with a NAK (MISSION_ACK(ERROR)) ``nak_times`` times, or ignore every
upload (``deaf``: a link that only carries telemetry down).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from forcemap.host.vessel.waypoints import Item
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

M = mavlink2


@dataclass
class MissionReceiver:
    """State of one upload; ``accepted`` holds the last complete mission (home first)."""

    retry_s: float = 1.0
    max_retries: int = 5
    drop_request: set[int] = field(default_factory=set)  # seq whose first request is not sent
    nak_at: int | None = None  # seq answered with MISSION_ACK(ERROR) instead of being stored
    nak_times: int = 1  # how many uploads are refused at nak_at
    deaf: bool = False  # uploads are not answered at all
    set_current: int | None = None  # a MISSION_SET_CURRENT received; the engine clears it
    accepted: list[Item] | None = None
    new_mission: bool = False  # set when a mission has been accepted; the engine clears it
    _count: int = 0
    _items: list[Item] = field(default_factory=list)
    _peer: tuple[int, int] = (255, 0)
    _asked_at: float = 0.0
    _retries: int = 0
    _active: bool = False

    def _request(self, seq: int, now: float) -> list:
        self._asked_at = now
        if seq in self.drop_request:
            self.drop_request.discard(seq)
            return []
        return [M.MAVLink_mission_request_int_message(*self._peer, seq, M.MAV_MISSION_TYPE_MISSION)]

    def _ack(self, result: int) -> list:
        return [M.MAVLink_mission_ack_message(*self._peer, result, M.MAV_MISSION_TYPE_MISSION)]

    def handle(self, msg, now: float) -> list:  # type: ignore[no-untyped-def]
        """Replies (pymavlink messages) to one received message at virtual time ``now``."""
        kind = msg.get_type()
        if getattr(msg, "mission_type", 0) != M.MAV_MISSION_TYPE_MISSION:
            return []
        if kind == "MISSION_SET_CURRENT":
            self.set_current = int(msg.seq)
            return []
        if kind == "MISSION_REQUEST_LIST":
            self._peer = (msg.get_srcSystem(), msg.get_srcComponent())
            n = len(self.accepted or [])
            return [M.MAVLink_mission_count_message(*self._peer, n, M.MAV_MISSION_TYPE_MISSION)]
        if kind in ("MISSION_REQUEST_INT", "MISSION_REQUEST") and not self._active:
            return self._send_item(int(msg.seq))
        if self.deaf:
            return []
        if (
            kind == "MISSION_COUNT"
            and getattr(msg, "mission_type", 0) == M.MAV_MISSION_TYPE_MISSION
        ):
            self._peer = (msg.get_srcSystem(), msg.get_srcComponent())
            self._count, self._items, self._retries = int(msg.count), [], 0
            self._active = self._count > 0
            if not self._active:
                self.accepted, self.new_mission = [], True
                return self._ack(M.MAV_MISSION_ACCEPTED)
            return self._request(0, now)
        if kind in ("MISSION_ITEM_INT", "MISSION_ITEM") and self._active:
            seq = int(msg.seq)
            if seq != len(self._items):
                return self._request(len(self._items), now)
            if self.nak_at == seq:
                self.nak_times -= 1
                if self.nak_times <= 0:
                    self.nak_at = None
                self._active = False
                return self._ack(M.MAV_MISSION_ERROR)
            scale = 1e-7 if kind == "MISSION_ITEM_INT" else 1.0
            self._items.append(
                Item(
                    int(msg.command), msg.x * scale, msg.y * scale, float(msg.z),
                    (msg.param1, msg.param2, msg.param3, msg.param4), int(msg.frame),
                )
            )  # fmt: skip
            self._retries = 0
            if len(self._items) < self._count:
                return self._request(len(self._items), now)
            self._active = False
            self.accepted, self.new_mission = list(self._items), True
            return self._ack(M.MAV_MISSION_ACCEPTED)
        return []

    def _send_item(self, seq: int) -> list:
        items = self.accepted or []
        if not 0 <= seq < len(items):
            return self._ack(M.MAV_MISSION_INVALID_SEQUENCE)
        it = items[seq]
        return [
            M.MAVLink_mission_item_int_message(
                *self._peer, seq, it.frame, it.command, int(seq == 0), 1, *it.params,
                it.lat_e7, it.lon_e7, it.alt, M.MAV_MISSION_TYPE_MISSION,
            )
        ]  # fmt: skip

    def tick(self, now: float) -> list:
        """Re-request an item waited for too long; give up after ``max_retries``."""
        if not self._active or now - self._asked_at < self.retry_s:
            return []
        self._retries += 1
        if self._retries > self.max_retries:
            self._active = False
            return self._ack(M.MAV_MISSION_OPERATION_CANCELLED)
        return self._request(len(self._items), now)
