"""`c4d fly --mission FILE`: an end-to-end SITL flight.

Starts the graph (`c4d up` as a child process in its own session, so the graph's supervisor
is single-threaded and this process's ROS threads never fork), waits for the estimator and the
recorder, uploads the plan, starts it (the mission arms and takes off when its first item is a
take-off, otherwise a take-off command comes first), prints progress while flying, and after
landing and disarm stops the graph, runs `analyze` on the flight's MCAP and prints the summary
(duration, distance, tracking error, overruns, failsafes, file paths; also in summary.txt).
A vehicle disarmed without completing the plan (failsafe landing, pilot) ends the run at once,
naming the failsafe; fly's own --timeout LAND is reported as fly's, not as the last warning.
Exit 0 only if the plan was completed, the vehicle landed and disarmed, the graph stopped
cleanly and (when configured) the recording and report exist.
"""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from c4d_common.vehicle import UploadRefusal
from c4d_ros.manifest import MISSION_UPLOAD

from .ros_link import key_values
from .summary import FLIGHT_MODES, NAV_STATES, FlightSummary, progress_line
from .supervisor import _pdeathsig, signal_group
from .system_config import SystemConfig, node_parameters, resolve_executable, variables_for

DISARM_GRACE_S = 3.0  # a disarmed vehicle with the mission still ACTIVE: end the run after this long


class FlightError(RuntimeError):
    """The flight cannot go on (one line)."""


@dataclass
class FlyOptions:
    mission: Path
    timeout_s: float
    report: bool


def recorder_dir(config: SystemConfig, run_dir: Path) -> Path | None:
    node = config.node("recorder")
    if node is None:
        return None
    out = node_parameters(node, variables_for(config, run_dir), config.path).get("output_dir", "flights")
    return Path(out) if Path(out).is_absolute() else Path.cwd() / out


def start_graph(config: SystemConfig, run_dir: Path, env: dict[str, str]) -> subprocess.Popen:
    run_dir.mkdir(parents=True, exist_ok=True)
    with open(run_dir / "c4d-up.log", "ab") as log:
        return subprocess.Popen([sys.executable, "-m", "c4d_bringup.cli", "up", "--config", str(config.path),
                                 "--run-dir", str(run_dir)], stdout=log, stderr=subprocess.STDOUT,
                                stdin=subprocess.DEVNULL, env=env, start_new_session=True, preexec_fn=_pdeathsig)


def stop_graph(up: subprocess.Popen, timeout: float) -> int:
    if up.poll() is None:
        signal_group(up.pid, signal.SIGINT)
        try:
            up.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            signal_group(up.pid, signal.SIGKILL)
            up.wait()
    signal_group(up.pid, signal.SIGKILL)
    return up.returncode


def fly(config: SystemConfig, options: FlyOptions, plan, run_dir: Path, out=sys.stdout) -> int:
    env = dict(os.environ)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = env.get("C4D_DISCOVERY_RANGE") or config.discovery_range
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = env["ROS_AUTOMATIC_DISCOVERY_RANGE"]

    def say(text: str) -> None:
        print(f"c4d fly: {text}", file=out, flush=True)

    interrupted: list[int] = []
    previous = {s: signal.signal(s, lambda signum, frame: interrupted.append(signum))
                for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)}
    up = start_graph(config, run_dir, env)
    say(f"graph starting ({len(config.nodes)} nodes, ROS_DOMAIN_ID {env.get('ROS_DOMAIN_ID', '0')}); "
        f"logs in {run_dir / 'logs'}")
    summary = FlightSummary()
    outcome, link, rec, started = "not flown", None, None, time.monotonic()
    try:
        from .ros_link import GraphLink

        link = GraphLink("c4d_fly")
        outcome = _fly(link, key_values, config, options, plan, up, summary, interrupted, say, started)
    except FlightError as exc:
        outcome = f"FAILED: {exc}"
        say(f"error: {exc}")
    finally:
        if link is not None:
            rec = link.latest.get("recorder")
            link.close()
        say("stopping the graph")
        code = stop_graph(up, config.shutdown_timeout_s + 10)
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    ok = outcome == "completed"
    if code != 0:
        ok = False
        outcome += f"; graph stopped with exit code {code} (see {run_dir / 'c4d-up.log'})"
    paths = {"run": str(run_dir)}
    flights = recorder_dir(config, run_dir)
    if flights is not None:
        bags = sorted(flights.glob("*.mcap"), key=lambda p: p.stat().st_mtime)
        if bags:
            paths["mcap"] = str(bags[-1])
            if options.report:
                report = _analyze(config, bags[-1], run_dir / "report", say)
                if report is None:
                    ok = False
                else:
                    paths["report"] = str(report)
        elif summary.armed_at is not None:
            ok = False
            paths["mcap"] = f"MISSING (recorder log: {run_dir / 'logs' / 'recorder.log'}; status {rec and key_values(rec)})"
    lines = summary.lines(outcome, paths)
    (run_dir / "summary.txt").write_text("\n".join(lines) + "\n")
    print("\n".join(["", "── c4d fly summary " + "─" * 40, *lines]), file=out, flush=True)
    if interrupted:
        return 130
    return 0 if ok else 1


def _analyze(config: SystemConfig, bag: Path, report_dir: Path, say) -> Path | None:
    from .system_config import ConfigError, NodeConfig

    try:
        exe = resolve_executable(NodeConfig("analyze", "c4d_data", "analyze", False))
    except ConfigError as exc:
        say(f"no report: {exc}")
        return None
    say(f"analysing {bag.name}")
    try:
        done = subprocess.run([str(exe), str(bag), "-o", str(report_dir), "--quiet"], capture_output=True, text=True,
                              timeout=300, start_new_session=True)
    except subprocess.TimeoutExpired:
        say("error: analyze took longer than 300 s")
        return None
    if done.returncode != 0:
        say(f"error: analyze failed: {(done.stderr or done.stdout).strip().splitlines()[-1:]}")
        return None
    html = sorted(report_dir.glob("*.html"))
    return html[0] if html else report_dir


def _fly(link, key_values, config, options, plan, up, summary, interrupted, say, started) -> str:
    from c4d_interfaces.msg import GuidanceSetpoint, MissionState, VehicleState, VehicleStatus
    from c4d_interfaces.srv import MissionControl, UploadMission, VehicleCommand
    from c4d_ros.plan_msgs import plan_to_msg

    def watch() -> None:
        if interrupted:
            raise FlightError(f"interrupted by {signal.Signals(interrupted[0]).name}")
        if up.poll() is not None:
            raise FlightError(f"the graph stopped (c4d up exit code {up.returncode}; see the run's c4d-up.log)")

    def now() -> float:
        return time.monotonic() - started

    link.listen("status", lambda m: summary.on_status(now(), m.armed, m.landed_state == VehicleStatus.LANDED_IN_AIR))
    link.listen("odometry", lambda m: summary.on_position(m.pose.pose.position.x, m.pose.pose.position.y,
                                                          m.pose.pose.position.z))
    link.listen("setpoint", lambda m: m.control_level == GuidanceSetpoint.LEVEL_POSITION and
                summary.on_setpoint(m.position.x, m.position.y, m.position.z))
    link.listen("stats", lambda m: summary.on_executor_stats(m.ticks_total, m.overruns_total, m.load_max_percent))

    def on_health(m) -> None:
        kv = key_values(m)
        summary.on_failsafe(kv.get("failsafe", ""), kv.get("reason", ""))
    link.listen("health", on_health)

    ready = VehicleState.VALID_ORIGIN | VehicleState.VALID_POSITION_XY | VehicleState.VALID_ATTITUDE
    if not link.spin(120, lambda: link.state_valid(ready), watch):
        raise FlightError("the estimator did not become valid within 120 s (see logs/navigation.log)")
    say(f"estimator ready after {now():.1f} s")
    if config.node("recorder") is not None:
        if link.spin(30, lambda: "recorder" in link.latest and
                     int(key_values(link.latest["recorder"]).get("topics", "0")) >= 15, watch):
            say(f"recorder ready ({key_values(link.latest['recorder'])['topics']} topics)")
        else:
            say("warning: the recorder has not reported 15 topics yet; flying anyway")
    deadline = time.monotonic() + 30
    while True:
        reply = link.call(link.upload, UploadMission.Request(plan=plan_to_msg(plan)), watch=watch)
        if reply is None:
            raise FlightError(f"{MISSION_UPLOAD.name} did not answer (is the mission node running? see logs/mission.log)")
        if reply.accepted or not UploadRefusal(reply.refusal).retry or time.monotonic() > deadline:
            break
        link.spin(1.0, watch=watch)
    if not reply.accepted:
        raise FlightError("plan rejected: " + "; ".join(reply.errors))
    for warning in reply.warnings:
        say(f"plan warning: {warning}")
    say(f"plan '{plan.name}' uploaded (id {reply.plan_id}, {len(plan.items)} items)")
    if plan.items and plan.items[0].type != "takeoff":
        altitude = next((i.z for i in plan.items if math.isfinite(i.z)), 5.0)
        _retry(link, link.vehicle, VehicleCommand.Request(command=VehicleCommand.Request.CMD_TAKEOFF, altitude=float(altitude)),
               VehicleCommand.Response, "take-off", watch)
        if not link.spin(60, lambda: _status(link) is not None and _status(link).nav_state == VehicleStatus.NAV_HOLD
                         and _status(link).landed_state == VehicleStatus.LANDED_IN_AIR, watch):
            raise FlightError("take-off not completed within 60 s")
    _retry(link, link.control, MissionControl.Request(action=MissionControl.Request.ACTION_START),
           MissionControl.Response, "mission start", watch)
    say("mission started")
    flight_start, last_print, last_item = time.monotonic(), 0.0, None
    timed_out = aborted = False
    disarmed_since: float | None = None
    while True:
        link.spin(0.2, watch=watch)
        m, s = link.latest.get("mission"), _status(link)
        if m is not None and s is not None and m.state == MissionState.STATE_COMPLETED and not s.armed:
            break
        if m is not None and m.state == MissionState.STATE_ABORTED and not aborted:
            aborted = True
            say(f"mission aborted ({_abort_cause(link, summary, timed_out, options.timeout_s)}); waiting for the vehicle to land")
        # the flight is over once the vehicle that flew is disarmed and not completing the plan: a
        # still-ACTIVE mission gets DISARM_GRACE_S to report the end of its own landing first
        if summary.armed_at is not None and s is not None and not s.armed:
            disarmed_since = disarmed_since or time.monotonic()
            if m is None or m.state != MissionState.STATE_ACTIVE or time.monotonic() - disarmed_since > DISARM_GRACE_S:
                break
        else:
            disarmed_since = None
        if time.monotonic() - flight_start > options.timeout_s and not timed_out:
            timed_out = True
            say(f"mission not finished after {options.timeout_s:.0f} s (--timeout): c4d fly commands LAND")
            link.call(link.vehicle, VehicleCommand.Request(command=VehicleCommand.Request.CMD_LAND), watch=watch)
        if timed_out and time.monotonic() - flight_start > options.timeout_s + 90:
            raise FlightError("the vehicle did not land within 90 s of the land command")
        item = (m.state, m.current_item) if m is not None else None
        if time.monotonic() - last_print >= 2.0 or item != last_item:
            last_print, last_item = time.monotonic(), item
            say(_progress(link, time.monotonic() - flight_start))
    say(_progress(link, time.monotonic() - flight_start))
    if config.node("recorder") is not None:
        link.spin(15, lambda: key_values(link.latest.get("recorder")).get("state") == "idle" and
                  int(key_values(link.latest.get("recorder")).get("files", "0")) >= 1, watch)
    m = link.latest.get("mission")
    if m is not None and m.state == MissionState.STATE_COMPLETED:
        return "completed"
    if timed_out:
        return f"timed out after {options.timeout_s:.0f} s (c4d fly commanded LAND; landed)"
    where = f" at item {m.current_item + 1}/{m.total_items}" if m is not None and m.total_items else ""
    return f"not completed: disarmed{where} ({_abort_cause(link, summary, timed_out, options.timeout_s)})"


def _abort_cause(link, summary: FlightSummary, timed_out: bool, timeout_s: float) -> str:
    """Why the plan stopped: fly's own timeout, else the failsafe health acted on during the flight
    (the latest health report no longer shows it once the vehicle is disarmed), else the latest report."""
    if timed_out:
        return f"c4d fly's --timeout of {timeout_s:.0f} s: LAND commanded by c4d fly"
    acting = summary.acting_failsafes()
    return acting if acting else _failsafe_text(link, key_values)


def _status(link):
    return link.latest.get("status")


def _failsafe_text(link, key_values) -> str:
    kv = key_values(link.latest.get("health"))
    return f"failsafe {kv.get('failsafe', '?')}: {kv.get('reason', '')}" if kv else "no health report"


def _progress(link, elapsed: float) -> str:
    m, s, o, b = (link.latest.get(k) for k in ("mission", "status", "odometry", "battery"))
    mission = (m.state, m.current_item, m.total_items, m.progress) if m is not None else None
    position = (o.pose.pose.position.x, o.pose.pose.position.y, o.pose.pose.position.z) if o is not None else None
    mode = "-" if s is None else (f"{'armed' if s.armed else 'disarmed'} {FLIGHT_MODES.get(s.flight_mode, '?')}"
                                  f"/{NAV_STATES.get(s.nav_state, '?')}")
    return progress_line(elapsed, mission, position, b.percentage if b is not None else None, mode)


def _retry(link, client, request, response_type, what: str, watch, seconds: float = 30.0) -> None:
    deadline = time.monotonic() + seconds
    while True:
        reply = link.call(client, request, watch=watch)
        if reply is None:
            raise FlightError(f"{what}: no answer from {client.srv_name}")
        if reply.result == response_type.RESULT_ACCEPTED:
            return
        if reply.result != response_type.RESULT_TEMPORARILY_REJECTED or time.monotonic() > deadline:
            raise FlightError(f"{what} refused: {reply.message}")
        link.spin(1.0, watch=watch)
