"""The perception node's surroundings glue, in-process on a private domain (no sim): a ray-cast
LaserScan and a navigation/state pose in, perception/surroundings and perception/markers out.

Checks what only the glue can get wrong: the pose taken from the sampled state (yaw and
position: the obstacle lands at its map position, not at its base_link one), the scan's stamp and
`map` frame, the DELETEALL that clears stale markers, no obstacles without a valid pose, the
wind-only Surroundings when the scans stop, and the one-line errors of bad parameters."""

from __future__ import annotations

import math

import pytest
from c4d_testing import spin_for
from scan_cast import ANGLE_MIN, INC, RANGE_MAX, RANGE_MIN, cast
from sensor_msgs.msg import LaserScan
from visualization_msgs.msg import Marker, MarkerArray

from c4d_common import quat
from c4d_gnc import perception_surroundings as ps
from c4d_interfaces.msg import Surroundings, VehicleState
from c4d_ros.manifest import MARKERS, NAV_STATE, SCAN, SURROUNDINGS
from c4d_ros.params import ParameterError, declare_all
from c4d_ros.stamps import s_to_stamp

POSE = (12.0, -4.0, 3.0, 1.2)  # x, y, z, yaw
POSTS = [(17.0, -1.0, 0.5), (8.0, -9.0, 0.3)]  # map


@pytest.fixture(scope="module")
def rig(ros_node):
    import rclpy

    node, executor = ros_node
    perception = rclpy.create_node("perception", context=node.context,
                                   parameter_overrides=[rclpy.parameter.Parameter("scan_timeout_s", value=0.3)])
    side = rclpy.create_node("_perception_samples", context=node.context)
    values = declare_all(perception, ps.PARAMS)
    around = ps.SurroundingsNode(perception, side, values, ps.airframe_of(values["airframe"]))
    executor.add_node(perception)
    got: dict[str, list] = {"s": [], "m": []}
    node.create_subscription(Surroundings, SURROUNDINGS.name, got["s"].append, SURROUNDINGS.qos)
    node.create_subscription(MarkerArray, MARKERS.name, got["m"].append, MARKERS.qos)
    pubs = (node.create_publisher(LaserScan, SCAN.name, SCAN.qos),
            node.create_publisher(VehicleState, NAV_STATE.name, NAV_STATE.qos))
    yield node, executor, pubs, got, around
    executor.remove_node(perception)
    perception.destroy_node()
    side.destroy_node()


def state(valid: int) -> VehicleState:
    x, y, z, yaw = POSE
    s = VehicleState(valid=valid)
    s.position.x, s.position.y, s.position.z = x, y, z
    w, qx, qy, qz = quat.from_euler(0.0, 0.0, yaw)
    s.orientation.w, s.orientation.x, s.orientation.y, s.orientation.z = w, qx, qy, qz
    return s


def scan(t: float) -> LaserScan:
    x, y, _, yaw = POSE
    msg = LaserScan(angle_min=ANGLE_MIN, angle_max=ANGLE_MIN + INC * 719, angle_increment=INC, range_min=RANGE_MIN,
                    range_max=RANGE_MAX)
    msg.header.stamp = s_to_stamp(t)
    msg.header.frame_id = "base_link"
    msg.ranges = cast(x, y, yaw, POSTS, noise=0.01, seed=int(t * 10)).tolist()
    return msg


def feed(rig, valid: int, t0: float, count: int) -> None:
    node, executor, (pub_scan, pub_state), got, _ = rig
    for k in range(count):
        pub_state.publish(state(valid))
        spin_for(executor, 0.02)
        pub_scan.publish(scan(t0 + 0.05 * k))
        spin_for(executor, 0.05)


def test_obstacles_in_map_with_the_estimated_pose(rig):
    node, executor, pubs, got, _ = rig
    assert spin_for(executor, 10.0, lambda: node.count_subscribers(SCAN.name) > 0
                    and node.count_publishers(SURROUNDINGS.name) > 0)
    feed(rig, ps.POSE_BITS | VehicleState.VALID_POSITION_Z, 100.0, 12)
    assert spin_for(executor, 3.0, lambda: any(m.obstacles for m in got["s"]))
    last = [m for m in got["s"] if m.header.stamp.sec >= 100][-1]
    assert last.header.frame_id == "map"
    assert len(last.obstacles) == 2, last.obstacles
    for cx, cy, r in POSTS:
        o = min(last.obstacles, key=lambda o: math.hypot(o.position.x - cx, o.position.y - cy))
        assert math.hypot(o.position.x - cx, o.position.y - cy) < 0.1 and abs(o.radius - r) < 0.05
        assert o.position.z == pytest.approx(POSE[2]) and math.isnan(o.height) and o.age > 0.0
    assert spin_for(executor, 2.0, lambda: got["m"])
    markers = got["m"][-1].markers
    assert markers[0].action == Marker.DELETEALL
    cylinders = [m for m in markers if m.type == Marker.CYLINDER]
    assert sorted(m.id for m in cylinders) == sorted(o.id for o in last.obstacles)


def test_no_pose_no_obstacles_and_wind_only_without_scans(rig):
    node, executor, pubs, got, around = rig
    got["s"].clear()
    feed(rig, VehicleState.VALID_POSITION_XY, 200.0, 4)  # no heading: the scan cannot be placed
    spin_for(executor, 0.2)
    from_scans = [m for m in got["s"] if m.header.stamp.sec >= 200]
    assert from_scans and all(not m.obstacles for m in from_scans)
    assert around.tracker.tracks == []
    got["s"].clear()
    spin_for(executor, 1.5)  # no scans: the wind timer publishes (10 Hz) after scan_timeout_s
    assert len(got["s"]) >= 8 and all(not m.obstacles and not m.wind_valid for m in got["s"])


def test_bad_parameters_one_line(ros_node):
    import rclpy

    node, _ = ros_node
    with pytest.raises(ParameterError, match="parameter 'airframe': no bundled airframe named 'nope'"):
        ps.airframe_of("nope")
    bad = rclpy.create_node("perception_bad", context=node.context,
                            parameter_overrides=[rclpy.parameter.Parameter("track_gate_m", value=0.0)])
    try:
        with pytest.raises(ParameterError, match="track_gate_m"):
            declare_all(bad, ps.PARAMS)
    finally:
        bad.destroy_node()
