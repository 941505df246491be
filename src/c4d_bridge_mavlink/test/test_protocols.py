"""Bridge protocol logic without ROS: frames and modes, mission and parameter microservices,
command translation, and a fuzz run of ≥ 100 000 hostile frames through the real UDP endpoint."""

from __future__ import annotations

import math
import random
import socket
import time

import pytest

from c4d_bridge_mavlink import frames
from c4d_bridge_mavlink.commands import Context, translate
from c4d_bridge_mavlink.mission_protocol import MISSION, MissionServer, WireItem
from c4d_bridge_mavlink.params import ParamServer
from c4d_bridge_mavlink.signing import mavlink as M
from c4d_bridge_mavlink.transport import Router
from c4d_common import quat
from c4d_common.vehicle import MissionAction, Mode, Nav, VehicleCommandId

GCS = M.MAVLink(None, 255, 190)


def from_gcs(msg):
    """A message as the vehicle would decode it (source ids set)."""
    return M.MAVLink(None, 1, 1).decode(bytearray(msg.pack(GCS)))


# ---------------------------------------------------------------- frames and modes
def test_enu_flu_to_ned_frd():
    assert frames.enu_to_ned((1.0, 2.0, 3.0)) == (2.0, 1.0, -3.0)
    assert frames.flu_to_frd((1.0, 2.0, 3.0)) == (1.0, -2.0, -3.0)
    north_level = quat.from_euler(0.0, 0.0, math.pi / 2)  # ENU yaw 90° = facing north
    assert all(abs(a) < 1e-9 for a in quat.to_euler(frames.attitude_to_ned(north_level)))
    roll, pitch, yaw = quat.to_euler(frames.attitude_to_ned(quat.from_euler(math.radians(10), math.radians(5), 0.0)))
    assert roll == pytest.approx(math.radians(10)) and pitch == pytest.approx(math.radians(-5))  # FLU pitch+ = nose down
    assert yaw == pytest.approx(math.pi / 2)  # facing east
    assert frames.compass_heading_deg(quat.from_euler(0, 0, 0.0)) == pytest.approx(90.0)


def test_px4_custom_modes():
    assert frames.mode_name(frames.px4_custom_mode(Mode.AUTO, Nav.HOLD)) == "AUTO.LOITER"
    assert frames.mode_name(frames.px4_custom_mode(Mode.AUTO, Nav.LAND)) == "AUTO.LAND"
    assert frames.mode_name(frames.px4_custom_mode(Mode.POSITION, 0)) == "POSCTL"
    assert frames.decode_px4_mode(frames.px4_custom_mode(Mode.AUTO, Nav.RTL)) == (4, 5)


# ---------------------------------------------------------------- mission protocol
class MissionHarness:
    def __init__(self, **kw) -> None:
        self.out: list = []
        self.uploads: list = []
        self.server = MissionServer(self.out.append, on_upload=lambda t, items: self.uploads.append((t, items)),
                                    on_clear=lambda t: M.MAV_MISSION_ACCEPTED, on_set_current=lambda seq: seq < 3, **kw)

    def send(self, msg, now=0.0):
        self.server.handle(from_gcs(msg), now)

    def last(self, kind):
        return next(m for m in reversed(self.out) if m.get_type() == kind)


def item(seq, lat=43.5, lon=1.48):
    return M.MAVLink_mission_item_int_message(1, 1, seq, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, 16, 0, 1, 0, 1, 0, math.nan,
                                              int(lat * 1e7), int(lon * 1e7), 5.0, MISSION)


def test_upload_sequencing_acceptance_and_download():
    h = MissionHarness()
    h.send(M.MAVLink_mission_count_message(1, 1, 3, MISSION))
    assert h.last("MISSION_REQUEST_INT").seq == 0
    h.send(item(0))
    h.send(item(2))  # ahead of sequence: the expected one is requested again
    assert h.last("MISSION_REQUEST_INT").seq == 1
    h.send(item(1))
    h.send(item(2))
    assert len(h.uploads) == 1 and len(h.uploads[0][1]) == 3 and h.uploads[0][1][1].params[4] == pytest.approx(43.5)
    assert not any(m.get_type() == "MISSION_ACK" for m in h.out)  # waits for the mission node's verdict
    h.server.finish_upload(M.MAV_MISSION_ACCEPTED)
    assert h.last("MISSION_ACK").type == M.MAV_MISSION_ACCEPTED and len(h.server.stored[MISSION]) == 3
    h.send(M.MAVLink_mission_request_list_message(1, 1, MISSION))
    assert h.last("MISSION_COUNT").count == 3
    h.send(M.MAVLink_mission_request_int_message(1, 1, 1, MISSION))
    got = h.last("MISSION_ITEM_INT")
    assert got.seq == 1 and got.x == int(43.5 * 1e7) and got.z == 5.0
    h.send(M.MAVLink_mission_request_int_message(1, 1, 7, MISSION))
    assert h.last("MISSION_ACK").type == M.MAV_MISSION_INVALID_SEQUENCE


def test_rejected_upload_keeps_the_stored_plan_and_timeouts_cancel():
    h = MissionHarness(timeout_s=1.0, retries=2)
    h.server.stored[MISSION] = [WireItem(16, 6, (0, 1, 0, 0, 1.0, 2.0, 3.0))]
    h.send(M.MAVLink_mission_count_message(1, 1, 1, MISSION))
    h.send(item(0))
    h.server.finish_upload(M.MAV_MISSION_INVALID)
    assert h.last("MISSION_ACK").type == M.MAV_MISSION_INVALID and h.server.stored[MISSION][0].params[4] == 1.0
    h.send(M.MAVLink_mission_count_message(1, 1, 2, MISSION), now=10.0)
    requests = lambda: sum(m.get_type() == "MISSION_REQUEST_INT" for m in h.out)  # noqa: E731
    before = requests()
    for t in (11.1, 12.2, 13.3):
        h.server.poll(t)
    assert requests() == before + 2  # two retries, then cancelled
    assert h.last("MISSION_ACK").type == M.MAV_MISSION_OPERATION_CANCELLED and h.server.transfer is None
    h.send(M.MAVLink_mission_count_message(1, 1, 10_000, MISSION))
    assert h.last("MISSION_ACK").type == M.MAV_MISSION_NO_SPACE
    h.send(item(0))  # an item with no transfer running
    assert h.last("MISSION_ACK").type == M.MAV_MISSION_ERROR
    h.send(M.MAVLink_mission_count_message(1, 1, 1, M.MAV_MISSION_TYPE_RALLY))
    assert h.last("MISSION_ACK").type == M.MAV_MISSION_UNSUPPORTED


# ---------------------------------------------------------------- parameters
def test_parameters_bounds_types_and_persistence(tmp_path):
    out: list = []
    store = tmp_path / "params.yaml"
    applied: list = []
    server = ParamServer(out.append, store, apply=lambda node, entries, done: (
        applied.extend((spec.ros_names[0], v) for spec, v in entries), done([(True, "")] * len(entries))))
    server.handle(from_gcs(M.MAVLink_param_request_list_message(1, 1)))
    assert len(out) == len(server.table) and out[0].param_count == len(server.table)
    server.handle(from_gcs(M.MAVLink_param_set_message(1, 1, b"MPC_XY_CRUISE", 99.0, M.MAV_PARAM_TYPE_REAL32)))
    assert out[-2].get_type() == "PARAM_ERROR" and out[-2].error == M.MAV_PARAM_ERROR_VALUE_OUT_OF_RANGE
    server.pump(0.0)
    assert out[-1].param_value == 5.0 and not store.exists()
    server.handle(from_gcs(M.MAVLink_param_set_message(1, 1, b"MPC_XY_CRUISE", float("nan"), M.MAV_PARAM_TYPE_REAL32)))
    assert out[-2].get_type() == "PARAM_ERROR"
    server.handle(from_gcs(M.MAVLink_param_set_message(1, 1, b"NO_SUCH", 1.0, M.MAV_PARAM_TYPE_REAL32)))
    assert out[-1].error == M.MAV_PARAM_ERROR_DOES_NOT_EXIST
    server.handle(from_gcs(M.MAVLink_param_set_message(1, 1, b"SIM_WIND_GUST", 3.0, M.MAV_PARAM_TYPE_REAL32)))
    server.pump(1.0)
    assert applied == [("fault.wind_gust_m_s", 3.0)] and out[-1].param_value == 3.0
    import struct

    bytewise = struct.unpack("<f", struct.pack("<i", 7))[0]  # INT32 bytewise in the float field
    server.handle(from_gcs(M.MAVLink_param_set_message(1, 1, b"SYSID_THISMAV", bytewise, M.MAV_PARAM_TYPE_INT32)))
    assert server.get("SYSID_THISMAV") == 7
    server.pump(2.0)
    again = ParamServer(out.append, store)
    assert again.get("SIM_WIND_GUST") == 3.0 and again.get("SYSID_THISMAV") == 7 and again.load_errors == []
    store.write_text("MPC_XY_CRUISE: 1000\n: [")
    assert ParamServer(out.append, store).load_errors and ParamServer(out.append, store).get("MPC_XY_CRUISE") == 5.0


# ---------------------------------------------------------------- commands
def cmd_long(command, *p):
    p = list(p) + [0.0] * (7 - len(p))
    return from_gcs(M.MAVLink_command_long_message(1, 1, command, 0, *p))


def test_command_translation():
    ctx = Context(home=(43.5, 1.48, 146.0), takeoff_altitude=5.0)
    arm = translate(cmd_long(M.MAV_CMD_COMPONENT_ARM_DISARM, 1, 21196), ctx)
    assert arm.kind == "vehicle" and arm.fields == {"command": VehicleCommandId.ARM, "force": True}
    assert translate(cmd_long(M.MAV_CMD_COMPONENT_ARM_DISARM, 3), ctx).result == M.MAV_RESULT_DENIED
    takeoff = translate(cmd_long(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, math.nan, math.nan, 156.0), ctx)
    assert takeoff.fields == {"command": VehicleCommandId.TAKEOFF, "altitude": pytest.approx(10.0)}  # AMSL 156 − home 146
    assert translate(cmd_long(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, math.nan), ctx).fields["altitude"] == 5.0
    assert translate(cmd_long(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 9999.0), ctx).result == M.MAV_RESULT_DENIED
    rtl = translate(cmd_long(M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 4, 5), ctx)
    assert rtl.fields == {"command": VehicleCommandId.RETURN_TO_LAUNCH}
    assert translate(cmd_long(M.MAV_CMD_DO_SET_MODE, 0, 4, 5), ctx).result == M.MAV_RESULT_DENIED
    mission = translate(cmd_long(M.MAV_CMD_DO_SET_MODE, 1, 4, 4), Context(ctx.home, 5.0, mission_paused=True))
    assert mission.kind == "mission" and mission.fields["action"] == MissionAction.RESUME
    repo = translate(from_gcs(M.MAVLink_command_int_message(1, 1, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                                                            M.MAV_CMD_DO_REPOSITION, 0, 0, -1, 0, 0, 90.0,
                                                            435001000, 14801000, 7.0)), ctx)
    assert repo.fields["command"] == VehicleCommandId.GOTO and repo.fields["latitude"] == pytest.approx(43.5001)
    assert repo.fields["altitude"] == 7.0 and repo.fields["yaw"] == pytest.approx(0.0)  # compass 90° = ENU 0
    assert translate(cmd_long(M.MAV_CMD_DO_REPOSITION, -1, 0, 0, 0, math.nan, 1.0, 10.0), ctx).result == M.MAV_RESULT_DENIED
    assert translate(cmd_long(31999), ctx).result == M.MAV_RESULT_UNSUPPORTED
    assert translate(cmd_long(M.MAV_CMD_SET_MESSAGE_INTERVAL, math.inf, 1), ctx).result == M.MAV_RESULT_DENIED


# ---------------------------------------------------------------- fuzz
def test_fuzz_100k_hostile_frames_no_crash_no_state_change(tmp_path):
    """≥ 100 000 frames over real UDP: random bytes, truncated and bit-flipped valid frames,
    wrong lengths, unknown ids, and valid frames with absurd values. Nothing raises, the stored
    mission and the parameters never change, absurd requests get their NACKs."""
    rng = random.Random(4)
    out: list = []
    params = ParamServer(out.append, tmp_path / "p.yaml")
    h = MissionHarness()
    h.server.stored[MISSION] = [WireItem(16, 6, (0, 1, 0, 0, 1.0, 2.0, 3.0))]
    before_params, before_mission = dict(params.values), list(h.server.stored[MISSION])
    absurd = [
        M.MAVLink_param_set_message(1, 1, b"MPC_XY_CRUISE", float("inf"), M.MAV_PARAM_TYPE_REAL32),
        M.MAVLink_param_set_message(1, 1, b"GF_MAX_HOR_DIST", -1e30, M.MAV_PARAM_TYPE_REAL32),
        M.MAVLink_param_set_message(1, 1, b"\xff\xfe", 1.0, M.MAV_PARAM_TYPE_REAL32),
        M.MAVLink_mission_item_int_message(1, 1, 60000, 99, 65535, 0, 1, math.nan, math.inf, 0, 0, 2**31 - 1, -2**31, 1e38),
        M.MAVLink_mission_request_int_message(1, 1, 65535, MISSION),
        M.MAVLink_command_long_message(1, 1, M.MAV_CMD_NAV_TAKEOFF, 0, math.nan, math.inf, 0, 0, 0, 0, 1e30),
        M.MAVLink_command_long_message(1, 1, M.MAV_CMD_DO_SET_MODE, 0, 255, 255, 255, 0, 0, 0, 0),
        M.MAVLink_command_int_message(1, 1, 200, M.MAV_CMD_DO_REPOSITION, 0, 0, 0, 0, 0, 0, 2**31 - 1, 2**31 - 1, math.nan),
        M.MAVLink_param_request_read_message(1, 1, b"", 30000),
    ]
    valid = [m.pack(GCS) for m in absurd]
    ctx = Context(home=(43.5, 1.48, 146.0), takeoff_altitude=5.0)
    nacks = {"command": 0, "param": 0, "mission": 0}
    with Router(["udpin:127.0.0.1:0"]) as router:
        port = router.endpoints["udpin:127.0.0.1:0"].local_address[1]
        sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sent = handled = sent_bytes = 0
        t0 = time.monotonic()
        while sent < 100_000:
            for _ in range(50):
                kind = rng.random()
                frame = bytearray(rng.choice(valid))
                if kind < 0.25:
                    frame = bytearray(rng.randbytes(rng.randint(1, 280)))
                elif kind < 0.45:
                    frame[rng.randrange(len(frame))] ^= 1 << rng.randrange(8)  # bad CRC (or a broken header)
                elif kind < 0.6:
                    frame = frame[: rng.randrange(1, len(frame))]  # truncated
                elif kind < 0.7:
                    frame[1] = rng.randrange(256)  # wrong payload length
                elif kind < 0.8:
                    frame[7:10] = rng.randrange(1 << 24).to_bytes(3, "little")  # unknown / other message id
                sender.sendto(bytes(frame), ("127.0.0.1", port))
                sent += 1
                sent_bytes += len(frame)
            while batch := router.poll(0.005):  # drain all: nothing may be lost in the socket buffer
                for received in batch:
                    handled += 1
                    msg = received.message
                    kind = msg.get_type()
                    if kind.startswith("MISSION_"):
                        h.server.handle(msg, 0.0)
                    elif kind.startswith("PARAM_"):
                        n = len(out)
                        params.handle(msg)
                        nacks["param"] += any(m.get_type() == "PARAM_ERROR" for m in out[n:])
                    elif kind in ("COMMAND_LONG", "COMMAND_INT"):
                        action = translate(msg, ctx)
                        nacks["command"] += action.kind == "ack" and action.result != M.MAV_RESULT_ACCEPTED
        handled += len(router.poll(0.2))
        stats = router.stats()["udpin:127.0.0.1:0"]
        errors = stats.rx_errors
        sender.close()
    nacks["mission"] = sum(m.get_type() == "MISSION_ACK" and m.type != M.MAV_MISSION_ACCEPTED for m in h.out)
    print(f"\nfuzz: {sent} frames in {time.monotonic() - t0:.1f} s, {handled} decoded and handled, {errors} parse errors "
          f"counted, NACKs {nacks}")
    assert params.values == before_params and h.server.stored[MISSION] == before_mission
    assert stats.rx_bytes == sent_bytes  # every datagram reached the parser
    assert handled > 10_000 and errors > 30_000
    assert nacks["param"] > 0 and nacks["command"] > 0 and nacks["mission"] > 0


def test_pilot_sticks_to_setpoints():
    from c4d_bridge_mavlink.manual import MAX_RATE, MAX_TILT, pilot_setpoint, stick_thrust

    sp = pilot_setpoint(x=500, y=1000, z=500, r=0, mode="attitude", yaw=0.3, hover=0.4)
    roll, pitch, yaw = quat.to_euler(sp.orientation)
    assert roll == pytest.approx(MAX_TILT) and pitch == pytest.approx(MAX_TILT / 2) and yaw == pytest.approx(0.3)
    nose = quat.rotate(sp.orientation, (1.0, 0.0, 0.0))
    assert nose[2] < 0  # forward stick: nose down
    assert sp.thrust == pytest.approx(0.4) and stick_thrust(0, 0.4) == 0.0 and stick_thrust(1000, 0.4) == 1.0
    assert stick_thrust(750, 0.4) == pytest.approx(0.7) and stick_thrust(float("nan"), 0.4) == pytest.approx(0.4)
    right = pilot_setpoint(0, 0, 500, 1000, "attitude", 0.0, 0.4)
    assert right.yaw_rate < 0  # yaw right = clockwise = negative ENU yaw rate
    rate = pilot_setpoint(0, -1000, 500, 0, "rate", 0.0, 0.4)
    assert rate.level == "rate" and rate.body_rate[0] == pytest.approx(-MAX_RATE)
    assert pilot_setpoint(float("inf"), 5000, -3, 0, "attitude", 0.0, 0.4).thrust == 0.0  # clamped, never NaN
