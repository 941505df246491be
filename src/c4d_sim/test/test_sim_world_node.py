"""The sim node's world glue, in-process on a private domain: the scan and sim/obstacles tasks run by
hand (no executive, no real-time loop) and their messages received over DDS; the world and lidar
parameters' errors; a bad world file ends the sim process with one line and exit 2.

Checks what only the glue can get wrong: LaserScan geometry fields and frame, ranges equal to the
lidar model's at the vehicle's true pose (heading included), REP-117 infinities surviving the
message, the truth message's ids / positions / mover velocity / wind, and silence without a world."""

from __future__ import annotations

import math
import subprocess

import numpy as np
import pytest
from c4d_testing import installed_executable, spin_for
from sensor_msgs.msg import LaserScan

from c4d_common import quat
from c4d_interfaces.msg import Surroundings
from c4d_ros.manifest import SCAN, SIM_OBSTACLES
from c4d_ros.params import ParameterError
from c4d_sim.lidar import LidarConfig
from c4d_sim.sim_config import default_sim_config, load_sim_config
from c4d_sim.sim_node import SimNode, read_world
from c4d_sim.world import Cylinder, Mover, WindField, World

WORLD = World(cylinders=(Cylinder(6.0, 0.0, 1.0, 10.0),),
              movers=(Mover(((0.0, -8.0), (0.0, 8.0)), 2.0, 0.5, 10.0, back_and_forth=True),),
              wind=WindField((3.0, -1.0, 0.0)))


@pytest.fixture(scope="module")
def rig(ros_node):
    import rclpy

    node, executor = ros_node
    got: dict[str, list] = {"scan": [], "obs": []}
    node.create_subscription(LaserScan, SCAN.name, got["scan"].append, SCAN.qos)
    node.create_subscription(Surroundings, SIM_OBSTACLES.name, got["obs"].append, SIM_OBSTACLES.qos)
    sim_node = rclpy.create_node("sim", context=node.context)
    sim = SimNode(sim_node, load_sim_config(default_sim_config()), 0, WORLD, LidarConfig(beams=8, noise=0.0))
    yield node, executor, sim, got
    sim.node.destroy_node()


def test_without_a_world_both_topics_exist_and_no_task_feeds_them(ros_node):
    import rclpy

    node, executor = ros_node
    before = node.count_publishers(SCAN.name), node.count_publishers(SIM_OBSTACLES.name)
    bare_node = rclpy.create_node("sim_without_world", context=node.context)
    try:
        bare = SimNode(bare_node, load_sim_config(default_sim_config()))
        assert spin_for(executor, 5.0, until=lambda: node.count_publishers(SCAN.name) == before[0] + 1
                        and node.count_publishers(SIM_OBSTACLES.name) == before[1] + 1)  # the graph matches the manifest
        assert bare.lidar is None and not {"scan", "obstacles"} & set(bare.executive.functions)
    finally:
        bare_node.destroy_node()


def test_scan_message_matches_the_lidar_at_the_true_pose(rig):
    node, executor, sim, got = rig
    state = sim.plant.state
    state.position, state.orientation, state.t = (0.0, 0.0, 2.0), quat.from_euler(0.0, 0.0, math.pi / 2), 0.0
    spin_for(executor, 1.0, until=lambda: node.count_publishers(SCAN.name) > 0)
    sim.scan(0)
    assert spin_for(executor, 5.0, until=lambda: got["scan"])
    m = got["scan"][-1]
    assert m.header.frame_id == "base_link" and m.angle_min == pytest.approx(-math.pi)
    assert m.angle_increment == pytest.approx(math.pi / 4) and m.angle_max == pytest.approx(3 * math.pi / 4)
    assert (m.range_min, m.range_max) == pytest.approx((0.1, 30.0)) and len(m.ranges) == 8
    r = np.array(m.ranges)
    # heading north: the pillar (east, 5 m to its surface) is on the right (beam 2, -90°), the mover
    # (at (0, -8) at t = 0, 7.5 m to its surface) behind (beam 0, -180°); nothing else: +inf
    assert r[2] == pytest.approx(5.0, abs=1e-4) and r[0] == pytest.approx(7.5, abs=1e-4)
    assert np.isposinf(r[[1, 3, 4, 5, 6, 7]]).all()


def test_truth_message_lists_obstacles_and_wind(rig):
    node, executor, sim, got = rig
    sim.plant.state.t = 5.0  # the mover went 10 m: 2 m north of the origin, coming back
    sim.plant.wind = WORLD.wind.at(5.0)
    sim.obstacles(0)
    assert spin_for(executor, 5.0, until=lambda: got["obs"])
    m = got["obs"][-1]
    assert m.header.frame_id == "map" and [o.id for o in m.obstacles] == [1, 2]
    pillar, mover = m.obstacles
    assert (pillar.position.x, pillar.position.y, pillar.position.z, pillar.radius) == pytest.approx((6.0, 0.0, 5.0, 1.0))
    assert (mover.position.x, mover.position.y) == pytest.approx((0.0, 2.0))
    assert (mover.velocity.x, mover.velocity.y) == pytest.approx((0.0, 2.0))
    assert pillar.confidence == 1.0 and pillar.age == pytest.approx(5.0)
    assert (m.wind.x, m.wind.y, m.wind.z) == pytest.approx((3.0, -1.0, 0.0)) and m.wind_valid


def test_world_parameters_refuse_bad_values(ros_node):
    import rclpy
    from rclpy.parameter import Parameter

    node, _ = ros_node
    for name, value, message in (("scan_rate_hz", 25.0, "scan_rate_hz"), ("scan_beams", 2, "scan_beams"),
                                 ("scan_noise_m", -0.1, "scan_noise_m")):
        bad = rclpy.create_node(f"sim_bad_{name}", context=node.context, parameter_overrides=[Parameter(name, value=value)])
        try:
            with pytest.raises(ParameterError, match=message):
                read_world(bad)
        finally:
            bad.destroy_node()


@pytest.mark.parametrize("params, error", [
    (["world:=/nonexistent/world.yaml"], "sim: error: cannot read world /nonexistent/world.yaml: No such file or directory"),
    (["world:={bad}"], "sim: error: world: field 'movers[0].mode' must be 'loop' or 'back_and_forth', got 'pingpong'"),
    (["world:={good}", "scan_rate_hz:=15.0"],
     "sim: error: parameter 'scan_rate_hz': 15 Hz does not divide the physics rate 1000 Hz (10, 12.5, 20 do)"),
])
def test_bad_world_exits_2_with_one_line(tmp_path, ros_env, params, error):
    bad, good = tmp_path / "bad.yaml", tmp_path / "good.yaml"
    bad.write_text("movers:\n  - {path: [[0, 0], [1, 0]], speed: 1, radius: 1, height: 2, mode: pingpong}\n")
    good.write_text("cylinders:\n  - {center: [5, 0], radius: 1, height: 3}\n")
    args = [a for p in params for a in ("-p", p.format(bad=bad, good=good))]
    done = subprocess.run([installed_executable("c4d_sim", "sim"), "--ros-args", *args], env=ros_env,
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 2, done.stderr
    assert [line for line in done.stderr.splitlines() if line.strip()] == [error]
