"""Whole graph (sim with a world, perception, navigation, core): what perception says is around the
vehicle against the sim's truth (sim/obstacles), in a hover.

World: two pillars, one mover going back and forth at 1.5 m/s, a steady 5 m/s wind; the lidar at
20 Hz, 720 beams. After take-off to 5 m and 3 s of settling, over 12 s of hover: each pillar's
perceived centre within 0.3 m of the truth (median; the perceived one converted from navigation's
estimated home into the sim's frame) and radius within 20 %; the mover's centre within 0.3 m and
velocity within 0.5 m/s (median, away from its turn-arounds); the wind estimate valid and within
1 m/s of the truth at the end (10+ s of hover). Prints the figures and perception's CPU.
"""

from __future__ import annotations

import functools
import math
import os
from pathlib import Path

import numpy as np
import pytest
from c4d_testing import installed_executable, sample_latest, spin_for

from c4d_common.geodesy import GeoOrigin

SIM_HOME = GeoOrigin(43.5629, 1.4815, 146.0)  # start of config/sim.yaml
WORLD = """name: perception_test
cylinders:
  - {center: [6.0, 3.0], radius: 0.5, height: 10.0}
  - {center: [-4.0, -5.0], radius: 0.8, height: 10.0}
movers:
  - {path: [[9.0, -9.0], [9.0, 9.0]], speed: 1.5, radius: 0.4, height: 10.0, mode: back_and_forth}
wind:
  mean_enu_m_s: [4.0, 3.0, 0.0]
  gust_m_s: 0.0
"""
WIND_TRUTH = (4.0, 3.0)
TURN_MARGIN_S = 2.0  # mover velocity judged only this long after its last change of direction


@pytest.fixture(scope="module")
def graph(module_processes, ros_node, tmp_path_factory):
    world = tmp_path_factory.mktemp("world") / "world.yaml"
    world.write_text(WORLD)
    nodes = [("c4d_sim", "sim", ["-p", f"world:={world}", "-p", "scan_rate_hz:=20.0", "-p", "scan_beams:=720"]),
             ("c4d_gnc", "perception", []), ("c4d_gnc", "navigation", []),
             ("c4d_gnc", "core", ["-p", "rt_priority:=50"])]
    procs = {name: module_processes.spawn(name, [installed_executable(pkg, name), "--ros-args", *args])
             for pkg, name, args in nodes}
    return (*ros_node, procs, module_processes)


def cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def stamp(m) -> float:
    return m.header.stamp.sec + m.header.stamp.nanosec * 1e-9


def test_obstacles_and_wind_against_the_truth(graph):
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    from c4d_interfaces.msg import Surroundings, VehicleState, VehicleStatus
    from c4d_interfaces.srv import VehicleCommand
    from c4d_ros.manifest import SIM_OBSTACLES, SURROUNDINGS

    node, executor, procs, group = graph
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    rec: dict[str, list] = {"seen": [], "truth": [], "status": []}
    deep = QoSProfile(depth=50, reliability=ReliabilityPolicy.BEST_EFFORT)  # matches both publishers, keeps a burst
    node.create_subscription(Surroundings, SURROUNDINGS.name, rec["seen"].append, deep)
    node.create_subscription(Surroundings, SIM_OBSTACLES.name, rec["truth"].append, deep)
    node.create_subscription(VehicleStatus, "vehicle/status", rec["status"].append, latched)
    state = sample_latest(node, VehicleState, "navigation/state")
    client = node.create_client(VehicleCommand, "gnc/command")
    spin = functools.partial(spin_for, executor, watch=(group, procs))

    assert client.wait_for_service(timeout_sec=30)
    valid = VehicleState.VALID_POSITION_XY | VehicleState.VALID_HEADING | VehicleState.VALID_ORIGIN
    assert spin(30, lambda: (s := state.latest()) is not None and s.valid & valid == valid), "estimator never valid"
    for _ in range(10):
        future = client.call_async(VehicleCommand.Request(command=VehicleCommand.Request.CMD_TAKEOFF, altitude=5.0))
        assert spin(10, future.done)
        if future.result().result != VehicleCommand.Response.RESULT_TEMPORARILY_REJECTED:
            break
        spin(1.0)
    assert future.result().result == VehicleCommand.Response.RESULT_ACCEPTED, future.result().message
    assert spin(25, lambda: rec["status"] and rec["status"][-1].nav_state == VehicleStatus.NAV_HOLD
                and rec["status"][-1].landed_state == VehicleStatus.LANDED_IN_AIR), "take-off did not complete"
    o = state.latest().origin
    home = GeoOrigin(o.latitude, o.longitude, o.altitude)
    spin(3.0)
    rec["seen"].clear()
    pid = procs["perception"].pid
    cpu0, t0 = cpu_s(pid), stamp(rec["truth"][-1])
    spin(12.0)
    cpu = 100.0 * (cpu_s(pid) - cpu0) / 12.0
    seen = [m for m in rec["seen"] if stamp(m) >= t0]
    truth = rec["truth"]
    truth_t = np.array([stamp(m) for m in truth])

    def truth_at(t: float):
        k = int(np.argmin(np.abs(truth_t - t)))
        return truth[k], t - truth_t[k]

    errors: dict[int, dict[str, list[float]]] = {}
    for m in seen:
        tm, dt = truth_at(stamp(m))
        if abs(dt) > 0.06:
            continue
        for ob in tm.obstacles:
            tx, ty = ob.position.x + ob.velocity.x * dt, ob.position.y + ob.velocity.y * dt
            near = [(math.hypot(*(np.array(SIM_HOME.to_enu(*home.to_geodetic(p.position.x, p.position.y, 0.0)))[:2]
                                  - (tx, ty))), p) for p in m.obstacles]
            if not near:
                continue
            d, p = min(near, key=lambda e: e[0])
            e = errors.setdefault(ob.id, {"pos": [], "radius": [], "vel": [], "truth_r": [ob.radius]})
            e["pos"].append(d)
            e["radius"].append(abs(p.radius - ob.radius) / ob.radius)
            before, _ = truth_at(stamp(m) - TURN_MARGIN_S)
            then = next((b for b in before.obstacles if b.id == ob.id), None)
            if then is not None and math.hypot(then.velocity.x - ob.velocity.x, then.velocity.y - ob.velocity.y) < 0.01:
                e["vel"].append(math.hypot(p.velocity.x - ob.velocity.x, p.velocity.y - ob.velocity.y))
    last = seen[-1]
    wind_error = math.hypot(last.wind.x - WIND_TRUTH[0], last.wind.y - WIND_TRUTH[1])
    print(f"\nperception over 12 s of hover ({len(seen)} Surroundings, {len(last.obstacles)} obstacles in the last):")
    for oid, e in sorted(errors.items()):
        vel = f", velocity error median {np.median(e['vel']):.2f} m/s ({len(e['vel'])})" if e["vel"] else ""
        print(f"  truth id {oid} (r {e['truth_r'][0]:.2f} m): centre error median {np.median(e['pos']):.3f} m "
              f"(max {np.max(e['pos']):.3f}), radius error median {100 * np.median(e['radius']):.1f} %{vel}")
    print(f"  wind estimate ({last.wind.x:.2f}, {last.wind.y:.2f}) m/s vs truth {WIND_TRUTH}: error {wind_error:.2f} m/s, "
          f"valid {last.wind_valid}, std {last.wind_std:.2f} m/s")
    print(f"  perception CPU {cpu:.1f} % of a core (500 Hz IMU path + 720-beam scans at 20 Hz)")
    assert len(seen) >= 200  # 20 Hz for 12 s
    assert set(errors) == {1, 2, 3}  # both pillars and the mover, every one perceived
    for oid, e in errors.items():
        assert len(e["pos"]) >= 100, (oid, len(e["pos"]))
        assert np.median(e["pos"]) <= 0.3, (oid, np.median(e["pos"]))
        assert np.median(e["radius"]) <= 0.2, (oid, np.median(e["radius"]))
    assert len(errors[3]["vel"]) >= 50 and np.median(errors[3]["vel"]) <= 0.5
    assert last.wind_valid and wind_error <= 1.0
