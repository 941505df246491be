"""A mission flown by `c4d fly` while the graph is disturbed, observed from outside (issue 13).

InterferenceFlight starts `c4d fly` on a generated 10 m square-loop plan, waits for cruise,
then lets the caller disturb the graph (kill -9 a node and wait for the supervisor's restart;
run a disturber process) while it records, from their sources:
  - the GNC core's worst tick per 1 s window (gnc/executor_stats: load_max × tick period) and
    skipped ticks,
  - the command stream as the vehicle received it (sim/actuator_link: worst gap, p99.9, > 20 ms),
  - the true altitude (sim/ground_truth),
  - platform stalls over the same window (StallProbe: a SCHED_FIFO 90 process's worst oversleep).
Shared by test/test_interference.py and bench/interference.py.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import yaml
from stall_probe import StallProbe

ROOT = Path(__file__).resolve().parents[2]
CRUISE_ALT = 10.0


def square_plan(seconds: float) -> dict:
    """Corners of a 15 m square at 10 m, enough for about `seconds` of cruise (~12 s per 15 m leg, measured)."""
    corners = ((15, 0), (15, 15), (0, 15), (0, 0))
    items = [{"type": "takeoff", "altitude": CRUISE_ALT}]
    items += [{"type": "waypoint", "east": corners[k % 4][0], "north": corners[k % 4][1], "alt": CRUISE_ALT,
               "acceptance_radius": 1.0} for k in range(max(1, int(seconds / 12) + 1))]
    items.append({"type": "land"})
    return {"name": "interference square", "cruise_speed": 3.0, "rtl_altitude": CRUISE_ALT,
            "geofence": {"max_altitude": 30, "max_distance": 100}, "items": items}


@dataclass
class Window:
    """Figures over [start, end] (monotonic seconds)."""

    label: str
    start: float
    end: float = 0.0
    worst_tick_ms: float = 0.0
    skipped_ticks: int = 0
    min_alt: float = float("inf")
    max_alt: float = float("-inf")
    platform_stall_ms: float = 0.0


@dataclass
class Observations:
    stats: list[tuple[float, float, int]] = field(default_factory=list)  # (t, worst tick ms, skipped)
    truth: list[tuple[float, float]] = field(default_factory=list)  # (t, true altitude)
    link: dict[str, float] = field(default_factory=dict)  # newest sim/actuator_link values
    mission: tuple[int, int] | None = None  # (state, current item)


class InterferenceFlight:
    """`c4d fly` of square_plan() plus the observers (see the module docstring)."""

    def __init__(self, run_dir: Path, env: dict[str, str], cruise_s: float) -> None:
        import rclpy
        from diagnostic_msgs.msg import DiagnosticStatus
        from nav_msgs.msg import Odometry
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor

        from c4d_interfaces.msg import ExecutorStats, MissionState
        from c4d_ros import manifest

        self.run_dir = run_dir
        run_dir.mkdir(parents=True, exist_ok=True)
        plan = run_dir / "plan.yaml"
        doc = square_plan(cruise_s)
        self.land_item = len(doc["items"]) - 1  # land_now() jumps there
        plan.write_text(yaml.safe_dump(doc, sort_keys=False))
        self.log_path = run_dir / "fly.log"
        self.fly = subprocess.Popen([str(ROOT / "c4d"), "fly", "--mission", str(plan), "--run-dir", str(run_dir / "run"),
                                     "--no-report"], stdout=open(self.log_path, "w"), stderr=subprocess.STDOUT,
                                    stdin=subprocess.DEVNULL, env=env, start_new_session=True)
        self.probe = StallProbe()
        self.context = Context()
        rclpy.init(context=self.context, domain_id=int(env["ROS_DOMAIN_ID"]))
        self.node = rclpy.create_node("c4d_interference_observer", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.obs = Observations()
        o = self.obs
        tick_ms = [2.0]

        def on_stats(m) -> None:
            tick_ms[0] = 1e3 / m.tick_rate_hz if m.tick_rate_hz > 0 else tick_ms[0]
            o.stats.append((time.monotonic(), m.load_max_percent / 100.0 * tick_ms[0], int(m.skipped_ticks)))

        self.node.create_subscription(ExecutorStats, manifest.EXECUTOR_STATS.name, on_stats, manifest.EXECUTOR_STATS.qos)
        self.node.create_subscription(Odometry, manifest.GROUND_TRUTH.name,
                                      lambda m: o.truth.append((time.monotonic(), m.pose.pose.position.z)),
                                      manifest.GROUND_TRUTH.qos)
        self.node.create_subscription(DiagnosticStatus, manifest.ACTUATOR_LINK.name,
                                      lambda m: o.link.update({kv.key: float(kv.value) for kv in m.values}),
                                      manifest.ACTUATOR_LINK.qos)
        self.node.create_subscription(MissionState, manifest.MISSION_STATE.name,
                                      lambda m: setattr(o, "mission", (m.state, m.current_item)), manifest.MISSION_STATE.qos)
        self.windows: list[Window] = []
        self.stalls: list[tuple[float, float]] = []
        from c4d_interfaces.srv import MissionControl

        self.control = self.node.create_client(MissionControl, manifest.MISSION_CONTROL.name)

    # ----------------------------------------------------------------- waiting
    def spin(self, seconds: float, until=None) -> bool:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=0.05)
            if until is not None and until():
                return True
            if self.fly.poll() is not None and until is not None:
                return False
        return until is None

    def wait_cruise(self, seconds: float = 150.0) -> bool:
        """True once the take-off item is done and the vehicle is within 1 m of the cruise altitude."""
        o = self.obs
        return self.spin(seconds, lambda: o.mission is not None and o.mission[1] >= 1 and bool(o.truth)
                         and abs(o.truth[-1][1] - CRUISE_ALT) < 1.0)

    # ----------------------------------------------------------------- disturbances
    def pids(self) -> dict[str, int | None]:
        state = self.run_dir / "run" / "supervisor.json"
        try:
            return {n: v.get("pid") for n, v in json.loads(state.read_text())["nodes"].items()}
        except (OSError, ValueError, KeyError):
            return {}

    def kill_and_wait_restart(self, name: str, seconds: float = 15.0) -> bool:
        """SIGKILL the node's process; True once the supervisor runs a new one."""
        old = self.pids().get(name)
        if not old:
            return False
        os.kill(old, signal.SIGKILL)
        return self.spin(seconds, lambda: self.pids().get(name) not in (None, old))

    def disturber(self, *args: str) -> subprocess.Popen:
        return subprocess.Popen([sys.executable, str(ROOT / "test" / "support" / "disturbers.py"), *args],
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True)

    # ----------------------------------------------------------------- accounting
    def open_window(self, label: str) -> Window:
        w = Window(label, time.monotonic())
        self.windows.append(w)
        return w

    def close_window(self, w: Window, settle_s: float = 1.5) -> Window:
        """Let the next statistics windows arrive, then fill `w` (stats windows ending inside it count)."""
        self.spin(settle_s)
        w.end = time.monotonic()
        inside = [s for s in self.obs.stats if w.start < s[0] <= w.end]
        w.worst_tick_ms = max((s[1] for s in inside), default=0.0)
        w.skipped_ticks = sum(s[2] for s in inside)
        alts = [z for t, z in self.obs.truth if w.start <= t <= w.end]
        if alts:
            w.min_alt, w.max_alt = min(alts), max(alts)
        return w

    def land_now(self) -> str:
        """Make the plan's land item current (mission/control SET_CURRENT, as a GCS does), so the
        flight ends when the disturbances do, whatever cruise they left; '' when accepted, else why not."""
        from c4d_interfaces.srv import MissionControl

        if not self.control.wait_for_service(timeout_sec=10.0):
            return "mission/control not available"
        future = self.control.call_async(MissionControl.Request(action=MissionControl.Request.ACTION_SET_CURRENT,
                                                                 item=self.land_item))
        self.spin(10.0, future.done)
        if not future.done():
            return "mission/control did not answer within 10 s"
        reply = future.result()
        return "" if reply.result == MissionControl.Response.RESULT_ACCEPTED else f"refused ({reply.result}): {reply.message}"

    def finish(self, seconds: float = 240.0) -> int:
        """Wait for `c4d fly` to end (it lands, stops the graph and writes its summary); its exit code."""
        end = time.monotonic() + seconds
        while self.fly.poll() is None and time.monotonic() < end:
            self.spin(0.5)
        if self.fly.poll() is None:
            os.killpg(self.fly.pid, signal.SIGINT)
            try:
                self.fly.wait(30)
            except subprocess.TimeoutExpired:
                os.killpg(self.fly.pid, signal.SIGKILL)
                self.fly.wait(10)
        self.stalls = self.probe.stop()
        for w in self.windows:
            w.platform_stall_ms = max((g for t, g in self.stalls if w.start <= t <= w.end + 1.0), default=0.0)
        return self.fly.returncode

    def close(self) -> None:
        import rclpy

        if self.fly.poll() is None:
            os.killpg(self.fly.pid, signal.SIGKILL)
        if self.probe.proc.poll() is None:
            self.probe.proc.kill()
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)

    def fly_log(self) -> str:
        return self.log_path.read_text(errors="replace")
