"""A fence uploaded over MAVLink in flight (issue 18): the whole graph (sim, perception, navigation,
core with its barrier, mission, health, bridge) and a pymavlink GCS. The vehicle flies a 60 m leg
east; in flight the GCS uploads (MAVLink fence protocol) first a malformed fence (a 2-vertex
polygon: MISSION_ACK INVALID_PARAM1 + a STATUSTEXT reason), then one the vehicle is inside of
(DENIED + reason), then an exclusion polygon across the leg 20-25 m east: accepted at once, the
mission pauses with the leg reported blocked, the vehicle stops before the zone and never
enters it (sim/ground_truth), FENCE_STATUS comes at 1 Hz without a breach, and a fence download
returns the exclusion polygon."""

from __future__ import annotations

import math
import socket
import threading
import time

import pytest
from c4d_testing import installed_executable, sample_latest

from c4d_common.geodesy import GeoOrigin
from c4d_common.geofence import LocalFence
from c4d_common.plan import Geofence

SIM_HOME = GeoOrigin(43.5629, 1.4815, 146.0)  # c4d_sim's start: the ground truth's ENU origin
WALL_EAST = (20.0, 25.0)  # the exclusion polygon across the leg: east 20..25 m, north -15..15 m
WALL = ((WALL_EAST[0], -15.0), (WALL_EAST[1], -15.0), (WALL_EAST[1], 15.0), (WALL_EAST[0], 15.0))


def geo(east: float, north: float) -> tuple[float, float]:
    lat, lon, _ = SIM_HOME.to_geodetic(east, north, 0.0)
    return lat, lon


def fence_items(command: int, polygon) -> list[tuple[int, int, list[float]]]:
    return [(command, 5, [float(len(polygon)), 0.0, 0.0, 0.0, *geo(e, n), 0.0]) for e, n in polygon]


class FenceGcs:
    """Just enough of a ground station: a heartbeat thread, typed receive (STATUSTEXT reassembled
    and kept aside while waiting for something else), commands, and the mission protocol's upload
    side."""

    def __init__(self, port: int, mavlink) -> None:
        from pymavlink import mavutil

        self.M, self.texts, self.log, self.running = mavlink, [], [], True
        self.parts: dict[int, list[str]] = {}
        self.conn = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=255, source_component=190,
                                               dialect="common")
        self.lock = threading.Lock()
        self.thread = threading.Thread(target=self._heartbeats, daemon=True)
        self.thread.start()

    def _heartbeats(self) -> None:
        while self.running:
            with self.lock:
                self.conn.mav.heartbeat_send(self.M.MAV_TYPE_GCS, self.M.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            time.sleep(0.5)

    def send(self, name: str, *args) -> None:
        with self.lock:
            getattr(self.conn.mav, f"{name}_send")(*args)

    def recv(self, types, timeout: float):
        types = {types} if isinstance(types, str) else set(types)
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            msg = self.conn.recv_match(blocking=True, timeout=0.1)
            if msg is None:
                continue
            if msg.get_type() == "STATUSTEXT":  # chunks of one id, the last shorter than 50 characters
                self.parts.setdefault(msg.id, []).append(msg.text)
                if msg.id == 0 or len(msg.text) < 50:
                    self.texts.append("".join(self.parts.pop(msg.id)))
                    self.log.append(f"text {self.texts[-1]}")
            elif msg.get_type() in ("COMMAND_ACK", "MISSION_ACK"):
                self.log.append(f"{msg.get_type()} {msg.to_dict()}")
            if msg.get_type() in types:
                return msg
        return None

    def text(self, start: str, timeout: float) -> str:
        """The first STATUSTEXT starting with `start` (already received or within `timeout`), "" if none."""
        end = time.monotonic() + timeout
        while True:
            found = next((t for t in self.texts if t.startswith(start)), None)
            if found is not None or time.monotonic() > end:
                self.texts.clear()
                return found or ""
            self.recv("STATUSTEXT", 0.2)

    def command(self, command: int, *params: float):
        self.send("command_long", 1, 1, command, 0, *(list(params) + [0.0] * (7 - len(params))))
        end = time.monotonic() + 10.0
        while (ack := self.recv("COMMAND_ACK", end - time.monotonic())) is not None and ack.command != command:
            pass
        return ack

    def upload(self, items: list[tuple[int, int, list[float]]], mission_type: int = 0) -> int:
        """The GCS side of a mission / fence upload; the MISSION_ACK type."""
        self.send("mission_count", 1, 1, len(items), mission_type)
        while (msg := self.recv(["MISSION_REQUEST_INT", "MISSION_ACK"], 10.0)) is not None:
            if msg.get_type() == "MISSION_ACK":
                return msg.type
            command, frame, p = items[msg.seq]
            lat, lon = (int(round(v * 1e7)) for v in p[4:6])
            self.send("mission_item_int", 1, 1, msg.seq, frame, command, 0, 1, *p[:4], lat, lon, p[6], mission_type)
        raise AssertionError("no MISSION_REQUEST_INT / MISSION_ACK from the vehicle")

    def story(self) -> str:
        return "GCS saw:\n" + "\n".join(self.log[-25:])

    def close(self) -> None:
        self.running = False
        self.thread.join()
        self.conn.close()


@pytest.fixture(scope="module")
def graph(module_processes, ros_node):
    from c4d_bridge_mavlink.signing import mavlink

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    nodes = [("c4d_sim", "sim", []), ("c4d_gnc", "perception", []), ("c4d_gnc", "navigation", []),
             ("c4d_gnc", "core", ["--ros-args", "-p", "rt_priority:=50"]), ("c4d_mission", "mission", []),
             ("c4d_health", "health", []),
             ("c4d_bridge_mavlink", "bridge", ["--ros-args", "-p", f"endpoints:=['udpin:127.0.0.1:{port}']"])]
    procs = {name: module_processes.spawn(name, [installed_executable(pkg, name), *args]) for pkg, name, args in nodes}
    gcs = FenceGcs(port, mavlink)
    gcs.procs = procs
    from nav_msgs.msg import Odometry

    gcs.truth = sample_latest(ros_node[0], Odometry, "sim/ground_truth")
    yield gcs, mavlink
    gcs.close()


def truth(gcs) -> tuple[float, float, float, float]:
    """Ground truth east, north, up [m] from the sim's home and horizontal speed [m/s]."""
    odom = gcs.truth.latest()
    p, v = odom.pose.pose.position, odom.twist.twist.linear
    return p.x, p.y, p.z, math.hypot(v.x, v.y)


def test_fence_uploaded_in_flight_stops_the_vehicle_before_the_zone(graph):
    gcs, M = graph
    assert gcs.recv("HEARTBEAT", 40.0) is not None, gcs.story()
    assert gcs.recv("HOME_POSITION", 40.0) is not None, gcs.story()
    leg = [(M.MAV_CMD_NAV_WAYPOINT, 6, [0.0, 1.0, 0.0, math.nan, *geo(60.0, 0.0), 5.0]),
           (M.MAV_CMD_NAV_LAND, 6, [0.0] * 4 + [*geo(60.0, 0.0), 0.0])]
    end = time.monotonic() + 30.0
    while (result := gcs.upload(leg)) == M.MAV_MISSION_ERROR and time.monotonic() < end:
        time.sleep(1.0)  # no home / battery state yet: retry
    assert result == M.MAV_MISSION_ACCEPTED, gcs.story()
    for _ in range(20):
        if gcs.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == M.MAV_RESULT_ACCEPTED:
            break
        time.sleep(1.0)  # pre-arm: estimator / sensors settling
    else:
        pytest.fail(gcs.story())
    assert gcs.command(M.MAV_CMD_MISSION_START, 0, 0).result == M.MAV_RESULT_ACCEPTED, gcs.story()

    end = time.monotonic() + 40.0  # take-off to 5 m, then the leg east
    while (gcs.truth.latest() is None or truth(gcs)[0] < 3.0) and time.monotonic() < end:
        gcs.recv("HEARTBEAT", 0.2)
        assert all(p.poll() is None for p in gcs.procs.values()), "a node died"
    east, _, up, speed = truth(gcs)
    assert east >= 3.0 and up > 3.0, gcs.story()

    # a malformed fence: refused by the bridge, with the reason
    gcs.texts.clear()
    assert gcs.upload(fence_items(M.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION, WALL[:2]), 1) == \
        M.MAV_MISSION_INVALID_PARAM1
    assert "a polygon needs >= 3 vertices" in gcs.text("fence rejected", 5.0), gcs.story()
    # a fence the vehicle is inside of: refused by the mission node (no force over MAVLink)
    east, north, _, _ = truth(gcs)
    around = [(east - 5, north - 5), (east + 40, north - 5), (east + 40, north + 5), (east - 5, north + 5)]
    assert gcs.upload(fence_items(M.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION, around), 1) == \
        M.MAV_MISSION_DENIED
    assert "outside the new fence" in gcs.text("fence rejected", 5.0), gcs.story()

    # the exclusion polygon across the leg, ahead of the vehicle
    east_at_upload = truth(gcs)[0]
    assert east_at_upload < WALL_EAST[0] - 8.0, "the vehicle flew too far before the upload"
    assert gcs.upload(fence_items(M.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION, WALL), 1) == \
        M.MAV_MISSION_ACCEPTED, gcs.story()
    assert gcs.text("mission paused", 5.0).startswith("mission paused: the leg to item 1 enters"), gcs.story()
    fence = LocalFence.from_geofence(Geofence(exclusion_polygons=(tuple(geo(e, n) for e, n in WALL),)), SIM_HOME)
    samples, statuses, states = [], [], []
    end = time.monotonic() + 10.0
    while time.monotonic() < end:
        msg = gcs.recv(["FENCE_STATUS", "MISSION_CURRENT"], 0.05)
        if msg is not None:
            (statuses if msg.get_type() == "FENCE_STATUS" else states).append(msg)
        samples.append(truth(gcs))
    furthest = max(s[0] for s in samples)
    print(f"\nfence uploaded at {east_at_upload:.1f} m east (speed {speed:.1f} m/s); furthest {furthest:.2f} m, "
          f"zone from {WALL_EAST[0]:g} m; final speed {samples[-1][3]:.2f} m/s")
    assert all(fence.breach((e, n, u)) is None for e, n, u, _ in samples)
    assert furthest < WALL_EAST[0] - 0.5, gcs.story()  # never inside the protection radius of the zone
    assert samples[-1][3] < 0.5, f"still moving at {samples[-1][3]:.2f} m/s"
    assert len(statuses) >= 8 and all(s.breach_status == 0 and s.breach_count == 0 for s in statuses)
    assert states and states[-1].mission_state == M.MISSION_STATE_PAUSED

    # a download returns the fence in force
    gcs.send("mission_request_list", 1, 1, 1)
    count = gcs.recv("MISSION_COUNT", 5.0)
    assert count is not None and count.count == 4
    items = []
    for seq in range(4):
        gcs.send("mission_request_int", 1, 1, seq, 1)
        item = gcs.recv("MISSION_ITEM_INT", 5.0)
        items.append(item)
    gcs.send("mission_ack", 1, 1, M.MAV_MISSION_ACCEPTED, 1)
    assert {i.command for i in items} == {M.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION}
    assert [(i.x, i.y) for i in items] == [tuple(int(round(c * 1e7)) for c in geo(e, n)) for e, n in WALL]
