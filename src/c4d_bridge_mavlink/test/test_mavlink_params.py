"""MAVLink parameters mapped onto live node parameters (c4d_bridge_mavlink.params): what the GCS sees
is what the node applied, a node's refusal is a PARAM_ERROR with the unchanged value, a flood is
coalesced into a few node requests, bad input is refused with a clear error."""

from __future__ import annotations

import math

from c4d_bridge_mavlink.params import TABLE, ParamServer
from c4d_bridge_mavlink.signing import mavlink as M

GCS = M.MAVLink(None, 255, 190)


def from_gcs(msg):
    return M.MAVLink(None, 1, 1).decode(bytearray(msg.pack(GCS)))


def param_set(name: str, value: float, kind: int = M.MAV_PARAM_TYPE_REAL32):
    return from_gcs(M.MAVLink_param_set_message(1, 1, name.encode(), value, kind))


class FakeNode:
    """Stands for the node's set_parameters service: records requests, answers when told."""

    def __init__(self) -> None:
        self.requests: list[tuple[str, list, object]] = []

    def __call__(self, node, entries, done) -> None:
        self.requests.append((node, [(spec.ros_names, value) for spec, value in entries], done))


def test_table_ids_types_and_full_download():
    out: list = []
    server = ParamServer(out.append, None)
    names = [p.name for p in TABLE]
    assert len(names) == len(set(names)) and all(len(n) <= 16 for n in names)
    assert {"MC_ROLLRATE_P", "MC_PITCHRATE_I", "MC_YAWRATE_D", "MC_ROLL_P", "MPC_XY_P", "MPC_Z_VEL_P_ACC",
            "MPC_XY_VEL_MAX", "MPC_Z_VEL_MAX_UP", "MPC_TKO_SPEED", "MPC_LAND_SPEED", "MIS_TAKEOFF_ALT",
            "COM_DL_LOSS_T"} <= set(names)
    server.handle(from_gcs(M.MAVLink_param_request_list_message(1, 1)))
    assert [m.param_index for m in out] == list(range(len(TABLE)))
    assert {m.param_count for m in out} == {len(TABLE)}
    assert {m.param_id for m in out} == set(names)
    out.clear()
    server.handle(from_gcs(M.MAVLink_param_request_read_message(1, 1, b"", len(TABLE))))  # index past the end
    assert out[-1].get_type() == "PARAM_ERROR" and out[-1].error == M.MAV_PARAM_ERROR_DOES_NOT_EXIST


def test_node_mapped_echo_is_what_the_node_applied(tmp_path):
    out: list = []
    node = FakeNode()
    refused: list[str] = []
    server = ParamServer(out.append, tmp_path / "p.yaml", apply=node, on_refused=refused.append)
    server.handle(param_set("MC_ROLLRATE_P", 44.0))
    assert out == []  # nothing echoed before the node answered
    server.pump(0.0)
    (name, entries, done), = node.requests
    assert name == "core" and entries == [(("gains.rate.roll.p",), 44.0)]
    done([(True, "")])
    assert out[-1].param_id == "MC_ROLLRATE_P" and out[-1].param_value == 44.0 and server.get("MC_ROLLRATE_P") == 44.0
    assert not (tmp_path / "p.yaml").exists()  # the node persists its live values, not the bridge
    # refused by the node (e.g. a cross-field rule): PARAM_ERROR, the unchanged value, the reason
    server.handle(param_set("MPC_THR_MIN", 0.97))
    server.pump(1.0)
    node.requests[-1][2]([(False, "limits.min_thrust_ratio (0.97) must be below limits.max_thrust_ratio (0.95)")])
    assert out[-2].get_type() == "PARAM_ERROR" and out[-2].error == M.MAV_PARAM_ERROR_VALUE_OUT_OF_RANGE
    assert out[-1].param_id == "MPC_THR_MIN" and math.isclose(out[-1].param_value, 0.08, rel_tol=1e-6)
    assert "must be below" in refused[-1]
    # the node does not answer
    server.handle(param_set("MC_ROLL_P", 7.0))
    server.pump(2.0)
    node.requests[-1][2](None)
    assert out[-2].error == M.MAV_PARAM_ERROR_COMPONENT_NOT_FOUND and out[-1].param_value == 9.0
    # one MAVLink parameter onto two ROS parameters
    server.handle(param_set("MPC_XY_P", 1.2))
    server.pump(3.0)
    (ros_names, value), = node.requests[-1][1]
    assert ros_names == ("gains.position.x.p", "gains.position.y.p") and math.isclose(value, 1.2, rel_tol=1e-6)


def test_bad_input_refused_without_reaching_the_node(tmp_path):
    out: list = []
    node = FakeNode()
    server = ParamServer(out.append, tmp_path / "p.yaml", apply=node)
    before = dict(server.values)
    for value in (math.nan, math.inf, -math.inf, -1.0, 1e9):
        server.handle(param_set("MC_ROLLRATE_P", value))
        assert out[-2].get_type() == "PARAM_ERROR" and out[-2].error == M.MAV_PARAM_ERROR_VALUE_OUT_OF_RANGE
        assert out[-1].param_value == 22.0
    server.handle(param_set("SYSID_THISMAV", 2.5))  # a fraction for an INT32 parameter sent as REAL32
    assert out[-2].get_type() == "PARAM_ERROR"
    server.handle(param_set("NO_SUCH_PARAM", 1.0))
    assert out[-1].get_type() == "PARAM_ERROR" and out[-1].error == M.MAV_PARAM_ERROR_DOES_NOT_EXIST
    server.handle(param_set("\xff\xfe", 1.0))
    assert out[-1].error == M.MAV_PARAM_ERROR_DOES_NOT_EXIST
    server.pump(0.0)
    assert node.requests == [] and server.values == before


def test_flood_is_coalesced_into_few_node_requests(tmp_path):
    """10 000 PARAM_SETs within one second: the node gets at most rate_hz requests (one in flight),
    each carrying only the newest value; every set is answered once the node applied it."""
    out: list = []
    node = FakeNode()
    server = ParamServer(out.append, tmp_path / "p.yaml", apply=node, rate_hz=20.0)
    for k in range(10_000):
        server.handle(param_set("MC_ROLLRATE_P", 20.0 + (k % 100) * 0.1))
        server.handle(param_set("MPC_XY_CRUISE", 3.0 + (k % 10) * 0.1))  # the bridge's own: one file write per pump
        t = k / 10_000
        server.pump(t)
        if node.requests and node.requests[-1][2] is not None:
            done = node.requests[-1][2]
            node.requests[-1] = (*node.requests[-1][:2], None)
            done([(True, "")] * len(node.requests[-1][1]))
    assert 1 <= len(node.requests) <= 21, len(node.requests)
    assert server.coalesced >= 10_000 - 21
    server.pump(2.0)
    node.requests[-1][2]([(True, "")])
    assert math.isclose(server.get("MC_ROLLRATE_P"), 29.9, rel_tol=1e-6)  # the newest value won
    assert math.isclose(server.get("MPC_XY_CRUISE"), 3.9, rel_tol=1e-6)


def test_node_values_and_announced_changes(tmp_path):
    out: list = []
    server = ParamServer(out.append, tmp_path / "p.yaml")
    server.node_values("core", {"gains.rate.roll.p": 30.0, "gains.position.x.p": 2.0, "unrelated": 1.0})
    assert server.get("MC_ROLLRATE_P") == 30.0 and server.get("MPC_XY_P") == 2.0 and out == []
    server.node_values("core", {"gains.rate.roll.p": 31.0, "gains.position.y.p": 9.0}, announce=True)
    assert [(m.param_id, m.param_value) for m in out] == [("MC_ROLLRATE_P", 31.0)]  # y follows x's entry: not read
    server.node_values("core", {"gains.rate.roll.p": math.nan}, announce=True)  # out of the table's bounds: ignored
    assert server.get("MC_ROLLRATE_P") == 31.0
    assert "gains.rate.roll.p" in server.live_names("core")
    (tmp_path / "p.yaml").write_text("MC_ROLLRATE_P: 50.0\n")  # a live value in the bridge's file: not taken
    again = ParamServer(out.append, tmp_path / "p.yaml")
    assert again.get("MC_ROLLRATE_P") == 22.0 and "kept by its node" in again.load_errors[0]
