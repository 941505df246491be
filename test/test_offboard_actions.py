"""The offboard/* actions over the whole graph in real time, judged on the sim's ground truth.

One graph (sim, perception, navigation, core, mission, offboard), one flight: refusals on the
ground, c4d_client arm + takeoff (success), takeoff while flying (rejected), goto beyond the
ceiling (rejected), follow_path empty / wrong frame (rejected), goto (success, ground truth at the
target), goto cancelled mid-way and follow_path cancelled (the vehicle holds: ground truth speed
< 0.3 m/s within 2 s), follow_path (success), c4d_client offboard streaming, land cancelled (holds in the air), land (success:
disarmed on the ground), take-off cancelled (holds low) and a last landing. The cancels go
through a plain rclpy ActionClient of the test's own node, the rest through c4d_client.
"""

from __future__ import annotations

import math
import time

import pytest
from c4d_testing import installed_executable, sample_latest, spin_for

from c4d_common.geodesy import GeoOrigin

SIM_HOME = GeoOrigin(43.5629, 1.4815, 146.0)  # src/c4d_sim/config/sim.yaml start: the ground truth's ENU origin
NODES = [("c4d_sim", "sim", []), ("c4d_gnc", "perception", []), ("c4d_gnc", "navigation", []),
         ("c4d_gnc", "core", ["--ros-args", "-p", "rt_priority:=50"]), ("c4d_mission", "mission", []),
         ("c4d_offboard", "offboard", [])]
HELD = 0.3  # [m/s] ground truth speed that counts as holding
TRUTH_TOL = 0.6  # [m] target vs ground truth: acceptance radius 0.3 + the estimator's error


@pytest.fixture(scope="module")
def flight(module_processes, ros_node, ros_domain_id):
    from nav_msgs.msg import Odometry

    from c4d_client import Vehicle

    procs = {name: module_processes.spawn(name, [installed_executable(pkg, name), *args]) for pkg, name, args in NODES}
    node, executor = ros_node
    truth = sample_latest(node, Odometry, "sim/ground_truth")
    vehicle = Vehicle(domain_id=ros_domain_id, connect_timeout=60.0)
    try:
        yield vehicle, node, executor, truth, procs, module_processes
    finally:
        vehicle.close()


class World:
    """Ground truth in the estimator's map frame (the sim's ENU origin is its own start point)."""

    def __init__(self, vehicle, truth):
        self.vehicle, self.truth = vehicle, truth
        o = vehicle.wait_ready().origin
        self.home = GeoOrigin(o.latitude, o.longitude, o.altitude)

    def position(self):
        p = self.truth.latest().pose.pose.position
        return self.home.to_enu(*SIM_HOME.to_geodetic(p.x, p.y, p.z))

    def speed(self):
        v = self.truth.latest().twist.twist.linear
        return math.sqrt(v.x ** 2 + v.y ** 2 + v.z ** 2)

    def held_within(self, seconds):
        """Seconds until the ground truth speed stays below HELD for 0.5 s, or None."""
        start, still = time.monotonic(), None
        while time.monotonic() - start < seconds + 0.5:
            if self.speed() < HELD:
                still = still or time.monotonic()
                if time.monotonic() - still >= 0.5:
                    return still - start
            else:
                still = None
            time.sleep(0.02)
        return None


def cancel_mid_way(node, executor, watch, kind, name, goal, moving):
    """Send `goal` with a plain rclpy ActionClient, cancel it once `moving()` holds, return the
    goal's final status."""
    from rclpy.action import ActionClient

    client = ActionClient(node, kind, name)
    spin = lambda s, until=None: spin_for(executor, s, until, watch)  # noqa: E731
    assert client.wait_for_server(timeout_sec=10)
    sent = client.send_goal_async(goal)
    assert spin(10, sent.done) and sent.result().accepted
    handle = sent.result()
    assert spin(30, moving), f"{name}: never started moving"
    cancel = handle.cancel_goal_async()
    assert spin(5, cancel.done) and len(cancel.result().goals_canceling) == 1
    result = handle.get_result_async()
    assert spin(10, result.done)
    client.destroy()
    return result.result()


def test_actions_success_cancel_and_rejection(flight):
    from action_msgs.msg import GoalStatus
    from nav_msgs.msg import Path

    from c4d_client import GoalRejected, make_path
    from c4d_interfaces.action import FollowPath, GoTo, Land, TakeOff
    from c4d_interfaces.msg import VehicleStatus

    v, node, executor, truth, procs, group = flight
    watch = (group, procs)
    world = World(v, truth)

    def rejected(call, *words):
        with pytest.raises(GoalRejected) as err:
            call()
        assert all(w in err.value.reason for w in words), err.value.reason

    def holding():  # the status says AUTO hold (it may trail the action's result by a message)
        return v.wait_for(lambda st: st.flight_mode == VehicleStatus.MODE_AUTO and st.nav_state == VehicleStatus.NAV_HOLD,
                          2.0)

    # on the ground: refusals with the vehicle's reason
    rejected(lambda: v.goto(5, 0, 5), "not flying")
    rejected(lambda: v.land(), "not armed")
    # take off with the client; a second take-off is refused
    v.arm()
    altitude = v.takeoff(5.0)
    assert abs(altitude - 5.0) < 0.3 and holding()
    assert abs(world.position()[2] - 5.0) < TRUTH_TOL, world.position()
    rejected(lambda: v.takeoff(5.0), "already flying")
    # goals outside the limits / malformed paths
    rejected(lambda: v.goto(10, 0, 150), "outside")  # above the vehicle's 120 m ceiling
    rejected(lambda: v.follow_path([]), "empty")
    odom = Path()
    odom.header.frame_id = "odom"
    odom.poses = make_path([(1, 1, 5)]).poses
    rejected(lambda: v.run_action("follow_path", FollowPath.Goal(path=odom), 10), "frame 'map'")
    # goto: success, then the vehicle holds at the target (AUTO hold)
    end = v.goto(8, 0, 5, speed=3.0)
    assert math.dist(end, (8, 0, 5)) < 0.3 and holding()
    assert world.held_within(3.0) is not None and math.dist(world.position(), (8, 0, 5)) < TRUTH_TOL, world.position()
    # goto cancelled mid-way: holds (speed < 0.3 m/s within 2 s), between start and target
    goal = GoTo.Goal(speed=3.0)
    goal.position.x, goal.position.y, goal.position.z = -8.0, 0.0, 5.0
    result = cancel_mid_way(node, executor, watch, GoTo, "offboard/goto", goal, lambda: world.position()[0] < 2.0)
    assert result.status == GoalStatus.STATUS_CANCELED and "cancel" in result.result.message
    settle = world.held_within(2.0)
    assert settle is not None, f"still moving {world.speed():.2f} m/s 2 s after the cancel"
    x = world.position()[0]
    assert -8.0 + 1.0 < x < 2.0 and holding(), (x, v.status)
    # follow_path cancelled: holds too
    goal = FollowPath.Goal(path=make_path([(x, 8, 5), (8, 8, 5)]), speed=3.0)
    result = cancel_mid_way(node, executor, watch, FollowPath, "offboard/follow_path", goal,
                            lambda: world.position()[1] > 3.0)
    assert result.status == GoalStatus.STATUS_CANCELED and result.result.poses_reached == 0
    assert world.held_within(2.0) is not None and holding(), f"{world.speed():.2f} m/s"
    # follow_path: success, at the last pose
    assert v.follow_path([(0, 4, 5), (4, 4, 6), (4, 0, 5)], speed=3.0) == 3
    assert world.held_within(3.0) is not None and math.dist(world.position(), (4, 0, 5)) < TRUTH_TOL, world.position()
    # offboard streaming from the client: OFFBOARD entered after the stream is live, the vehicle follows it
    with v.offboard() as ob:
        assert v.status.flight_mode == VehicleStatus.MODE_OFFBOARD
        assert ob.sent >= 50  # >= 1 s of stream at 50 Hz before the switch
        # the status at the switch may still name the core as the source (seen once): the next ones name the stream
        assert v.wait_for(lambda st: st.setpoint_source == VehicleStatus.SOURCE_OFFBOARD, 1.0), v.status
        ob.set_position(0, 4, 5)
        arrived = lambda: math.dist(world.position(), (0, 4, 5)) < TRUTH_TOL and world.speed() < HELD  # noqa: E731
        assert spin_for(executor, 15, arrived, watch), world.position()
    assert holding()
    # land cancelled: holds in the air; then land: disarmed on the ground
    result = cancel_mid_way(node, executor, watch, Land, "offboard/land", Land.Goal(), lambda: world.position()[2] < 4.0)
    assert result.status == GoalStatus.STATUS_CANCELED and holding() and v.status.armed
    assert world.held_within(2.0) is not None and world.position()[2] > 2.5, world.position()
    v.land()
    assert not v.status.armed and v.status.landed_state == VehicleStatus.LANDED_ON_GROUND
    assert world.position()[2] < 0.3, world.position()
    # take-off cancelled: holds low, then lands again
    result = cancel_mid_way(node, executor, watch, TakeOff, "offboard/takeoff", TakeOff.Goal(altitude=6.0),
                            lambda: world.position()[2] > 1.5)
    assert result.status == GoalStatus.STATUS_CANCELED and holding()
    assert world.held_within(2.0) is not None and 1.5 < world.position()[2] < 4.0, world.position()
    v.land()
    assert not v.status.armed
