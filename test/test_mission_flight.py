"""Mission over the whole graph in real time: upload (bad plans rejected, active plan kept),
wrong-state commands refused, then the example survey flown to completion and landed."""

from __future__ import annotations

import functools
import json
import math
from pathlib import Path

import pytest
from c4d_testing import call_service, installed_executable, sample_latest, spin_for, upload_plan

from c4d_common.geodesy import GeoOrigin

ROOT = Path(__file__).resolve().parent.parent
SIM_HOME = GeoOrigin(43.5629, 1.4815, 146.0)
NODES = [("c4d_sim", "sim", []), ("c4d_gnc", "perception", []), ("c4d_gnc", "navigation", []),
         ("c4d_gnc", "core", ["--ros-args", "-p", "rt_priority:=50"]), ("c4d_mission", "mission", []),
         ("c4d_mission", "payload", ["--ros-args", "-p", "output_dir:={captures}"])]


@pytest.fixture(scope="module")
def graph(module_processes, ros_node, tmp_path_factory):
    captures = tmp_path_factory.mktemp("captures")
    procs = {name: module_processes.spawn(name, [installed_executable(pkg, name),
                                                 *[a.format(captures=captures) for a in args]])
             for pkg, name, args in NODES}
    procs["captures_dir"] = captures
    return (*ros_node, procs, module_processes)


def test_survey_mission(graph):
    from nav_msgs.msg import Odometry
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    from c4d_common.plan import plan_from_yaml_text
    from c4d_common.plan_files import load_plan
    from c4d_common.plan_validation import local_point
    from c4d_interfaces.msg import CaptureEvent, MissionState, VehicleState, VehicleStatus
    from c4d_interfaces.srv import DownloadMission, MissionControl, UploadMission, VehicleCommand
    from c4d_ros.plan_msgs import plan_to_msg

    node, executor, procs, group = graph
    captures_dir = procs.pop("captures_dir")
    best = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    world = {"truth": None, "status": None, "mission": None, "reached": {}}

    def on_mission(m):
        world["mission"] = m
        if m.last_reached_item >= 0 and m.last_reached_item not in world["reached"] and world["truth"] is not None:
            world["reached"][m.last_reached_item] = world["truth"]

    node.create_subscription(Odometry, "sim/ground_truth",
                             lambda m: world.__setitem__("truth", (m.pose.pose.position.x, m.pose.pose.position.y,
                                                                   m.pose.pose.position.z)), best)
    state = sample_latest(node, VehicleState, "navigation/state")
    node.create_subscription(VehicleStatus, "vehicle/status", lambda m: world.__setitem__("status", m), latched)
    node.create_subscription(MissionState, "mission/state", on_mission, latched)
    captured: list = []
    node.create_subscription(CaptureEvent, "payload/captures", captured.append,
                             QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE))
    clients = {name: node.create_client(t, f"mission/{name}") for name, t in
               (("upload", UploadMission), ("download", DownloadMission), ("control", MissionControl))}
    vehicle = node.create_client(VehicleCommand, "vehicle/command")

    spin = functools.partial(spin_for, executor, watch=(group, procs))

    call = functools.partial(call_service, spin)

    ready = VehicleState.VALID_ORIGIN | VehicleState.VALID_POSITION_XY
    assert spin(40, lambda: state.latest() is not None and state.latest().valid & ready == ready)
    survey = load_plan(ROOT / "missions" / "survey.yaml")
    outside = plan_from_yaml_text((ROOT / "missions" / "survey.yaml").read_text().replace("east: 20, north: 20",
                                                                                          "east: 300, north: 20"))
    # bad plan, nothing loaded: rejected with the reason; start without a plan: refused
    reply = upload_plan(spin, clients["upload"], UploadMission.Request(plan=plan_to_msg(outside)))
    assert not reply.accepted and any(e.startswith("item 5: outside the geofence polygon") for e in reply.errors)
    assert not call(clients["download"], DownloadMission.Request()).has_plan
    reply = call(clients["control"], MissionControl.Request(action=MissionControl.Request.ACTION_START))
    assert reply.result == MissionControl.Response.RESULT_DENIED and "no plan" in reply.message
    # good plan accepted; a later bad upload leaves it in place
    reply = call(clients["upload"], UploadMission.Request(plan=plan_to_msg(survey)))
    assert reply.accepted and reply.plan_id > 0, reply.errors
    assert not call(clients["upload"], UploadMission.Request(plan=plan_to_msg(outside))).accepted
    kept = call(clients["download"], DownloadMission.Request())
    assert kept.has_plan and kept.plan.plan_id == reply.plan_id and len(kept.plan.items) == len(survey.items)
    # commands in the wrong state are refused with a result code
    land = call(vehicle, VehicleCommand.Request(command=VehicleCommand.Request.CMD_LAND))
    assert land.result == VehicleCommand.Response.RESULT_DENIED and "not armed" in land.message
    pause = call(clients["control"], MissionControl.Request(action=MissionControl.Request.ACTION_PAUSE))
    assert pause.result == MissionControl.Response.RESULT_DENIED
    # fly it
    start = call(clients["control"], MissionControl.Request(action=MissionControl.Request.ACTION_START))
    assert start.result == MissionControl.Response.RESULT_ACCEPTED, start.message
    assert spin(180, lambda: world["mission"] is not None and world["mission"].state == MissionState.STATE_COMPLETED), \
        (world["mission"], group.log_of(procs["mission"])[-2000:])
    assert spin(10, lambda: world["status"] is not None and not world["status"].armed)
    origin = state.latest().origin
    home = GeoOrigin(origin.latitude, origin.longitude, origin.altitude)
    misses = []
    for k, item in enumerate(survey.items):
        if item.type != "waypoint":
            continue
        assert k in world["reached"], f"waypoint {k} never reported reached"
        truth = home.to_enu(*SIM_HOME.to_geodetic(*world["reached"][k]))  # ground truth in the mission frame
        miss = math.dist(truth, local_point(item, home))
        misses.append(miss)
        assert miss <= item.acceptance_radius + 0.3, (k, miss)  # + the estimator's error (~0.15 m RMS)
    # camera every 5 m along the planned legs (88 m): 17 geotagged captures within 1 m of their planned spot
    path = [(0.0, 0.0)] + [local_point(i, home)[:2] for i in survey.items if i.type == "waypoint"]
    capture_misses = []
    for k, c in enumerate(captured):
        s, planned = 5.0 * (k + 1), None
        for a, b in zip(path, path[1:], strict=False):
            if s <= math.dist(a, b):
                planned = (a[0] + (b[0] - a[0]) * s / math.dist(a, b), a[1] + (b[1] - a[1]) * s / math.dist(a, b))
                break
            s -= math.dist(a, b)
        capture_misses.append(math.dist((c.position.x, c.position.y), planned))
    assert len(captured) == 17 and max(capture_misses) <= 1.0, capture_misses
    files = sorted(captures_dir.glob("captures_*.csv"))
    assert len(files) == 1 and len(files[0].read_text().splitlines()) == 1 + 17
    geojson = json.loads(files[0].with_suffix(".geojson").read_text())
    assert len(geojson["features"]) == 17 and geojson["features"][0]["geometry"]["type"] == "Point"
    print(f"\nsurvey: {len(misses)} waypoints, true distance at 'reached' max {max(misses):.2f} m; "
          f"{len(captured)} captures, max {max(capture_misses):.2f} m from plan")
    assert world["truth"][2] < 0.05
