"""MAVLink geofence without ROS (issue 18): fence items from pymavlink-encoded MISSION_ITEM_INT
frames through the mission microservice to a c4d Geofence (and back for downloads), refusals with
the MISSION_ACK type and the reason, FENCE_STATUS breach tracking, OBSTACLE_DISTANCE sectors."""

from __future__ import annotations

import math

import pytest

from c4d_bridge_mavlink.encoders import Snapshot, fence_status, obstacle_distances
from c4d_bridge_mavlink.fence import (
    FenceItemsError,
    FenceWatch,
    geofence_from_items,
    items_from_geofence,
    sector_distances,
)
from c4d_bridge_mavlink.mission_protocol import FENCE, MissionServer, WireItem
from c4d_bridge_mavlink.signing import mavlink as M
from c4d_common import quat
from c4d_common.geodesy import GeoOrigin
from c4d_common.plan import Geofence

GCS = M.MAVLink(None, 255, 190)
VEHICLE = M.MAVLink(None, 1, 1)
HOME = GeoOrigin(43.5629, 1.4815, 146.0)


def wire(msg):
    """`msg` packed by the GCS and decoded by the vehicle, as on the link."""
    return VEHICLE.decode(bytearray(msg.pack(GCS)))


def geo(east: float, north: float) -> tuple[float, float]:
    lat, lon, _ = HOME.to_geodetic(east, north, 0.0)
    return lat, lon


def fence_item(seq: int, command: int, param1: float, east: float, north: float, frame=M.MAV_FRAME_GLOBAL_INT):
    lat, lon = geo(east, north)
    return M.MAVLink_mission_item_int_message(1, 1, seq, frame, command, 0, 1, param1, 0, 0, 0, int(round(lat * 1e7)),
                                              int(round(lon * 1e7)), 0.0, FENCE)


def upload(items) -> tuple[list, list]:
    """A GCS's FENCE upload through the real MissionServer: (frames sent to the GCS, items handed on)."""
    out, handed = [], []
    server = MissionServer(out.append, on_upload=lambda t, got: handed.append((t, got)),
                           on_clear=lambda t: M.MAV_MISSION_ACCEPTED, on_set_current=lambda s: True)
    server.handle(wire(M.MAVLink_mission_count_message(1, 1, len(items), FENCE)), 0.0)
    for item in items:
        server.handle(wire(item), 0.0)
    return out, handed


def flat(points) -> list[float]:
    return [c for p in points for c in p]


V, X = M.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION, M.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION
CI, CX = M.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION, M.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION
SQUARE = [(-60, -60), (60, -60), (60, 60), (-60, 60)]
WALL = [(20, -10), (25, -10), (25, 10), (20, 10)]


def test_inclusion_exclusion_polygons_and_circle_through_the_protocol():
    items = [fence_item(k, V, 4, e, n) for k, (e, n) in enumerate(SQUARE)]
    items += [fence_item(4 + k, X, 4, e, n) for k, (e, n) in enumerate(WALL)]
    items += [fence_item(8, CX, 4.5, 0, 30), fence_item(9, M.MAV_CMD_NAV_FENCE_RETURN_POINT, 0, 0, 0)]
    out, handed = upload(items)
    assert [m.get_type() for m in out] == ["MISSION_REQUEST_INT"] * 10 and handed[0][0] == FENCE
    fence = geofence_from_items(handed[0][1], 25.0, 100.0)
    assert (fence.max_altitude, fence.max_distance) == (25.0, 100.0)
    assert flat(fence.polygon) == pytest.approx(flat(geo(e, n) for e, n in SQUARE), abs=1e-7)
    assert flat(fence.exclusion_polygons[0]) == pytest.approx(flat(geo(e, n) for e, n in WALL), abs=1e-7)
    assert fence.exclusion_circles[0] == pytest.approx((*geo(0, 30), 4.5), abs=1e-7)
    # a download returns the same polygons and circle
    back = geofence_from_items(items_from_geofence(fence), 25.0, 100.0)
    assert back == fence


@pytest.mark.parametrize("items, result, reason", [
    ([(CI, 50, 0, 0)], M.MAV_MISSION_UNSUPPORTED, "inclusion circles are not supported"),
    ([(CX, 0, 0, 0)], M.MAV_MISSION_INVALID_PARAM1, "circle radius must be > 0 m"),
    ([(X, 2, 0, 0), (X, 2, 1, 0)], M.MAV_MISSION_INVALID_PARAM1, "a polygon needs >= 3 vertices"),
    ([(X, 4, 0, 0), (X, 4, 1, 0), (X, 4, 1, 1)], M.MAV_MISSION_INVALID, "not 4 consecutive items"),
    ([(X, 3, 0, 0), (V, 3, 1, 0), (X, 3, 1, 1)], M.MAV_MISSION_INVALID, "not 3 consecutive items"),
    ([(V, 3, 0, 0), (V, 3, 1, 0), (V, 3, 1, 1), (V, 3, 5, 0), (V, 3, 6, 0), (V, 3, 6, 1)], M.MAV_MISSION_UNSUPPORTED,
     "a second inclusion polygon"),
    ([(M.MAV_CMD_NAV_WAYPOINT, 0, 0, 0)], M.MAV_MISSION_UNSUPPORTED, "is not a fence item"),
])
def test_malformed_fences_name_the_item_and_the_ack_type(items, result, reason):
    wired = [wire(fence_item(k, c, p, e, n)) for k, (c, p, e, n) in enumerate(items)]
    _, handed = upload(wired)
    with pytest.raises(FenceItemsError, match=reason) as err:
        geofence_from_items(handed[0][1])
    assert err.value.result == result


def test_local_frame_and_out_of_range_vertices_are_refused():
    with pytest.raises(FenceItemsError, match="not a global frame"):
        geofence_from_items([WireItem(CX, M.MAV_FRAME_LOCAL_NED, (5.0, 0, 0, 0, 1.0, 2.0, 0.0))])
    with pytest.raises(FenceItemsError, match="out of range"):
        geofence_from_items([WireItem(CX, M.MAV_FRAME_GLOBAL_INT, (5.0, 0, 0, 0, 95.0, 2.0, 0.0))])
    assert geofence_from_items([]) == Geofence()  # an empty upload clears


def test_fence_status_counts_breaches_on_entry_and_types_them():
    watch = FenceWatch()
    assert watch.message(0.0) is None  # no fence in force: not sent
    wall = tuple(geo(e, n) for e, n in WALL)
    watch.set_fence(Geofence(max_altitude=20.0, exclusion_polygons=(wall,), min_altitude=3.0), HOME)
    watch.update((0.0, 0.0, 5.0), True, 10.0)
    msg = watch.message(0.0)
    assert (msg.breach_status, msg.breach_count, msg.breach_type) == (0, 0, M.FENCE_BREACH_NONE)
    for t, p in ((11.0, (22.0, 0.0, 5.0)), (11.1, (23.0, 0.0, 5.0)), (12.0, (30.0, 0.0, 5.0)), (13.0, (30.0, 0.0, 25.0))):
        watch.update(p, True, t)
    msg = wire(watch.message(1.0))
    assert (msg.breach_status, msg.breach_count, msg.breach_type, msg.breach_time) == (1, 2, M.FENCE_BREACH_MAXALT, 12000)
    assert msg.breach_mitigation == M.FENCE_MITIGATE_VEL_LIMIT
    watch.update((0.0, 0.0, 2.0), True, 14.0)  # from the ceiling straight to the floor: the same breach
    assert (watch.breached, watch.breach_type, watch.count) == (True, M.FENCE_BREACH_MINALT, 2)
    watch.update((0.0, 0.0, 2.0), False, 15.0)  # landing: the floor does not apply
    assert not watch.breached and watch.count == 2
    watch.update((0.0, 0.0, 2.0), True, 16.0)
    assert watch.count == 3 and watch.last_breach_s == 16.0
    watch.set_fence(Geofence(), HOME)  # cleared
    assert watch.message(0.0) is None and not watch.breached


def test_obstacle_sectors_are_relative_to_the_heading_in_frd():
    east_facing, north_facing = 0.0, math.pi / 2  # ENU yaw
    ahead = sector_distances((0.0, 0.0), east_facing, ((5.0, 0.0, 0.5),))
    assert ahead[0] == 450 and ahead[1] == 450 and ahead[71] == 450  # ±5.7° wide, ±2.5° sectors
    assert ahead[2] == 3001 and ahead[36] == 3001  # nothing else: max_distance + 1
    right = sector_distances((0.0, 0.0), north_facing, ((5.0, 0.0, 0.5),))  # facing north, obstacle east = right
    assert right[18] == 450 and right[0] == 3001 and right[54] == 3001
    behind_left = sector_distances((10.0, 10.0), east_facing, ((7.0, 13.0, 0.2),))  # north-west: 225° clockwise
    assert min(behind_left) == behind_left[45] == int(round((math.hypot(3, 3) - 0.2) * 100))
    assert sector_distances((0.0, 0.0), 0.0, ((40.0, 0.0, 1.0),)) == [3001] * 72  # beyond range
    inside = sector_distances((0.0, 0.0), 0.0, ((0.2, 0.0, 0.5),))
    assert inside == [10] * 72  # inside its circle: every sector at min_distance


def test_obstacle_distance_message_from_the_snapshot():
    s = Snapshot(boot_s=0.0, valid_position=True, position=(0.0, 0.0, 5.0), orientation=quat.from_euler(0, 0, 0.0),
                 obstacles=((3.0, 0.0, 0.5),), obstacles_t=10.0)
    msg = wire(obstacle_distances(s, 10.5))
    assert msg.frame == M.MAV_FRAME_BODY_FRD and msg.increment == 5 and msg.increment_f == 5.0
    assert (msg.min_distance, msg.max_distance) == (10, 3000) and len(msg.distances) == 72
    assert msg.distances[0] == 250 and msg.distances[36] == 3001
    assert obstacle_distances(s, 11.5) is None  # scans stopped: stale
    assert obstacle_distances(Snapshot(), 0.0) is None
    assert fence_status(Snapshot(), 0.0) is None
