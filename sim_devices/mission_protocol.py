"""The vehicle side of MAVLink's mission upload, as ArduPilot Rover answers it.

    GCS: MISSION_COUNT(n)          vehicle: MISSION_REQUEST_INT(0)
    GCS: MISSION_ITEM_INT(0)       vehicle: MISSION_REQUEST_INT(1) ... MISSION_ACK(ACCEPTED) after n-1

Item 0 is home. The vehicle re-requests an item it has waited ``retry_s`` for (virtual time), and
gives up after ``max_retries`` (MISSION_ACK(OPERATION_CANCELLED)). An item out of sequence is answered
with a request for the expected one. For tests of the ground side it can drop its first request for
a given item, or answer one item with a NAK (MISSION_ACK(ERROR)) once.
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
    nak_at: int | None = None  # seq answered once with MISSION_ACK(ERROR) instead of being stored
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

    def tick(self, now: float) -> list:
        """Re-request an item waited for too long; give up after ``max_retries``."""
        if not self._active or now - self._asked_at < self.retry_s:
            return []
        self._retries += 1
        if self._retries > self.max_retries:
            self._active = False
            return self._ack(M.MAV_MISSION_OPERATION_CANCELLED)
        return self._request(len(self._items), now)
