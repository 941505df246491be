"""System modes and transition planning (c4d_bringup.system_modes), without ROS."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from c4d_bringup.system_config import ConfigError, parse_system_config
from c4d_bringup.system_modes import (
    ACTIVE,
    INACTIVE,
    UNCONFIGURED,
    ModesError,
    Step,
    failure_reason,
    parse_modes,
    phase_of,
    plan,
)

NODES = ("sim", "core", "mission", "payload")
SITL = Path(__file__).resolve().parents[1] / "config" / "sitl.yaml"


def test_default_modes_payload_only_in_flight():
    doc = yaml.safe_load(SITL.read_text())
    table = parse_system_config(doc, SITL, frozenset({0, 1})).mode_table()
    assert "payload" not in table.active_in("preflight") and "payload" in table.active_in("flight")
    assert "payload" not in table.active_in("landing")
    assert {"mission", "offboard"}.isdisjoint(table.active_in("maintenance")) and "core" in table.active_in("maintenance")
    assert set(table.nodes) == set(doc["nodes"])  # every bundled node is managed


def test_no_modes_section_is_every_node_active_everywhere():
    table = parse_modes(None, NODES, "x")
    assert all(table.active_in(p) == frozenset(NODES) for p in ("preflight", "flight", "landing", "maintenance"))


@pytest.mark.parametrize("doc, words", [
    ({"takeoff": {}}, "unknown phase 'takeoff'"),
    ({"flight": {"inactive": ["camera"]}}, "unknown node 'camera'"),
    ({"flight": {"active": ["core"], "inactive": ["sim"]}}, "either"),
    ({"flight": {"active": "core"}}, "must be a list"),
    ([1], "must be a mapping"),
])
def test_bad_modes_are_one_line_errors(doc, words):
    with pytest.raises(ModesError, match=words) as err:
        parse_modes(doc, NODES, "sys.yaml")
    assert "\n" not in str(err.value)


def test_bad_modes_in_the_system_yaml_are_config_errors():
    doc = yaml.safe_load(SITL.read_text())
    doc["modes"] = {"cruise": {}}
    with pytest.raises(ConfigError, match="modes: unknown phase 'cruise'"):
        parse_system_config(doc, SITL, frozenset({0, 1}))


def test_phase_of_vehicle_status():
    assert phase_of(False, 1, 0) == "preflight"
    assert phase_of(False, 2, 2) == "preflight"  # disarmed is preflight whatever else
    assert phase_of(True, 1, 1) == "flight"  # armed on the ground, taking off
    assert phase_of(True, 2, 2) == "flight"
    assert phase_of(True, 4, 2) == "landing"
    assert phase_of(True, 2, 6) == "landing" and phase_of(True, 2, 5) == "landing"


def test_plan_configures_all_then_activates_wanted_in_start_order():
    states = {n: UNCONFIGURED for n in NODES}
    steps = plan(states, {"sim", "core", "mission"}, NODES)
    assert [str(s) for s in steps] == ["configure sim", "activate sim", "configure core", "activate core",
                                       "configure mission", "activate mission", "configure payload"]


def test_plan_phase_change_deactivates_in_reverse_order_first():
    states = {"sim": ACTIVE, "core": ACTIVE, "mission": ACTIVE, "payload": INACTIVE}
    assert plan(states, {"sim", "core", "payload"}, NODES) == [Step("mission", "deactivate"), Step("payload", "activate")]
    assert plan(states, {"sim", "core", "mission"}, NODES) == []  # already there
    states["core"] = UNCONFIGURED  # restarted by the supervisor
    assert plan(states, {"sim", "core", "mission"}, NODES) == [Step("core", "configure"), Step("core", "activate")]
    assert plan({"sim": 0}, {"sim"}, ("sim",)) == []  # unknown state (no answer): left alone


def test_failure_reason_is_the_nodes_own_lifecycle_line():
    log = "\n".join([
        "[INFO] [1.0] [core]: lifecycle: configured (inactive)",
        "[ERROR] [2.0] [payload]: lifecycle: configure failed: not this node",
        "[ERROR] [3.0] [core]: something else",
        "[ERROR] [4.0] [core]: lifecycle: configure failed: core config /x.yaml: not found",
        "[WARN] [5.0] [core]: later warning",
    ])
    assert failure_reason(log, "core") == "configure failed: core config /x.yaml: not found"
    assert failure_reason("[ERROR] [3.0] [core]: something else", "core") == "something else"
    assert failure_reason(log, "health") is None
