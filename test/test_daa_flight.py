"""Detect-and-avoid and geofence preservation over the whole graph (issue 18): sim with a world and its
lidar, perception (clusters, tracks), navigation, core (the barrier), mission (plan, geofence/set).
Judged on the sim's truth: sim/ground_truth against sim/obstacles.

1. A plan whose only leg runs through two pillars (the planner is not told): the mission completes and
   the true clearance to every pillar's surface stays >= the protection radius (0.5 m) — what the core
   saw came from the real lidar through perception.
2. A fence set in flight with geofence/set (east edge 8 m ahead), then an 8 m/s velocity push at it in
   OFFBOARD (this test plays the offboard gateway on guidance/offboard): the true position never
   crosses the edge.
Prints the figures and the core's executor overruns over the run.
"""

from __future__ import annotations

import functools
import math

import pytest
from c4d_testing import call_service, installed_executable, sample_latest, spin_for, upload_plan

from c4d_common.geodesy import GeoOrigin

SIM_HOME = GeoOrigin(43.5629, 1.4815, 146.0)  # start of config/sim.yaml
R = 0.5
WORLD = """name: daa_test
cylinders:
  - {center: [8.0, 0.3], radius: 0.5, height: 15.0}
  - {center: [14.0, -0.4], radius: 0.6, height: 15.0}
"""


@pytest.fixture(scope="module")
def graph(module_processes, ros_node, tmp_path_factory):
    world = tmp_path_factory.mktemp("world") / "world.yaml"
    world.write_text(WORLD)
    nodes = [("c4d_sim", "sim", ["--ros-args", "-p", f"world:={world}"]), ("c4d_gnc", "perception", []),
             ("c4d_gnc", "navigation", []), ("c4d_gnc", "core", ["--ros-args", "-p", "rt_priority:=50"]),
             ("c4d_mission", "mission", [])]
    spawn = module_processes.spawn
    return (*ros_node, {name: spawn(name, [installed_executable(pkg, name), *args]) for pkg, name, args in nodes},
            module_processes)


def test_mission_through_pillars_then_fence_push(graph):
    from nav_msgs.msg import Odometry
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    node, executor, procs, group = graph
    from c4d_common.plan import Geofence, Item, Plan
    from c4d_interfaces.msg import ExecutorStats, GuidanceSetpoint, MissionState, Surroundings, VehicleState
    from c4d_interfaces.srv import MissionControl, SetGeofence, UploadMission, VehicleCommand
    from c4d_ros.plan_msgs import geofence_to_msg, plan_to_msg

    best = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    rec = {"truth": None, "obstacles": None, "mission": None, "clearance": math.inf, "overruns": []}

    def on_truth(m):
        p = m.pose.pose.position
        rec["truth"] = (p.x, p.y, p.z)
        if rec["obstacles"] and p.z > 1.0:
            for o in rec["obstacles"].obstacles:
                d = math.hypot(p.x - o.position.x, p.y - o.position.y) - o.radius
                rec["clearance"] = min(rec["clearance"], d)

    node.create_subscription(Odometry, "sim/ground_truth", on_truth, best)
    node.create_subscription(Surroundings, "sim/obstacles", lambda m: rec.__setitem__("obstacles", m), best)
    node.create_subscription(MissionState, "mission/state", lambda m: rec.__setitem__("mission", m), latched)
    node.create_subscription(ExecutorStats, "gnc/executor_stats", lambda m: rec["overruns"].append(m.overruns_total),
                             QoSProfile(depth=5, reliability=ReliabilityPolicy.RELIABLE))
    state = sample_latest(node, VehicleState, "navigation/state")
    spin = functools.partial(spin_for, executor, watch=(group, procs))
    call = functools.partial(call_service, spin)
    upload = node.create_client(UploadMission, "mission/upload")
    control = node.create_client(MissionControl, "mission/control")
    set_fence = node.create_client(SetGeofence, "geofence/set")
    core = node.create_client(VehicleCommand, "gnc/command")

    ready = VehicleState.VALID_ORIGIN | VehicleState.VALID_POSITION_XY
    assert spin(40, lambda: state.latest() is not None and state.latest().valid & ready == ready)
    origin = state.latest().origin
    home = GeoOrigin(origin.latitude, origin.longitude, origin.altitude)

    # 1. the leg (0, 0) -> (22, 0) at 5 m runs through both pillars; the plan ends in the air
    plan = Plan((Item("takeoff", z=5.0), Item("waypoint", x=22.0, y=0.0, z=5.0, acceptance_radius=1.0)), cruise_speed=3.0)
    reply = upload_plan(spin, upload, UploadMission.Request(plan=plan_to_msg(plan)))
    assert reply.accepted, reply.errors
    start = call(control, MissionControl.Request(action=MissionControl.Request.ACTION_START))
    assert start.result == MissionControl.Response.RESULT_ACCEPTED, start.message
    assert spin(60, lambda: rec["mission"] is not None and rec["mission"].state == MissionState.STATE_COMPLETED), \
        (rec["mission"], rec["truth"], group.log_of(procs["core"])[-1500:])
    assert rec["obstacles"] is not None and len(rec["obstacles"].obstacles) == 2
    assert rec["clearance"] >= R, rec["clearance"]
    assert rec["clearance"] < 2.0, rec["clearance"]  # the leg did pass the pillars closely: the barrier worked
    mission_clearance = rec["clearance"]

    # 2. a fence set in flight, east edge 8 m ahead of the vehicle; an 8 m/s push east at it
    def geo(e, n):
        lat, lon, _ = home.to_geodetic(e, n, 0.0)
        return (lat, lon)

    edge = 30.0
    fence = Geofence(polygon=(geo(-30.0, -30.0), geo(edge, -30.0), geo(edge, 30.0), geo(-30.0, 30.0)), max_altitude=20.0)
    answer = call(set_fence, SetGeofence.Request(fence=geofence_to_msg(fence)))
    assert answer.result == SetGeofence.Response.RESULT_ACCEPTED, answer.message
    spin(1.0)  # geofence/active reaches the core

    def push():
        sp = GuidanceSetpoint(control_level=GuidanceSetpoint.LEVEL_VELOCITY)
        sp.header.stamp = node.get_clock().now().to_msg()
        sp.header.frame_id = "map"
        sp.position.x = sp.position.y = sp.position.z = math.nan
        sp.velocity.x, sp.velocity.y, sp.velocity.z = 8.0, 0.0, 0.0
        sp.acceleration.x = sp.acceleration.y = sp.acceleration.z = math.nan
        sp.yaw = sp.yaw_rate = sp.thrust = math.nan
        sp.max_horizontal_speed = sp.max_vertical_speed = math.nan
        publisher.publish(sp)

    publisher = node.create_publisher(GuidanceSetpoint, "guidance/offboard", 10)
    timer = node.create_timer(0.02, push)
    spin(1.5)  # a live stream before OFFBOARD
    worst = {"x": -math.inf}

    def track():
        x = home.to_enu(*SIM_HOME.to_geodetic(*rec["truth"]))[0]  # truth in the estimator's (the fence's) frame
        worst["x"] = max(worst["x"], x)
        return False

    mode = call(core, VehicleCommand.Request(command=VehicleCommand.Request.CMD_SET_MODE, mode=6))
    assert mode.result == VehicleCommand.Response.RESULT_ACCEPTED, mode.message
    end = node.get_clock().now().nanoseconds + 8e9
    while node.get_clock().now().nanoseconds < end:
        spin(0.05)
        track()
    node.destroy_timer(timer)
    call(core, VehicleCommand.Request(command=VehicleCommand.Request.CMD_HOLD))
    assert worst["x"] < edge, worst
    assert worst["x"] > edge - 3.0, worst  # it did go to the fence
    overruns = rec["overruns"][-1] - rec["overruns"][0] if rec["overruns"] else -1
    print(f"\nDAA: mission through 2 pillars, min true clearance {mission_clearance:.2f} m (r = {R} m); fence push at "
          f"8 m/s: closest {edge - worst['x']:.2f} m inside the edge; core overruns during the run: {overruns}")
