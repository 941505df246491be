"""The home row ground stations of the QGC WPL tradition send as item 0 (MAVProxy `wp load`,
Mission Planner): not a mission item, but the GCS's numbering is kept (issue 14 item 10)."""

from __future__ import annotations

from pymavlink import mavutil, mavwp

from c4d_bridge_mavlink.mission_protocol import MISSION, MissionServer, WireItem, home_row_of
from c4d_bridge_mavlink.signing import mavlink as M

GCS = M.MAVLink(None, 255, 190)
WPL = """QGC WPL 110
0\t1\t0\t16\t0\t0\t0\t0\t43.5629\t1.4815\t146.0\t1
1\t0\t3\t16\t0\t0\t0\t0\t43.56295\t1.48155\t6.0\t1
2\t0\t3\t16\t0\t0\t0\t0\t43.56300\t1.48155\t6.0\t1
3\t0\t2\t20\t0\t0\t0\t0\t0\t0\t0\t1
"""


def from_gcs(msg):
    return M.MAVLink(None, 1, 1).decode(bytearray(msg.pack(GCS)))


def mavproxy_items(path, monkeypatch) -> list:
    """The items MAVProxy's `wp load` sends: pymavlink's MAVWPLoader rows (MAVLink 2, as MAVProxy
    runs it) as MISSION_ITEM_INT."""
    monkeypatch.setenv("MAVLINK20", "1")
    mavutil.set_dialect("common")
    try:
        loader = mavwp.MAVWPLoader(target_system=1, target_component=1)
        loader.load(str(path))
    finally:
        monkeypatch.undo()
        mavutil.set_dialect("common")
    out = []
    for w in (loader.wp(k) for k in range(loader.count())):
        located = w.command in (16, 22)
        x, y = (int(w.x * 1e7), int(w.y * 1e7)) if located else (int(w.x), int(w.y))
        out.append(M.MAVLink_mission_item_int_message(1, 1, w.seq, w.frame, w.command, w.current, w.autocontinue, w.param1,
                                                      w.param2, w.param3, w.param4, x, y, w.z, MISSION))
    return out


class Harness:
    def __init__(self) -> None:
        self.out, self.uploads, self.current = [], [], []
        self.server = MissionServer(self.out.append, on_upload=lambda t, items: self.uploads.append(items),
                                    on_clear=lambda t: M.MAV_MISSION_ACCEPTED,
                                    on_set_current=lambda k: self.current.append(k) or k < 3)

    def upload(self, items) -> None:
        self.server.handle(from_gcs(M.MAVLink_mission_count_message(1, 1, len(items), MISSION)), 0.0)
        for msg in items:
            self.server.handle(from_gcs(msg), 0.0)


def test_mavproxy_wp_load_home_row_is_not_an_item_and_the_numbering_is_kept(tmp_path, monkeypatch):
    path = tmp_path / "mission.waypoints"
    path.write_text(WPL)
    h = Harness()
    h.upload(mavproxy_items(path, monkeypatch))
    assert [i.command for i in h.uploads[0]] == [16, 16, 20]  # the mission node gets the three items
    h.server.finish_upload(M.MAV_MISSION_ACCEPTED, plan_id=4)
    assert h.out[-1].get_type() == "MISSION_ACK" and h.out[-1].type == M.MAV_MISSION_ACCEPTED
    h.server.active_plan_id = 4
    assert h.server.wire_seq(4, 0) == 1 and h.server.wire_seq(4, 3) == 4  # MISSION_CURRENT seq / total
    assert h.server.wire_seq(5, 0) == 0  # another plan (uploaded over ROS): no home row
    h.server.handle(from_gcs(M.MAVLink_mission_set_current_message(1, 1, 2)), 0.0)
    assert h.current == [1]  # GCS item 2 = plan item 1
    h.server.handle(from_gcs(M.MAVLink_mission_set_current_message(1, 1, 0)), 0.0)
    assert h.current == [1] and h.out[-1].get_type() == "STATUSTEXT"  # the home row cannot be flown
    h.server.handle(from_gcs(M.MAVLink_mission_request_list_message(1, 1, MISSION)), 0.0)
    assert h.out[-1].count == 4  # downloaded as uploaded, home row first
    h.server.handle(from_gcs(M.MAVLink_mission_request_int_message(1, 1, 0, MISSION)), 0.0)
    assert h.out[-1].frame == M.MAV_FRAME_GLOBAL_INT and h.out[-1].z == 146.0
    h.server.handle(from_gcs(M.MAVLink_mission_ack_message(1, 1, M.MAV_MISSION_ACCEPTED, MISSION)), 0.0)
    h.server.handle(from_gcs(M.MAVLink_mission_clear_all_message(1, 1, MISSION)), 0.0)
    assert h.server.home_row is None and h.server.wire_seq(4, 0) == 0


def test_only_an_absolute_first_waypoint_before_relative_items_is_a_home_row():
    home = WireItem(16, M.MAV_FRAME_GLOBAL_INT, (0, 0, 0, 0, 43.5, 1.4, 146.0))
    relative = WireItem(16, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, (0, 0, 0, 0, 43.5, 1.4, 6.0))
    amsl = WireItem(16, M.MAV_FRAME_GLOBAL_INT, (0, 0, 0, 0, 43.5, 1.4, 152.0))
    takeoff = WireItem(22, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, (0, 0, 0, 0, 0, 0, 5.0))
    assert home_row_of([home, relative]) is home
    assert home_row_of([amsl, amsl]) is None  # a QGC plan in AMSL mode: an ordinary waypoint
    assert home_row_of([takeoff, relative]) is None and home_row_of([home]) is None
