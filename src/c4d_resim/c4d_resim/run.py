"""One re-simulation: load, override, run navigation and core, compare with the recording, write the MCAP.

Comparison is per sample key — navigation/state by its stamp, control/actuators by its tick index —
byte for byte (bit-identical means the same CDR bytes), with the physical differences kept for the
report (position, velocity, yaw; motor commands) and the first divergence of each stream.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from c4d_data.bag_writer import BagWriter
from c4d_gnc import journal as jr
from c4d_gnc import wire
from c4d_interfaces.msg import ActuatorCommand
from c4d_ros import cdr

from . import overrides
from .engine import CoreRun, Counts, JournalEnd, core_ticks, navigation
from .flight import ACTUATORS, STATE, Flight, load
from .pipeline import NavigationProcess, usable_cpus


def same_cdr(new: bytes, old: bytes) -> bool:
    """The same serialized message: byte for byte, the recorded one possibly followed by the 1-3 zero bytes DDS
    pads a payload with to a multiple of 4 on the wire (navigation/state's 518 bytes are recorded as 520)."""
    return new == old or (0 < len(old) - len(new) < 4 and len(old) % 4 == 0 and old.startswith(new)
                          and not any(old[len(new):]))


PLOT_EVERY = 10  # identical samples decoded for the report's trajectory: one in 10


@dataclass
class Stream:
    """Per-sample comparison of one regenerated topic with the recorded one.

    `add` only compares bytes (the re-simulation loop's share); the samples the report plots — every differing
    one, one identical in PLOT_EVERY — are kept raw and decoded by `finish()`, after the loop is timed."""

    name: str
    values: Callable[[bytes], tuple[float, ...]]  # a serialized sample's physical values (for plots, differences)
    compared: int = 0
    identical: int = 0
    only_resim: int = 0  # regenerated samples the recording lacks (recorder drops on best-effort topics)
    first_divergence: float | None = None  # [s] key time of the first differing sample
    first_key: int | None = None
    t: list[float] = field(default_factory=list)  # [s] of each compared sample
    diff: list[float] = field(default_factory=list)  # physical difference (m or command units)
    recorded: list[tuple[float, ...]] = field(default_factory=list)  # values (every differing sample, 1 in 10 else)
    resim: list[tuple[float, ...]] = field(default_factory=list)
    _kept: list[tuple[int, bytes, bytes | None]] = field(default_factory=list)  # (diff index, recorded, new or None)

    def add(self, key: int, t: float, new: bytes, old: bytes | None) -> None:
        if old is None:
            self.only_resim += 1
            return
        self.compared += 1
        self.t.append(t)
        self.diff.append(0.0)
        if same_cdr(new, old):
            self.identical += 1
            if self.compared % PLOT_EVERY == 1:  # identical: decoded for the trajectory plot only now and then
                self._kept.append((-1, old, None))
            return
        self._kept.append((len(self.diff) - 1, old, new))
        if self.first_divergence is None:
            self.first_divergence, self.first_key = t, key

    def finish(self) -> None:
        """Decode the kept samples: the plotted values and the differing samples' differences."""
        for i, old, new in self._kept:
            a = self.values(old)
            b = a if new is None else self.values(new)
            self.recorded.append(a)
            self.resim.append(b)
            if i >= 0:
                self.diff[i] = max((abs(x - y) for x, y in zip(a, b, strict=True)), default=0.0)
        self._kept.clear()

    @property
    def max_diff(self) -> float:
        return max(self.diff, default=0.0)


@dataclass
class Result:
    flight: Flight
    overrides: list[str]
    state: Stream
    actuators: Stream
    counts: Counts
    nav_start_s: float
    core_start_s: float
    end_s: float
    wall_s: float
    nav_wall_s: float
    output: Path | None
    modes_recorded: list[tuple[bool, int, int]] = field(default_factory=list)  # (armed, mode, nav) changes
    modes_resim: list[tuple[bool, int, int]] = field(default_factory=list)
    processes: int = 1  # 2: navigation ran in a second process (nav_wall_s: its busy time, overlapping wall_s)

    @property
    def flight_s(self) -> float:
        return self.end_s - self.core_start_s

    @property
    def exact(self) -> bool:
        return (self.state.compared > 0 and self.state.identical == self.state.compared
                and self.actuators.identical == self.actuators.compared > 0)


def state_values(raw: bytes) -> tuple[float, ...]:
    s = wire.state_from_cdr(raw)
    return (*s.position, *s.velocity)


def actuator_values(raw: bytes) -> tuple[float, ...]:
    """The motor commands of a serialized ActuatorCommand (c4d_ros.cdr: ~1 µs, not ~30 µs deserializing)."""
    v = cdr.ACTUATOR_COMMAND.unpack(raw, ActuatorCommand)
    return tuple(v[7:7 + v[6]])


def _status_changes(flight: Flight) -> list[tuple[bool, int, int]]:
    from rclpy.serialization import deserialize_message

    from c4d_interfaces.msg import VehicleStatus

    out: list[tuple[bool, int, int]] = []
    for _, raw in flight.logged["/vehicle/status"]:
        m = deserialize_message(raw, VehicleStatus)
        key = (bool(m.armed), int(m.flight_mode), int(m.nav_state))
        if not out or out[-1] != key:
            out.append(key)
    return out


def resimulate(path: str | Path, assignments: list[str] | None = None, window: tuple[float, float] | None = None,
               output: str | Path | None = None, processes: int | None = None) -> Result:
    """Re-simulate `path`; BagError / FlightError / OverrideError (one line) for unusable input.
    `window`: (from, to) [s after the core's snapshot] of the samples compared and written.
    `processes`: 1 runs navigation and the core in this process, 2 navigation in a second one
    (c4d_resim.pipeline; same bytes); None: 2 when this process may use two CPUs or more."""
    if processes is None:
        processes = 2 if usable_cpus() >= 2 else 1
    if processes not in (1, 2):
        raise ValueError(f"processes must be 1 or 2, got {processes}")
    flight = load(path)
    parsed = overrides.parse(assignments or [])
    nav_snap, core_snap = flight.nav.snapshot, flight.core.snapshot
    filt, run = nav_snap["filter"], CoreRun.from_snapshot(core_snap)
    for node, name, text in parsed:
        if node == "navigation":
            overrides.apply_navigation(filt, nav_snap.get("params", {}), name, text)
        else:
            overrides.apply_core(run, core_snap["params"], core_snap.get("ranges", {}), name, text)
    counts = Counts()
    recorded_states = {jr.cdr_stamp_ns(raw): raw for _, raw in flight.logged[STATE]}
    recorded_ticks = {}
    for _, raw in flight.logged[ACTUATORS]:
        recorded_ticks[_tick_of(raw)] = raw
    nav_first = _first_imu(flight)
    regenerated: dict[int, bytes] = {}
    state_stream, act_stream = Stream(STATE, state_values), Stream(ACTUATORS, actuator_values)
    core_start = core_snap["core"].inputs.now
    lo, hi = (core_start + window[0], core_start + window[1]) if window else (-math.inf, math.inf)
    writer = _writer(flight, output) if output else None
    child = NavigationProcess(flight, filt, counts) if processes == 2 else None
    nav_iter = iter(child) if child else navigation(flight, filt, counts)
    nav_wall = [0.0]  # processes 1: navigation's share of the wall time (2: the child's busy time, below)

    def advance() -> int | None:
        """One more re-simulated navigation/state: compared, written; its stamp (None: the journal ended)."""
        t0 = time.perf_counter()
        item = next(nav_iter, None)
        nav_wall[0] += time.perf_counter() - t0
        if item is None:
            return None
        key, raw = item
        regenerated[key] = raw
        t = jr.stamp_s(key)
        if lo <= t <= hi:
            state_stream.add(key, t, raw, recorded_states.get(key))
            if writer:
                writer.write(STATE, raw, key, key)
        return key

    def pull_until(ns: int) -> bytes | None:
        if ns < nav_first:
            return recorded_states.get(ns)  # before navigation's snapshot: what it published
        while ns not in regenerated:
            if advance() is None:
                raise JournalEnd
        raw = regenerated[ns]
        for old in [k for k in regenerated if k <= ns]:  # the core reads forward in time: older ones are done
            del regenerated[old]
        return raw

    start = time.perf_counter()
    end_s = core_start
    out = run.core.out
    modes: list[tuple[bool, int, int]] = []
    try:
        try:
            for k, now_ns, raw in core_ticks(flight, run, pull_until, counts):
                t = now_ns * 1e-9
                end_s = t
                key = (bool(out.armed), int(out.mode), int(out.nav))
                if not modes or modes[-1] != key:
                    modes.append(key)
                if lo <= t <= hi:
                    act_stream.add(k, t, raw, recorded_ticks.get(k))
                    if writer:
                        writer.write(ACTUATORS, raw, now_ns, now_ns)
        except JournalEnd:
            pass  # the core's journal goes on a few ticks past navigation's in the file: stop where the states end
        while advance() is not None:  # navigation's samples after the core's last journalled tick
            pass
        wall = time.perf_counter() - start
    finally:
        if child:
            child.close()
    if child:
        nav_wall[0] = child.busy_s
    state_stream.finish()
    act_stream.finish()
    if writer:
        writer.close()
    return Result(flight, list(assignments or []), state_stream, act_stream, counts, jr.stamp_s(nav_first),
                  core_start, end_s, wall, nav_wall[0], Path(output) if output else None, _status_changes(flight), modes,
                  processes)


def _tick_of(raw: bytes) -> int:
    v = cdr.ACTUATOR_COMMAND.unpack(raw, ActuatorCommand)
    return int(v[7 + v[6]])


def _first_imu(flight: Flight) -> int:
    for payload in (p for _, p in flight.nav.batches):
        for rec in jr.records(payload):
            if rec[0] == jr.N_IMU:
                return rec[1]
    return 1 << 62


def _writer(flight: Flight, output: str | Path) -> BagWriter:
    """A rosbag2 MCAP with every recorded topic; navigation/state and control/actuators are re-simulated."""
    w = BagWriter(output, custom_data={"c4d.resim_of": str(flight.path)})
    for name, topic in flight.topics.items():
        schema = topic.schema
        w.add_topic(name, topic.type_name, schema.data.decode() if schema else "", topic.offered_qos, topic.type_hash)
    for name, log, pub, raw in flight.others:
        w.write(name, raw, log, pub)
    return w
