"""`c4d fly` end to end in real time: the whole graph (9 processes) flies the short example mission
missions/hop.yaml, lands and stops, in under 2 minutes; nothing is left running; the flight's
MCAP is complete and readable by the independent `rosbags` reader (arm and disarm in it), and
the analysis report exists with its plots."""

from __future__ import annotations

import json
import time
from pathlib import Path

import yaml
from c4d_testing import RUN_TOKEN, call_service, installed_executable, leftover_processes, spin_for

ROOT = Path(__file__).resolve().parent.parent


def test_c4d_fly_hop(processes, tmp_path):
    from rosbags.highlevel import AnyReader

    # the bundled SITL config, with the MAVLink bridge on an ephemeral port (other tests may hold 14550)
    doc = yaml.safe_load((ROOT / "src" / "c4d_bringup" / "config" / "sitl.yaml").read_text())
    doc["nodes"]["bridge"]["parameters"]["endpoints"] = ["udpin:127.0.0.1:0"]
    doc["run_root"] = str(tmp_path / "runs")
    (tmp_path / "system.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    run = tmp_path / "run"
    t0 = time.monotonic()
    fly = processes.spawn("fly", [installed_executable("c4d_bringup", "c4d"), "fly", "--mission",
                                  str(ROOT / "missions" / "hop.yaml"), "--config", str(tmp_path / "system.yaml"),
                                  "--run-dir", str(run)])
    code = fly.wait(timeout=150)
    elapsed = time.monotonic() - t0
    out = processes.log_of(fly)
    print(f"\nc4d fly hop: exit {code} after {elapsed:.1f} s\n{out[-1500:]}")
    assert code == 0, (out[-3000:], (run / "c4d-up.log").read_text()[-2000:])
    assert elapsed < 120
    # nothing left behind: no process of this test run is alive, every node's pid is gone
    assert leftover_processes(RUN_TOKEN) == []
    nodes = json.loads((run / "supervisor.json").read_text())["nodes"]
    assert sorted(nodes) == sorted(doc["nodes"]) and all(n["pid"] is None for n in nodes.values())
    assert all(n["restarts"] == 0 for name, n in nodes.items() if name != "bridge"), nodes
    # the summary: completed, with the figures the issue asks for
    summary = (run / "summary.txt").read_text()
    assert "flight     completed" in summary
    for key in ("duration", "distance", "tracking", "overruns", "failsafes  none", "mcap", "report"):
        assert f"\n{key}" in "\n" + summary, summary
    distance = float(summary.split("distance   ")[1].split(" m")[0])
    assert 14.0 <= distance <= 30.0, summary  # 4 m up, 8 m north, 4 m down (+ estimator noise)
    assert "ACTIVE    item  2/3" in out  # live progress lines while flying
    # the recording: one complete MCAP, read by rosbags, arm and disarm inside
    bags = sorted((run / "flights").glob("*.mcap"))
    assert len(bags) == 1 and summary.count(str(bags[0])) == 1
    armed, counts = [], {}
    with AnyReader([bags[0]]) as reader:
        for connection, _, raw in reader.messages():
            counts[connection.topic] = counts.get(connection.topic, 0) + 1
            if connection.topic == "/vehicle/status":
                armed.append(reader.deserialize(raw, connection.msgtype).armed)
    assert True in armed and armed[-1] is False
    assert counts["/control/actuators"] > 5000 and counts["/mission/state"] > 10 and "/sim/ground_truth" in counts
    # the analysis report
    report = run / "report" / "index.html"
    assert report.is_file() and report.stat().st_size > 1000 and str(report) in summary
    assert len(list((run / "report").glob("*.png"))) >= 5
    assert (run / "logs" / "core.log").stat().st_size > 0


FAR = """name: far
items:
  - {type: takeoff, altitude: 10}
  - {type: waypoint, east: 50000, north: 0, alt: 10}
  - {type: land}
"""


def test_c4d_fly_refuses_a_plan_beyond_the_endurance_before_anything_starts(tmp_path):
    """Issue 14.1: one waypoint 50 km away and no geofence: the endurance at full charge (the SITL
    pack) refuses it offline — one `c4d: error:` line, exit 2, no run folder, no process started."""
    import subprocess

    (tmp_path / "far.yaml").write_text(FAR)
    done = subprocess.run([installed_executable("c4d_bringup", "c4d"), "fly", "--mission", "far.yaml"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 2, (done.stdout, done.stderr)
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("c4d: error: mission far.yaml: ") and "exceeds 80 %" in lines[0], lines
    assert done.stdout == "" and list(tmp_path.iterdir()) == [tmp_path / "far.yaml"]  # no c4d_runs/: nothing started
    assert leftover_processes(RUN_TOKEN) == []


def test_c4d_fly_ends_the_run_when_a_failsafe_lands_the_vehicle(processes, ros_node, tmp_path):
    """Issue 14.3: a failsafe landing commanded straight to the core (the mission node is stopped,
    so health bypasses it) left the mission ACTIVE and `fly` printing `disarmed AUTO/-` until its
    timeout (3 x estimate + 60 s). Once the vehicle is disarmed the run ends, naming the failsafe."""
    import functools
    import os
    import signal

    from rcl_interfaces.srv import SetParameters
    from rclpy.parameter import Parameter

    node, executor = ros_node
    sim_params = node.create_client(SetParameters, "sim/set_parameters")
    doc = yaml.safe_load((ROOT / "src" / "c4d_bringup" / "config" / "sitl.yaml").read_text())
    doc["nodes"]["bridge"]["parameters"]["endpoints"] = ["udpin:127.0.0.1:0"]
    (tmp_path / "system.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    run = tmp_path / "run"
    fly = processes.spawn("fly", [installed_executable("c4d_bringup", "c4d"), "fly", "--mission",
                                  str(ROOT / "missions" / "survey.yaml"), "--config", str(tmp_path / "system.yaml"),
                                  "--run-dir", str(run), "--no-report"])

    def wait_log(text: str, seconds: float) -> bool:
        end = time.monotonic() + seconds
        while time.monotonic() < end and fly.poll() is None:
            if text in processes.log_of(fly):
                return True
            time.sleep(0.2)
        return text in processes.log_of(fly)

    assert wait_log("ACTIVE    item  3/", 90), processes.log_of(fly)[-2000:]  # in the air, on the first leg
    mission = json.loads((run / "supervisor.json").read_text())["nodes"]["mission"]["pid"]
    os.kill(mission, signal.SIGSTOP)  # the mission node cannot hear the landing nor report it
    try:
        drain = Parameter("fault.battery_drain_factor", value=3000.0).to_parameter_msg()
        reply = call_service(functools.partial(spin_for, executor), sim_params, SetParameters.Request(parameters=[drain]))
        assert reply.results[0].successful, reply.results[0].reason
        assert wait_log("stopping the graph", 60), processes.log_of(fly)[-2000:]
    finally:
        os.kill(mission, signal.SIGCONT)
    assert fly.wait(timeout=60) == 1
    summary = (run / "summary.txt").read_text()
    assert "flight     not completed: disarmed at item" in summary and "failsafe LAND battery_critical" in summary, summary
