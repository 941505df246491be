"""Shared workload for the executive benchmarks: a GNC core in flight with fresh inputs.

Not a benchmark itself. `flying_core()` returns a GncCore holding position at 5 m (AUTO,
HOLD, in the air) whose inputs look like a hovering vehicle, so every cascade stage does its
full work each time it runs; `refresh(core, now)` re-stamps the inputs for the next tick.
`busy(us)` is a synthetic CPU load (a user module of a given execution time).
"""

from __future__ import annotations

import time

import yaml

from c4d_common.airframe import default_airframe_path, load_airframe
from c4d_gnc.core_config import default_config_path
from c4d_gnc.gnc import GncCore, Landed, Mode, Nav, StateSample

CORE_YAML = default_config_path()  # the airframes moved to c4d_common; core.yaml stays with c4d_gnc


def core_executive_config() -> dict:
    return yaml.safe_load(CORE_YAML.read_text())["executive"]


def flying_core(tick_s: float) -> GncCore:
    core = GncCore(load_airframe(default_airframe_path("quad_x")), tick_s)
    refresh(core, time.monotonic())
    core.out.armed, core.out.mode, core.out.nav, core.out.landed = True, Mode.AUTO, Nav.HOLD, Landed.IN_AIR
    core.hold = (0.0, 0.0, 5.0)
    return core


def refresh(core: GncCore, now: float) -> None:
    core.inputs.now = now
    core.inputs.state = StateSample(now, (0.01, -0.02, 4.98), (0.0, 0.01, 0.0), (1.0, 0.0, 0.0, 0.0), (0.001, 0.0, 0.0))
    core.inputs.gyro, core.inputs.gyro_stamp = (0.001, -0.002, 0.0), now


def busy(microseconds: float) -> None:
    end = time.perf_counter_ns() + int(microseconds * 1000)
    while time.perf_counter_ns() < end:
        pass
