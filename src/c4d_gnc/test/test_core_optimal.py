"""The core starts with phase_method optimal: the exact phases, proven, with the cascade's precedence edges
(issue 22); the published schedule carries method, optimality and bound. One process, no graph."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

from c4d_gnc.core_config import load_core_config
from c4d_gnc.ros_conversions import schedule_msg


def test_core_config_optimal_schedule_and_its_message():
    cfg = load_core_config(None, None, "optimal")
    s = cfg.schedule
    assert s.method == "optimal" and s.optimality == "optimal" and s.lower_bound_us == s.max_tick_load_us
    assert s.max_tick_load_us <= load_core_config(None, None, "gcdplus").schedule.max_tick_load_us
    assert any((e.producer, e.consumer) == ("state_update", "rate_control") for e in s.precedence)
    order = [t.name for t in s.tasks]
    assert order.index("state_update") < order.index("rate_control") < order.index("mixer")
    msg = schedule_msg(s, cfg.executive_name, 0.0)
    assert msg.method == "optimal" and msg.optimality == "optimal" and msg.lower_bound_us == float(s.max_tick_load_us)
    assert cfg.parameters()["phase_method"] == "optimal"


def test_core_process_starts_with_phase_method_optimal():
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="OFF", PYTHONUNBUFFERED="1")  # the process meets no graph
    proc = subprocess.Popen([sys.executable, "-m", "c4d_gnc.core_node", "--ros-args", "-p", "phase_method:=optimal"],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True)
    lines: list[str] = []
    try:
        deadline = time.monotonic() + 60
        assert proc.stdout is not None
        while time.monotonic() < deadline:
            line = proc.stdout.readline()
            if not line:
                break
            lines.append(line)
            if "phases by" in line:
                break
    finally:
        os.killpg(proc.pid, signal.SIGINT)
        try:
            rest, _ = proc.communicate(timeout=20)  # keep draining: a full pipe would block its shutdown
            lines.extend(rest.splitlines(keepends=True))
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
    started = [line for line in lines if "phases by" in line]
    assert started, "".join(lines)
    assert "phases by optimal" in started[0] and "proven optimal" in started[0], started[0]
    assert not any("WARN" in line and "phase_method optimal" in line for line in lines)
