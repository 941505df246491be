"""MAVLink mission microservice, vehicle side (https://mavlink.io/en/services/mission.html).

What: upload (MISSION_COUNT → MISSION_REQUEST_INT per item → MISSION_ITEM_INT → MISSION_ACK),
download (MISSION_REQUEST_LIST → MISSION_COUNT → item requests → items → the GCS's ACK),
clear (MISSION_CLEAR_ALL), set current (MISSION_SET_CURRENT → MISSION_CURRENT), for mission
types MISSION and FENCE (RALLY is answered UNSUPPORTED). INT items only; MISSION_REQUEST (float,
deprecated) is answered with MISSION_ITEM_INT as the spec allows. Item requests are re-sent on a
timeout (default 1.5 s, 5 retries), after which the transfer is cancelled
(MAV_MISSION_OPERATION_CANCELLED). Out-of-sequence items are answered by re-requesting the expected
one (spec), items for a transfer that is not running get MAV_MISSION_ERROR, a count above the
limit MAV_MISSION_NO_SPACE. Nothing here raises on input.

Home row: ground stations of the QGC WPL tradition (MAVProxy `wp load`, Mission Planner) send the
planned home as item 0, a NAV_WAYPOINT in an absolute-altitude frame, before relative-altitude
items. It is not a mission item (PX4 and ArduPilot fly from item 1): `home_row_of` recognises it,
the mission node gets the items after it, and while the plan accepted from that upload is the
active one, the ground station's numbering is kept — MISSION_CURRENT, MISSION_ITEM_REACHED and
MISSION_SET_CURRENT count the home row (`wire_seq` / `plan_index`) and a download returns it first.
A first item in an absolute frame with no relative-altitude item after it (a QGC plan in AMSL
mode) is an ordinary waypoint.

Why a separate state machine: the protocol's sequencing, timeouts and result codes are the part
ground stations are picky about; here they are tested frame by frame without ROS. Acceptance is
asynchronous: a complete upload goes to `on_upload` (the node asks the mission node to validate)
and the ACK is sent by `finish_upload` with the verdict; the active plan only changes on accept.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from .signing import mavlink

M = mavlink
MISSION, FENCE, RALLY = M.MAV_MISSION_TYPE_MISSION, M.MAV_MISSION_TYPE_FENCE, M.MAV_MISSION_TYPE_RALLY
GLOBAL_INT_FRAMES = (M.MAV_FRAME_GLOBAL_INT, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, M.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT)


@dataclass(frozen=True)
class WireItem:
    """One mission item as carried by MISSION_ITEM_INT, with x/y already in degrees (float)."""

    command: int
    frame: int
    params: tuple[float, float, float, float, float, float, float]  # param1..4, x (lat), y (lon), z
    autocontinue: bool = True


def item_from_message(msg) -> WireItem:
    """MISSION_ITEM_INT → WireItem (int frames: degE7 → degrees; the non-int frame ids map to the INT ones)."""
    frame = {M.MAV_FRAME_GLOBAL: M.MAV_FRAME_GLOBAL_INT,
             M.MAV_FRAME_GLOBAL_RELATIVE_ALT: M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT}.get(msg.frame, msg.frame)
    x, y = float(msg.x), float(msg.y)
    if frame in GLOBAL_INT_FRAMES:
        x, y = x / 1e7, y / 1e7
    return WireItem(msg.command, frame, (msg.param1, msg.param2, msg.param3, msg.param4, x, y, float(msg.z)),
                    bool(msg.autocontinue))


def item_message(item: WireItem, seq: int, mission_type: int, target: tuple[int, int], current: bool = False):
    x, y = item.params[4], item.params[5]
    if item.frame in GLOBAL_INT_FRAMES:
        x, y = (int(round(v * 1e7)) if math.isfinite(v) else 0 for v in (x, y))
    else:
        x, y = (int(round(v)) if math.isfinite(v) else 0 for v in (x, y))
    p = [v if math.isfinite(v) or math.isnan(v) else 0.0 for v in item.params]
    return M.MAVLink_mission_item_int_message(target[0], target[1], seq, item.frame, item.command, int(current),
                                              int(item.autocontinue), p[0], p[1], p[2], p[3], x, y, p[6], mission_type)


def home_row_of(items: list[WireItem]) -> WireItem | None:
    """Item 0 when it is a QGC WPL home row (module docstring), else None."""
    if len(items) < 2 or items[0].command != M.MAV_CMD_NAV_WAYPOINT or items[0].frame != M.MAV_FRAME_GLOBAL_INT:
        return None
    relative = (M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, M.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT)
    return items[0] if any(i.frame in relative for i in items[1:]) else None


@dataclass
class _Transfer:
    kind: str  # "upload" | "download" | "validating"
    mission_type: int
    partner: tuple[int, int]
    count: int
    next_seq: int = 0
    items: list | None = None
    deadline: float = 0.0
    retries: int = 0
    home_row: WireItem | None = None  # an upload's home row, not handed to on_upload


class MissionServer:
    def __init__(self, send: Callable[[object], None], *, on_upload: Callable[[int, list[WireItem]], None],
                 on_clear: Callable[[int], int], on_set_current: Callable[[int], bool],
                 max_items: int = 500, timeout_s: float = 1.5, retries: int = 5) -> None:
        self.send = send
        self.on_upload, self.on_clear, self.on_set_current = on_upload, on_clear, on_set_current
        self.max_items, self.timeout_s, self.max_retries = max_items, timeout_s, retries
        self.stored: dict[int, list[WireItem]] = {MISSION: [], FENCE: []}  # what a download returns
        self.transfer: _Transfer | None = None
        self.home_row: WireItem | None = None  # of the plan uploaded with one (plan id home_plan_id)
        self.home_plan_id = -1
        self.active_plan_id = 0  # the mission node's active plan (the node reports it)
        self.stats = {"uploads": 0, "downloads": 0, "rejected": 0, "cancelled": 0, "retries": 0}

    # ------------------------------------------------------------------ helpers
    def _ack(self, partner: tuple[int, int], result: int, mission_type: int) -> None:
        self.send(M.MAVLink_mission_ack_message(partner[0], partner[1], result, mission_type))

    def _request(self) -> None:
        t = self.transfer
        self.send(M.MAVLink_mission_request_int_message(t.partner[0], t.partner[1], t.next_seq, t.mission_type))

    @staticmethod
    def _type(msg) -> int:
        return getattr(msg, "mission_type", MISSION)

    def _offset(self, plan_id: int) -> int:
        return 1 if self.home_row is not None and plan_id == self.home_plan_id else 0

    def wire_seq(self, plan_id: int, index: int) -> int:
        """The sequence number a GCS knows for item `index` (or count) of plan `plan_id`."""
        return index + self._offset(plan_id) if index >= 0 else index

    def plan_index(self, seq: int) -> int:
        """The active plan's item index of a GCS sequence number (-1: the home row)."""
        return seq - self._offset(self.active_plan_id)

    # ------------------------------------------------------------------ input
    def handle(self, msg, now: float) -> None:
        """Feed one received message addressed to us (other types are ignored)."""
        kind = msg.get_type()
        partner = (msg.get_srcSystem(), msg.get_srcComponent())
        handler = {"MISSION_COUNT": self._count, "MISSION_ITEM_INT": self._item, "MISSION_ITEM": self._item_float,
                   "MISSION_REQUEST_LIST": self._request_list, "MISSION_REQUEST_INT": self._request_item,
                   "MISSION_REQUEST": self._request_item, "MISSION_ACK": self._gcs_ack,
                   "MISSION_CLEAR_ALL": self._clear, "MISSION_SET_CURRENT": self._set_current}.get(kind)
        if handler is not None:
            handler(msg, partner, now)

    def _count(self, msg, partner, now) -> None:
        mtype = self._type(msg)
        if mtype not in (MISSION, FENCE):
            return self._ack(partner, M.MAV_MISSION_UNSUPPORTED, mtype)
        if self.transfer is not None and self.transfer.kind == "validating":
            return self._ack(partner, M.MAV_MISSION_DENIED, mtype)  # busy with the previous upload's verdict
        if msg.count > self.max_items:
            return self._ack(partner, M.MAV_MISSION_NO_SPACE, mtype)
        if msg.count == 0:
            self.transfer = _Transfer("validating", mtype, partner, 0, items=[])
            self.on_upload(mtype, [])
            return
        self.transfer = _Transfer("upload", mtype, partner, msg.count, items=[], deadline=now + self.timeout_s)
        self._request()

    def _item_float(self, msg, partner, now) -> None:
        t = self.transfer
        if t is None or t.kind != "upload" or partner != t.partner:
            return self._ack(partner, M.MAV_MISSION_ERROR, self._type(msg))
        # float items carry degrees in x/y: accept them as the INT form
        converted = M.MAVLink_mission_item_int_message(msg.target_system, msg.target_component, msg.seq, msg.frame,
                                                       msg.command, msg.current, msg.autocontinue, msg.param1,
                                                       msg.param2, msg.param3, msg.param4, 0, 0, msg.z, self._type(msg))
        item = item_from_message(converted)
        item = WireItem(item.command, item.frame, item.params[:4] + (float(msg.x), float(msg.y), item.params[6]),
                        item.autocontinue)
        self._accept_item(msg.seq, item, now)

    def _item(self, msg, partner, now) -> None:
        t = self.transfer
        if t is None or t.kind != "upload" or partner != t.partner or self._type(msg) != t.mission_type:
            return self._ack(partner, M.MAV_MISSION_ERROR, self._type(msg))
        self._accept_item(msg.seq, item_from_message(msg), now)

    def _accept_item(self, seq: int, item: WireItem, now: float) -> None:
        t = self.transfer
        if seq != t.next_seq:
            if seq < t.next_seq:
                return  # a duplicate (our re-request crossed it): ignore
            self._request()  # ahead of sequence: ask again for the one we need
            return
        t.items.append(item)
        t.next_seq += 1
        t.retries, t.deadline = 0, now + self.timeout_s
        if t.next_seq < t.count:
            self._request()
            return
        t.kind = "validating"
        t.home_row = home_row_of(t.items) if t.mission_type == MISSION else None
        self.on_upload(t.mission_type, t.items[1:] if t.home_row is not None else list(t.items))

    def finish_upload(self, result: int, plan_id: int = 0) -> None:
        """Verdict for the upload handed to on_upload: MAV_MISSION_ACCEPTED stores it (a MISSION
        upload as plan `plan_id`, with its home row if it had one)."""
        t = self.transfer
        if t is None or t.kind != "validating":
            return
        self.transfer = None
        if result == M.MAV_MISSION_ACCEPTED:
            self.stored[t.mission_type] = t.items[1:] if t.home_row is not None else list(t.items)
            if t.mission_type == MISSION:  # the accepted plan is the active one from now on
                self.home_row, self.home_plan_id, self.active_plan_id = t.home_row, plan_id, plan_id
            self.stats["uploads"] += 1
        else:
            self.stats["rejected"] += 1
        self._ack(t.partner, result, t.mission_type)

    def _request_list(self, msg, partner, now) -> None:
        mtype = self._type(msg)
        if mtype not in (MISSION, FENCE):
            self.send(M.MAVLink_mission_count_message(partner[0], partner[1], 0, mtype))
            return
        if self.transfer is not None and self.transfer.kind in ("upload", "validating"):
            return self._ack(partner, M.MAV_MISSION_DENIED, mtype)
        items = self.stored[mtype]
        if mtype == MISSION and self._offset(self.active_plan_id) and items:
            items = [self.home_row, *items]  # as the GCS uploaded it
        self.transfer = _Transfer("download", mtype, partner, len(items), items=list(items), deadline=now + self.timeout_s) \
            if items else None
        self.send(M.MAVLink_mission_count_message(partner[0], partner[1], len(items), mtype))

    def _request_item(self, msg, partner, now) -> None:
        mtype = self._type(msg)
        t = self.transfer
        if t is None or t.kind != "download" or partner != t.partner or mtype != t.mission_type:
            return self._ack(partner, M.MAV_MISSION_ERROR, mtype)
        if not 0 <= msg.seq < t.count:
            return self._ack(partner, M.MAV_MISSION_INVALID_SEQUENCE, mtype)
        t.deadline = now + self.timeout_s * (self.max_retries + 1)  # the GCS drives a download
        self.send(item_message(t.items[msg.seq], msg.seq, mtype, partner))

    def _gcs_ack(self, msg, partner, now) -> None:
        t = self.transfer
        if t is not None and t.kind == "download" and partner == t.partner:
            self.transfer = None
            self.stats["downloads"] += 1

    def _clear(self, msg, partner, now) -> None:
        mtype = self._type(msg)
        if mtype not in (MISSION, FENCE, M.MAV_MISSION_TYPE_ALL):
            return self._ack(partner, M.MAV_MISSION_UNSUPPORTED, mtype)
        if self.transfer is not None and self.transfer.kind in ("upload", "validating"):
            return self._ack(partner, M.MAV_MISSION_DENIED, mtype)
        result = self.on_clear(mtype)
        if result == M.MAV_MISSION_ACCEPTED:
            for t in (MISSION, FENCE):
                if mtype in (t, M.MAV_MISSION_TYPE_ALL):
                    self.stored[t] = []
                    self.home_row = None if t == MISSION else self.home_row
        self._ack(partner, result, mtype)

    def _set_current(self, msg, partner, now) -> None:
        index = self.plan_index(msg.seq)
        if index < 0 or not self.on_set_current(index):
            self.send(M.MAVLink_statustext_message(M.MAV_SEVERITY_WARNING, f"mission item {msg.seq} does not exist".encode(),
                                                   0, 0))

    # ------------------------------------------------------------------ time
    def poll(self, now: float) -> None:
        """Re-send the pending item request on timeout; cancel after the retries."""
        t = self.transfer
        if t is None or t.kind == "validating" or now < t.deadline:
            return
        if t.kind == "upload" and t.retries < self.max_retries:
            t.retries += 1
            t.deadline = now + self.timeout_s
            self.stats["retries"] += 1
            self._request()
            return
        self.transfer = None
        self.stats["cancelled"] += 1
        if t.kind == "upload":
            self._ack(t.partner, M.MAV_MISSION_OPERATION_CANCELLED, t.mission_type)
