"""Pull the series a flight report needs out of a recording, with a progress bar.

Why: the report plots dozens of quantities from ~10 topics among a few hundred thousand
messages. One linear pass decodes only the topics below (mcap_ros2, from the schemas stored in
the file, so old recordings decode even after a message changed) and turns them into numpy
columns, with time in seconds from the start of the recording (receive time). Absent topics
simply give empty series: every report section then says what is missing.
"""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from tqdm import tqdm

from ..bag_reader import BagContents, Decoders, iter_messages


def euler(w: float, x: float, y: float, z: float) -> tuple[float, float, float]:
    """Roll, pitch, yaw [rad] (ZYX) of a body->world quaternion."""
    roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return roll, pitch, yaw


def _stamp(header) -> float:
    return header.stamp.sec + header.stamp.nanosec * 1e-9


def _state(m) -> tuple:
    q = m.orientation
    return (m.position.x, m.position.y, m.position.z, m.velocity.x, m.velocity.y, m.velocity.z,
            *euler(q.w, q.x, q.y, q.z), m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z)


def _setpoint(m) -> tuple:
    return (m.position.x, m.position.y, m.position.z, m.velocity.x, m.velocity.y, m.velocity.z, m.control_level)


def _truth(m) -> tuple:
    p = m.pose.pose.position
    return p.x, p.y, p.z


def _actuators(m) -> tuple:
    return (float(m.armed), _stamp(m.header), *m.outputs)


def _battery(m) -> tuple:
    return m.voltage, m.current, m.percentage


def _status(m) -> tuple:
    return float(m.armed), m.flight_mode, m.nav_state, m.landed_state, m.failsafe_action


def _mission(m) -> tuple:
    return m.state, m.current_item, m.total_items, m.progress, m.distance_to_item


def _capture(m) -> tuple:
    return m.index, m.position.x, m.position.y, m.position.z, m.trigger


def _stats(m) -> tuple:
    return (m.load_mean_percent, m.load_max_percent, m.release_jitter_mean_us, m.release_jitter_max_us,
            m.release_jitter_p99_us, float(m.overruns), float(m.ticks), m.cpu_percent)


COLUMNS = {  # series: (topic, row function, column names)
    "state": ("/navigation/state", _state, ("x", "y", "z", "vx", "vy", "vz", "roll", "pitch", "yaw", "p", "q", "r")),
    "setpoint": ("/guidance/setpoint", _setpoint, ("x", "y", "z", "vx", "vy", "vz", "level")),
    "truth": ("/sim/ground_truth", _truth, ("x", "y", "z")),
    "actuators": ("/control/actuators", _actuators, ("armed", "stamp")),
    "battery": ("/sensors/battery", _battery, ("voltage", "current", "percentage")),
    "status": ("/vehicle/status", _status, ("armed", "mode", "nav", "landed", "failsafe")),
    "mission": ("/mission/state", _mission, ("state", "item", "total", "progress", "distance")),
    "captures": ("/payload/captures", _capture, ("index", "x", "y", "z", "trigger")),
    "stats": ("/gnc/executor_stats", _stats, ("load_mean", "load_max", "jitter_mean", "jitter_max", "jitter_p99",
                                             "overruns", "ticks", "cpu")),
}
# further topics of a series: the gateway's validated offboard stream is what the core follows in OFFBOARD (the
# mission publishes in AUTO only), so the tracking plots cover both kinds of flight
ALSO = {"/guidance/offboard": "setpoint"}
KEEP = {"/gnc/schedule": "schedule", "/mission/plan": "plan"}  # last message kept whole
EVENTS = {"/health/summary": "health", "/bridge/link_stats": "link"}  # every message kept whole


@dataclass
class Series:
    t: np.ndarray  # [s] from the start of the recording
    columns: dict[str, np.ndarray]
    extra: np.ndarray | None = None  # actuators: motor outputs (n x motors)

    def __len__(self) -> int:
        return len(self.t)

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]


@dataclass
class FlightData:
    contents: BagContents
    series: dict[str, Series] = field(default_factory=dict)
    kept: dict[str, Any] = field(default_factory=dict)
    events: dict[str, list[tuple[float, Any]]] = field(default_factory=dict)
    task_stats: list[tuple[float, Any]] = field(default_factory=list)

    def has(self, name: str) -> bool:
        return name in self.series and len(self.series[name]) > 0


def _series(name: str, times: list[float], rows: list[tuple]) -> Series:
    names = COLUMNS[name][2]
    if not rows:
        return Series(np.zeros(0), {n: np.zeros(0) for n in names})
    width = len(names)
    fixed = np.array([r[:width] for r in rows], dtype=float)
    extra = None
    if name == "actuators":
        motors = max(len(r) - width for r in rows)
        extra = np.full((len(rows), motors), np.nan)
        for k, r in enumerate(rows):
            extra[k, :len(r) - width] = r[width:]
    return Series(np.array(times), {n: fixed[:, k] for k, n in enumerate(names)}, extra)


def extract(contents: BagContents, progress: bool = True) -> FlightData:
    """One pass over the recording; returns every series the report uses."""
    by_topic = {topic: name for name, (topic, _, _) in COLUMNS.items()} | ALSO
    wanted = [t for t in (*by_topic, *KEEP, *EVENTS) if t in contents.topics]
    total = sum(contents.topics[t].count for t in wanted)
    decoders = Decoders()
    times: dict[str, list[float]] = defaultdict(list)
    rows: dict[str, list[tuple]] = defaultdict(list)
    data = FlightData(contents)
    t0 = contents.start_ns
    bar = tqdm(total=total, unit="msg", desc=contents.path.name, disable=not progress or None, leave=False)
    for k, (topic, message) in enumerate(iter_messages(contents, wanted, log_time_order=False)):
        t = (message.log_time - t0) * 1e-9
        m = decoders.decode(topic, message.data)
        name = by_topic.get(topic.name)
        if name is not None:
            rows[name].append(COLUMNS[name][1](m))
            times[name].append(t)
            if name == "stats":
                data.task_stats.append((t, list(m.tasks)))
        elif topic.name in KEEP:
            data.kept[KEEP[topic.name]] = m
        else:
            data.events.setdefault(EVENTS[topic.name], []).append((t, m))
        if k % 2000 == 0:
            bar.update(2000 if k else 1)
    bar.close()
    for name in COLUMNS:
        order = np.argsort(times[name], kind="stable") if times[name] else []
        data.series[name] = _series(name, [times[name][i] for i in order], [rows[name][i] for i in order])
    for name in data.events:
        data.events[name].sort(key=lambda item: item[0])
    data.task_stats.sort(key=lambda item: item[0])
    return data
