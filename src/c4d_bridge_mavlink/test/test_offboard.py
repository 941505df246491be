"""MAVLink offboard (issue 17.7): SET_POSITION_TARGET_* / SET_ATTITUDE_TARGET → c4d setpoints,
POSITION_TARGET_LOCAL_NED back, PX4 main mode 6 both ways. Every input is a pymavlink-encoded frame
decoded as the vehicle decodes it (float32 fields, source ids), with the type masks stock
MAVSDK sends (src/mavsdk/plugins/offboard/offboard_impl.cpp)."""

from __future__ import annotations

import math

import pytest

from c4d_bridge_mavlink import encoders as enc
from c4d_bridge_mavlink import frames
from c4d_bridge_mavlink.commands import Context, translate, translate_set_mode
from c4d_bridge_mavlink.offboard import OffboardDecoder, Target, VehicleFrame, position_target_local_ned
from c4d_bridge_mavlink.signing import mavlink as M
from c4d_common import quat
from c4d_common.geodesy import GeoOrigin
from c4d_common.vehicle import Level, Mode, Nav, VehicleCommandId

GCS = M.MAVLink(None, 245, 190)
HOME = (43.5, 1.48, 146.0)
HERE = VehicleFrame((10.0, 20.0, 5.0), math.pi / 2, HOME)  # 10 m east, 20 m north, 5 m up, facing north
# MAVSDK's masks: set_velocity_ned ignores position, acceleration and yaw rate; set_position_ned velocity,
# acceleration and yaw rate; set_velocity_body position, acceleration and yaw
VEL_NED = 0b1001_1100_0111
POS_NED = 0b1001_1111_1000
VEL_BODY = 0b0101_1100_0111


def rx(msg):
    """A message as the vehicle decodes it."""
    return M.MAVLink(None, 1, 1).decode(bytearray(msg.pack(GCS)))


def local(frame, mask, x=0.0, y=0.0, z=0.0, vx=0.0, vy=0.0, vz=0.0, a=(0.0, 0.0, 0.0), yaw=0.0, yaw_rate=0.0, target=(1, 1)):
    return rx(M.MAVLink_set_position_target_local_ned_message(1234, *target, frame, mask, x, y, z, vx, vy, vz, *a, yaw,
                                                              yaw_rate))


def nan(*values) -> bool:
    return all(math.isnan(v) for v in values)


def test_mavsdk_velocity_and_position_ned_become_enu_setpoints():
    d = OffboardDecoder(1)
    t = d.decode(local(M.MAV_FRAME_LOCAL_NED, VEL_NED, 9.0, 9.0, 9.0, vx=2.0, vy=-1.0, vz=-0.5, yaw=math.radians(90)), HERE)
    assert t.level == Level.VELOCITY and nan(*t.position, *t.acceleration, t.yaw_rate)  # ignored → NaN, not 9 / 0
    assert t.velocity == pytest.approx((-1.0, 2.0, 0.5))  # north 2, west 1, climbing 0.5
    assert t.yaw == pytest.approx(0.0, abs=1e-6)  # heading 90° (east) = ENU 0
    t = d.decode(local(M.MAV_FRAME_LOCAL_NED, POS_NED, 3.0, -4.0, -6.0, yaw=math.radians(-90)), HERE)
    assert t.level == Level.POSITION and t.position == pytest.approx((-4.0, 3.0, 6.0)) and nan(*t.velocity)
    assert abs(math.remainder(t.yaw - math.pi, math.tau)) < 1e-6  # heading west
    # position x/y with a vertical velocity: POSITION level, z follows the velocity (the core's NaN-axis rule)
    t = d.decode(local(M.MAV_FRAME_LOCAL_NED, 0b1101_1101_1100, 1.0, 2.0, vz=-1.0), HERE)
    assert t.level == Level.POSITION and t.position[:2] == (2.0, 1.0) and nan(t.position[2], t.velocity[0], t.yaw)
    assert t.velocity[2] == 1.0
    t = d.decode(local(M.MAV_FRAME_LOCAL_NED, 0b1100_0011_1111, a=(0.5, 0.0, -1.0)), HERE)
    assert t.level == Level.ACCELERATION and t.acceleration == (0.0, 0.5, 1.0)
    assert d.decode(local(M.MAV_FRAME_LOCAL_NED, 0b1101_1111_1100, 1.0, 2.0), HERE) is None  # z: no position, no velocity
    assert d.decode(local(M.MAV_FRAME_LOCAL_NED, 0b1101_1111_0111, vx=1.0), HERE) is None  # velocity x only
    assert d.accepted == 4 and d.rejected == {"mask": 2}


def test_offset_and_body_frames_are_relative_to_the_vehicle():
    d = OffboardDecoder(1)
    t = d.decode(local(M.MAV_FRAME_LOCAL_OFFSET_NED, POS_NED, 1.0, 2.0, -3.0, yaw=0.0), HERE)
    assert t.position == pytest.approx((12.0, 21.0, 8.0)) and t.yaw == pytest.approx(math.pi / 2)  # yaw absolute
    # MAVSDK set_velocity_body: forward 1, right 2, down 0.5, yaw rate 0.3 rad/s clockwise; vehicle faces north
    t = d.decode(local(M.MAV_FRAME_BODY_NED, VEL_BODY, vx=1.0, vy=2.0, vz=0.5, yaw_rate=0.3), HERE)
    assert t.level == Level.VELOCITY and t.velocity == pytest.approx((2.0, 1.0, -0.5))
    assert t.yaw_rate == pytest.approx(-0.3) and nan(t.yaw)
    east = VehicleFrame((0.0, 0.0, 2.0), 0.0, HOME)  # facing east: forward = east, right = south
    t = d.decode(local(M.MAV_FRAME_BODY_OFFSET_NED, POS_NED, 3.0, 1.0, -1.0, yaw=math.radians(30)), east)
    assert t.position == pytest.approx((3.0, -1.0, 3.0)) and t.yaw == pytest.approx(math.radians(-30))  # 30° right
    assert d.decode(local(M.MAV_FRAME_BODY_NED, VEL_BODY, vx=1.0), VehicleFrame(HERE.position, math.nan)) is None
    assert d.decode(local(M.MAV_FRAME_LOCAL_OFFSET_NED, POS_NED, 1.0), VehicleFrame()) is None
    assert d.rejected == {"no_estimate": 2}


def global_int(frame, mask, lat, lon, alt, vx=0.0, yaw=0.0):
    return rx(M.MAVLink_set_position_target_global_int_message(5, 1, 1, frame, mask, int(round(lat * 1e7)),
                                                               int(round(lon * 1e7)), alt, vx, 0, 0, 0, 0, 0, yaw, 0))


def test_global_int_via_home_relative_and_amsl():
    d = OffboardDecoder(1)
    lat, lon, _ = GeoOrigin(*HOME).to_geodetic(15.0, -25.0, 0.0)
    t = d.decode(global_int(M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, POS_NED, lat, lon, 7.0), HERE)
    assert t.level == Level.POSITION and t.position == pytest.approx((15.0, -25.0, 7.0), abs=0.02)  # degE7 ≈ 1 cm
    t = d.decode(global_int(M.MAV_FRAME_GLOBAL_INT, POS_NED, lat, lon, 150.0), HERE)
    assert t.position[2] == pytest.approx(4.0)  # 150 m AMSL, home at 146
    assert d.decode(global_int(M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, POS_NED, lat, lon, 7.0), VehicleFrame()) is None
    assert d.decode(global_int(M.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT, POS_NED, lat, lon, 7.0), HERE) is None
    assert d.decode(global_int(M.MAV_FRAME_GLOBAL_INT, POS_NED, 95.0, lon, 7.0), HERE) is None
    assert d.rejected == {"no_home": 1, "frame": 1, "malformed": 1}


def attitude(mask, q=(1.0, 0.0, 0.0, 0.0), rates=(0.0, 0.0, 0.0), thrust=0.6):
    return rx(M.MAVLink_set_attitude_target_message(7, 1, 1, mask, q, *rates, thrust))


def test_attitude_target_frd_ned_to_flu_enu():
    d = OffboardDecoder(1)
    frd_ned = quat.from_euler(math.radians(10), math.radians(5), math.radians(90))  # right wing down, nose up, east
    t = d.decode(attitude(0b0000_0111, frd_ned), HERE)  # MAVSDK set_attitude: rates ignored
    assert t.level == Level.ATTITUDE and t.thrust == pytest.approx(0.6) and nan(*t.body_rate, t.yaw_rate)
    roll, pitch, yaw = quat.to_euler(t.orientation)
    assert (roll, pitch, yaw) == pytest.approx((math.radians(10), math.radians(-5), 0.0), abs=1e-6)  # FLU pitch+ = nose down
    t = d.decode(attitude(0b1000_0000, rates=(0.1, 0.2, 0.3), thrust=0.4), HERE)  # MAVSDK set_attitude_rate
    assert t.level == Level.RATE and t.body_rate == pytest.approx((0.1, -0.2, -0.3)) and t.thrust == pytest.approx(0.4)
    assert d.decode(attitude(0b1000_0100, rates=(0.1, 0.2, 0.3)), HERE) is None  # no attitude, a rate missing
    assert d.decode(attitude(0b0100_0000), HERE) is None  # thrust ignored
    assert d.decode(attitude(0, q=(0.5, 0.0, 0.0, 0.0)), HERE) is None  # not a unit quaternion
    assert d.decode(attitude(0, thrust=1.5), HERE) is None
    assert d.rejected == {"mask": 2, "malformed": 2}


def test_bad_frames_dropped_counted_and_warned_once():
    d = OffboardDecoder(1)
    for _ in range(3):
        assert d.decode(local(M.MAV_FRAME_LOCAL_ENU, POS_NED, 1.0), HERE) is None
    assert d.decode(local(M.MAV_FRAME_LOCAL_NED, VEL_NED, vx=math.nan), HERE) is None  # used and NaN
    assert d.decode(local(M.MAV_FRAME_LOCAL_NED, VEL_NED, x=math.nan, vx=1.0), HERE) is not None  # ignored NaN is fine
    assert d.decode(local(M.MAV_FRAME_LOCAL_NED, POS_NED, math.inf), HERE) is None
    assert d.decode(local(M.MAV_FRAME_LOCAL_NED, POS_NED | 512, 1.0), HERE) is None  # force setpoint
    assert d.decode(local(M.MAV_FRAME_LOCAL_NED, 0b1101_1111_1111), HERE) is None  # nothing to follow
    assert d.decode(local(M.MAV_FRAME_LOCAL_NED, POS_NED, 1.0, target=(2, 1)), HERE) is None  # another vehicle
    assert d.decode(local(M.MAV_FRAME_LOCAL_NED, POS_NED, 1.0, target=(1, 5)), HERE) is None  # another component
    assert d.decode(local(M.MAV_FRAME_LOCAL_NED, POS_NED, 1.0, target=(0, 0)), HERE) is not None  # broadcast
    assert d.rejected == {"frame": 3, "malformed": 2, "mask": 1, "empty": 1, "not_addressed": 2} and d.accepted == 2
    warnings = d.take_warnings()
    assert len(warnings) == 4 and "frame 4 not supported" in warnings[0] and d.take_warnings() == []
    d.decode(local(M.MAV_FRAME_LOCAL_ENU, POS_NED, 1.0), HERE)
    assert d.take_warnings() == []  # once per kind


def test_position_target_echo_round_trip():
    d = OffboardDecoder(1)
    sent = local(M.MAV_FRAME_LOCAL_NED, VEL_NED, vx=2.0, vy=-1.0, vz=-0.5, yaw=math.radians(45))
    echo = rx(position_target_local_ned(d.decode(sent, HERE), 99))
    assert echo.coordinate_frame == M.MAV_FRAME_LOCAL_NED and echo.type_mask == VEL_NED
    assert (echo.vx, echo.vy, echo.vz) == pytest.approx((2.0, -1.0, -0.5)) and echo.yaw == pytest.approx(math.radians(45))
    echo = rx(position_target_local_ned(d.decode(local(M.MAV_FRAME_LOCAL_NED, POS_NED, 3.0, -4.0, -6.0), HERE), 99))
    assert (echo.x, echo.y, echo.z, echo.type_mask) == pytest.approx((3.0, -4.0, -6.0, POS_NED))
    assert position_target_local_ned(Target(Level.RATE, body_rate=(0.0, 0.0, 0.0), thrust=0.5), 0) is None


def test_position_target_stream_only_in_offboard_while_live():
    s = enc.Snapshot(boot_s=0.0, status_known=True, flight_mode=Mode.POSITION)
    s.offboard_target, s.offboard_target_t = Target(Level.POSITION, position=(1.0, 2.0, 3.0)), 10.0
    assert enc.position_target(s, 10.1) is None  # not in OFFBOARD
    s.flight_mode = Mode.OFFBOARD
    msg = enc.position_target(s, 10.1)
    assert (msg.x, msg.y, msg.z, msg.time_boot_ms) == (2.0, 1.0, -3.0, 10100)
    assert enc.position_target(s, 10.6) is None  # stream stale: the core no longer follows it


def test_offboard_is_px4_main_mode_6_both_ways():
    custom = frames.px4_custom_mode(Mode.OFFBOARD, Nav.NONE)
    assert frames.decode_px4_mode(custom) == (6, 0) and frames.mode_name(custom) == "OFFBOARD"
    hb = enc.heartbeat(enc.Snapshot(status_known=True, armed=True, flight_mode=Mode.OFFBOARD))
    assert hb.custom_mode == 6 << 16 and hb.base_mode & M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    ctx = Context(HOME, 5.0)
    cmd = rx(M.MAVLink_command_long_message(1, 1, M.MAV_CMD_DO_SET_MODE, 0, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 6, 0,
                                            0, 0, 0, 0))
    assert translate(cmd, ctx).fields == {"command": VehicleCommandId.SET_MODE, "mode": Mode.OFFBOARD}
    legacy = rx(M.MAVLink_set_mode_message(1, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 6 << 16))
    assert translate_set_mode(legacy, ctx).fields == {"command": VehicleCommandId.SET_MODE, "mode": Mode.OFFBOARD}
    # MAVSDK offboard.stop() → set_flight_mode(Hold) = AUTO.LOITER (main 4, sub 3) → the core's HOLD
    hold = rx(M.MAVLink_set_mode_message(1, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, (4 << 16) | (3 << 24)))
    assert translate_set_mode(hold, ctx).fields == {"command": VehicleCommandId.HOLD}
    assert translate_set_mode(rx(M.MAVLink_set_mode_message(1, 0, 6 << 16)), ctx).result == M.MAV_RESULT_DENIED
