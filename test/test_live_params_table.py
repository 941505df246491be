"""The live-parameter tables agree with each other and with the docs (no graph, < 2 s):

- every MAVLink parameter mapped onto the core names one of the core's live tunables, with the
  same bounds and the bundled quad_x airframe's value as default (the bridge cannot import
  c4d_gnc, so this is where a drifting copy is caught);
- every core tunable is reachable from MAVLink, except the few listed; the same for the
  navigation's EKF noises and the health's thresholds (their per-event delays are ROS-only);
- the core's table round-trips the airframe (airframe_with(af, values(af)) == af) and a change
  lands in the right field; the cross-field rules refuse sets that would not fly;
- docs/parameters.md's generated tables are those of the code (tools/parameters_doc.py --check);
- the per-vehicle store: atomic write, restore skipping bad entries, reset; the deferred writer.
"""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

from c4d_bridge_mavlink.params import TABLE
from c4d_common.airframe import default_airframe_path, load_airframe
from c4d_common.tunable import DeferredWriter, PendingChanges, TunableError, VehicleStore, vehicle_dir
from c4d_gnc.live_gains import airframe_values, airframe_with, core_table

ROOT = Path(__file__).resolve().parent.parent
QUAD = load_airframe(default_airframe_path("quad_x"))


def test_mavlink_core_entries_match_the_core_table():
    table = core_table(QUAD)
    mapped = set()
    for spec in (p for p in TABLE if p.node == "core"):
        assert spec.live
        for ros in spec.ros_names:
            assert ros in table, f"{spec.name}: core has no parameter {ros}"
            t = table.items[ros]
            assert (spec.minimum, spec.maximum) == (t.low, t.high), f"{spec.name} bounds differ from {ros}'s"
            assert math.isclose(spec.default, t.default, rel_tol=1e-9), f"{spec.name} default differs from quad_x {ros}"
            mapped.add(ros)
    assert set(table.items) - mapped == set(), sorted(set(table.items) - mapped)


def test_mavlink_navigation_and_health_entries_match_their_tables():
    """EKF2_* / BAT_* / COM_OF_LOSS_T and the C4D_* ones: live, on the node that owns them, same
    bounds, the default EKF configuration's (drag from quad_x, the node's default) / the bundled failsafe
    policy's values; every EKF tunable and every top-level policy threshold is reachable (the per-event delays are ROS-only)."""
    from c4d_gnc.ekf import drag_config
    from c4d_gnc.live_navigation import navigation_table
    from c4d_health.health_node import default_policy
    from c4d_health.live_policy import policy_table
    from c4d_health.policy import FailsafePolicy

    navigation = navigation_table(drag_config(QUAD))
    tables = {"navigation": navigation, "health": policy_table(FailsafePolicy.from_yaml(default_policy()))}
    for node, table in tables.items():
        mapped = set()
        for spec in (p for p in TABLE if p.node == node):
            assert spec.live and len(spec.ros_names) == 1 and len(spec.name) <= 16
            t = table.items[spec.ros_names[0]]
            assert (spec.minimum, spec.maximum) == (t.low, t.high), f"{spec.name} bounds differ from {t.name}'s"
            assert math.isclose(spec.default, t.default, rel_tol=1e-9), f"{spec.name} default differs from {t.name}"
            mapped.add(t.name)
        unmapped = {n for n in set(table.items) - mapped if not n.startswith("events.")}
        assert unmapped == set(), (node, sorted(unmapped))
    names = {p.name for p in TABLE}
    assert {"EKF2_GPS_P_GATE", "EKF2_BARO_NOISE", "EKF2_HEAD_NOISE", "BAT_LOW_THR", "BAT_CRIT_THR",
            "COM_OF_LOSS_T"} <= names
    assert len(names) == len(TABLE)  # ids are unique


def test_core_table_round_trip_and_cross_rules():
    values = airframe_values(QUAD)
    assert airframe_with(QUAD, values) == QUAD
    tuned = airframe_with(QUAD, {"gains.rate.roll.p": 44.0, "limits.max_tilt_deg": 20.0, "gains.velocity.z.i_limit": 1.0})
    assert tuned.rate.p == (44.0, 22.0, 12.0) and math.isclose(tuned.max_tilt, math.radians(20.0))
    assert tuned.velocity.i_limit[2] == 1.0 and tuned.mass == QUAD.mass
    table = core_table(QUAD)
    assert table.check({"limits.min_thrust_ratio": 0.96}, values).startswith("limits.min_thrust_ratio (0.96) must be below")
    assert "to hover" in table.check({"limits.max_thrust_ratio": 0.4}, values)
    assert "not finite" in table.check({"gains.rate.roll.p": math.nan}, values)
    assert "expected a number" in table.check({"gains.rate.roll.p": "x"}, values)
    assert "no such parameter" in table.check({"gains.nope": 1.0}, values)
    pending = PendingChanges(table, values)  # two batches of one tick checked together
    assert pending.submit({"limits.max_thrust_ratio": 0.5}) == ""
    assert "must be below" in pending.submit({"limits.min_thrust_ratio": 0.6})
    assert pending.take() == {"limits.max_thrust_ratio": 0.5} and pending.take() == {}


def test_docs_tables_are_generated_from_the_code():
    result = subprocess.run([sys.executable, str(ROOT / "tools" / "parameters_doc.py"), "--check"],
                            capture_output=True, text=True, check=False)
    assert result.returncode == 0, result.stderr


def test_vehicle_store(tmp_path):
    env = {"XDG_DATA_HOME": str(tmp_path)}
    assert vehicle_dir("quad-7", env) == tmp_path / "c4d" / "vehicles" / "quad-7"
    for bad in ("", "../x", "a/b", "x" * 65):
        try:
            vehicle_dir(bad, env)
            raise AssertionError(bad)
        except TunableError:
            pass
    table = core_table(QUAD)
    store = VehicleStore.of("quad-7", "core", env)
    store.update({"gains.rate.roll.p": 30.0}, table.defaults())
    store.update({"gains.rate.roll.p": 22.0, "gains.attitude.roll.p": 7.0}, table.defaults())  # back to default: dropped
    assert store.read() == {"gains.attitude.roll.p": 7.0}
    assert not list(store.path.parent.glob(".*.tmp"))
    store.path.write_text("gains.attitude.roll.p: 7.0\ngains.rate.roll.p: 9999\nbogus: 1\n")
    restored, problems = store.restore(table, table.defaults())
    assert restored == {"gains.attitude.roll.p": 7.0} and len(problems) == 2
    store.path.write_text(": [")
    assert store.restore(table, table.defaults())[0] == {}
    writer = DeferredWriter(store)
    for k in range(100):
        writer.submit({"gains.rate.roll.p": 20.0 + k})
    assert writer.flush()
    assert store.read() == {"gains.rate.roll.p": 119.0}
    assert store.reset() and not store.path.exists() and not store.reset()
