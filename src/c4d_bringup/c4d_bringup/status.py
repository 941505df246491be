"""`c4d status`: one screen of the live graph (nodes alive, mode, position, battery, executor load).

Listens in the current ROS_DOMAIN_ID until every node of the system config has been discovered
and each of them has published what the screen shows (or `wait_s` seconds have passed), then
prints. Exit 0 when every node is alive, 1 otherwise (so scripts can wait on it). Returning as
soon as the picture is complete keeps it quick on an idle machine and still right on a loaded one,
where DDS discovery of a whole graph can take seconds.
"""

from __future__ import annotations

import math
import os
import sys

from c4d_ros.manifest import BATTERY, EXECUTOR_STATS, HEALTH_SUMMARY, MISSION_STATE, NAV_ODOMETRY, STATUS

from .ros_link import key_values
from .summary import FLIGHT_MODES, LANDED, MISSION_STATES, NAV_STATES
from .system_config import SystemConfig

# what each node contributes to the screen: `latest` keys that must be filled before printing early
SHOWN_BY_NODE = {"core": ("status", "stats"), "navigation": ("odometry",), "sim": ("battery",),
                 "mission": ("mission",), "health": ("health",), "recorder": ("recorder",)}


def complete(expected: list[str], present: set[str], latest: dict) -> bool:
    """True when every expected node is discovered and has published what the screen shows."""
    return all(n in present for n in expected) and all(
        key in latest for n in expected for key in SHOWN_BY_NODE.get(n, ()))


def render(expected: list[str], present: set[str], latest: dict, domain: str) -> tuple[list[str], bool]:
    """The status screen as lines, and whether every expected node is alive (ROS-free: plain messages in)."""
    missing = [n for n in expected if n not in present]
    others = sorted(n for n in present if n not in expected and not n.startswith("_") and not n.startswith("c4d_"))
    lines = [f"c4d status — ROS_DOMAIN_ID {domain}"]
    lines.append("nodes     " + "  ".join(f"{n} {'up' if n in present else 'DOWN'}" for n in expected)
                 + (f"   (+ {', '.join(others)})" if others else ""))
    s = latest.get("status")
    if s is None:
        lines.append(f"vehicle   no {STATUS.name}")
    else:
        fs = "" if not s.failsafe_action else f", failsafe {s.failsafe_action} {s.failsafe_reason}"
        lines.append(f"vehicle   {'ARMED' if s.armed else 'disarmed'}, mode {FLIGHT_MODES.get(s.flight_mode, '?')}"
                     f"/{NAV_STATES.get(s.nav_state, '?')}, {LANDED.get(s.landed_state, '?')}{fs}")
    o = latest.get("odometry")
    if o is None:
        lines.append(f"position  no {NAV_ODOMETRY.name}")
    else:
        p, v = o.pose.pose.position, o.twist.twist.linear
        lines.append(f"position  E {p.x:.2f} N {p.y:.2f} U {p.z:.2f} m (map, ENU), speed {math.hypot(v.x, v.y, v.z):.1f} m/s")
    b = latest.get("battery")
    lines.append(f"battery   no {BATTERY.name}" if b is None else
                 f"battery   {b.voltage:.1f} V, {100 * b.percentage:.0f} %" + (
                     f", {b.current:.1f} A" if math.isfinite(b.current) else ""))
    x = latest.get("stats")
    lines.append(f"executor  no {EXECUTOR_STATS.name}" if x is None else
                 f"executor  {x.executor} {x.tick_rate_hz:.0f} Hz: load mean {x.load_mean_percent:.1f} % max "
                 f"{x.load_max_percent:.1f} %, jitter p99 {x.release_jitter_p99_us:.0f} us, overruns {x.overruns} "
                 f"(total {x.overruns_total} of {x.ticks_total} ticks), cpu {x.cpu_percent:.0f} %")
    m = latest.get("mission")
    lines.append(f"mission   no {MISSION_STATE.name}" if m is None else f"mission   {MISSION_STATES.get(m.state, '?')}" + (
        f", item {min(m.current_item + 1, m.total_items)}/{m.total_items}, {100 * m.progress:.0f} %" if m.total_items else ""))
    h = key_values(latest.get("health"))
    lines.append(f"health    no {HEALTH_SUMMARY.name}" if not h else
                 f"health    {latest['health'].message or 'ok'}; failsafe {h.get('failsafe', '?')}"
                 + (f" ({h['reason']})" if h.get("reason") else "")
                 + (f"; dead nodes {h['dead_nodes']}" if h.get("dead_nodes") else "")
                 + (f"; stalled nodes {h['stalled_nodes']}" if h.get("stalled_nodes") else ""))
    r = key_values(latest.get("recorder"))
    if r:
        lines.append(f"recorder  {r.get('state', '?')}, {r.get('files', '?')} files, {r.get('topics', '?')} topics, "
                     f"dropped {r.get('dropped', '?')}" + (f", file {r['file']}" if r.get("file") else ""))
    return lines, not missing


def status(config: SystemConfig, wait_s: float, out=sys.stdout) -> int:
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = os.environ.get("C4D_DISCOVERY_RANGE") or config.discovery_range
    from .ros_link import GraphLink

    link = GraphLink("c4d_status")
    try:
        link.spin(wait_s, until=lambda: complete(config.names, link.node_names(), link.latest))
        present = link.node_names()
        lines, all_up = render(config.names, present, link.latest, os.environ.get("ROS_DOMAIN_ID", "0"))
    finally:
        link.close()
    print("\n".join(lines), file=out, flush=True)
    return 0 if all_up else 1
