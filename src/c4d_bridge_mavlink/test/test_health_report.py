"""What the bridge reports about the vehicle's state and health (issue 14 items 11, 12, 14, 15):
modes a stock GCS names, no heartbeat before the vehicle's status is known, SYS_STATUS bits from
the vehicle's own reports, failsafe texts, GET_HOME_POSITION."""

from __future__ import annotations

from c4d_bridge_mavlink import encoders as enc
from c4d_bridge_mavlink.commands import Context, Kind, translate
from c4d_bridge_mavlink.frames import mode_name, px4_custom_mode
from c4d_bridge_mavlink.health_report import PERCEPTION_BITS, FailsafeAnnouncer, VehicleHealth, sensor_bits
from c4d_bridge_mavlink.signing import mavlink as M
from c4d_common.vehicle import FailsafeAction, Mode, Nav


def test_every_mode_and_navigation_state_has_a_name_stock_gcss_know():
    """Issue 14.11: after landing (AUTO, NAV_NONE) the mode was AUTO.READY, which MAVProxy shows as UNKNOWN."""
    from pymavlink import mavutil  # MAVProxy's decoder of PX4 custom modes

    for mode in Mode:
        for nav in Nav:
            assert mavutil.interpret_px4_mode(0, px4_custom_mode(mode, nav)) != "UNKNOWN", (mode, nav)
    assert mavutil.interpret_px4_mode(0, px4_custom_mode(Mode.AUTO, Nav.RTL)) == "RTL"
    assert mode_name(px4_custom_mode(Mode.AUTO, Nav.NONE)) == "AUTO.LOITER"  # landed / disarmed: PX4's Hold


def test_rtl_is_reported_as_rtl_in_the_heartbeat_with_or_without_a_plan():
    s = enc.Snapshot(status_known=True, mission_known=True, armed=True, flight_mode=Mode.AUTO, nav_state=Nav.RTL)
    for mission_state in (M.MISSION_STATE_PAUSED, M.MISSION_STATE_ACTIVE):  # a commanded RTL aborts the plan; an rtl item
        s.mission_state = mission_state
        assert mode_name(enc.heartbeat(s).custom_mode) == "AUTO.RTL"
    s.nav_state = Nav.GOTO  # a plan's legs are flown as GOTO: AUTO.MISSION while the plan is active, else a go-to
    assert mode_name(enc.heartbeat(s).custom_mode) == "AUTO.MISSION"
    s.mission_state = M.MISSION_STATE_PAUSED
    assert mode_name(enc.heartbeat(s).custom_mode) == "AUTO.LOITER"


def test_no_heartbeat_until_the_vehicle_status_is_known():
    s = enc.Snapshot()  # a restarted bridge: armed=False is a default, not news
    assert enc.heartbeat(s) is None
    s.status_known, s.armed, s.nav_state = True, True, Nav.HOLD
    hb = enc.heartbeat(s)
    assert hb.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED and hb.system_status == M.MAV_STATE_ACTIVE
    s.nav_state = Nav.GOTO  # a plan's leg or a go-to: the mission state tells
    assert enc.heartbeat(s) is None
    s.mission_known, s.mission_state = True, M.MISSION_STATE_ACTIVE
    assert mode_name(enc.heartbeat(s).custom_mode) == "AUTO.MISSION"


ALL_OK = {name: True for name in PERCEPTION_BITS}


def bits(sensor_ok=ALL_OK, status_known=True, attitude=True, position=True, home=True, **health):
    return sensor_bits(VehicleHealth(dict(sensor_ok), **health), status_known, attitude, position, home)


def test_sys_status_bits_follow_the_vehicle_reports():
    ok = bits()
    assert ok.armable and ok.present == ok.enabled and ok.health == ok.present
    imu = M.MAV_SYS_STATUS_SENSOR_3D_GYRO | M.MAV_SYS_STATUS_SENSOR_3D_ACCEL
    bad_imu = bits({**ALL_OK, "imu": False})
    assert not bad_imu.armable and bad_imu.health & imu == 0 and bad_imu.present & imu == imu
    assert bad_imu.health & M.MAV_SYS_STATUS_SENSOR_GPS
    assert not bits({}).armable and bits({}).health & M.MAV_SYS_STATUS_SENSOR_3D_MAG == 0  # nothing heard yet
    assert not bits({k: v for k, v in ALL_OK.items() if k != "baro"}).armable  # one sensor never heard
    no_nav = bits(attitude=False, position=False)
    assert not no_nav.armable and not no_nav.health & (M.MAV_SYS_STATUS_AHRS | M.MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL)
    assert not bits(home=False).armable and not bits(position=False).armable
    no_core = bits(status_known=False)
    assert not no_core.armable and not no_core.health & M.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
    assert not bits(core_lost=True).health & M.MAV_SYS_STATUS_SENSOR_ANGULAR_RATE_CONTROL
    assert not bits(battery_warning=True).health & M.MAV_SYS_STATUS_SENSOR_BATTERY


def test_health_summary_names_a_lost_core_and_battery_warnings():
    h = VehicleHealth()
    h.on_summary({"failsafe": "WARN", "active": "battery_low,link_loss", "dead_nodes": "mission, core", "stalled_nodes": ""})
    assert h.core_lost and h.battery_warning
    h.on_summary({"failsafe": "NONE", "active": "", "dead_nodes": "", "stalled_nodes": "perception"})
    assert not h.core_lost and not h.battery_warning


def test_sys_status_message_carries_the_bits():
    s = enc.Snapshot(status_known=True, valid_attitude=True, valid_position=True, home=(47.0, 8.0, 400.0))
    s.health.sensor_ok.update(ALL_OK)
    assert enc.sys_status(s).onboard_control_sensors_health & M.MAV_SYS_STATUS_PREARM_CHECK
    s.health.sensor_ok["imu"] = False
    msg = enc.sys_status(s)
    assert not msg.onboard_control_sensors_health & M.MAV_SYS_STATUS_PREARM_CHECK
    assert msg.onboard_control_sensors_present & M.MAV_SYS_STATUS_PREARM_CHECK  # MAVSDK reads armable only when present


def test_a_warning_coming_and_going_is_not_a_failsafe_cleared():
    """Issue 14.15: NONE → WARN → NONE on the ground said "failsafe cleared" with no failsafe announced."""
    said = FailsafeAnnouncer()
    for action in (FailsafeAction.NONE, FailsafeAction.WARN, FailsafeAction.NONE, FailsafeAction.WARN, FailsafeAction.NONE):
        assert said.update(action, "executor_overrun") is None
    rtl = said.update(FailsafeAction.RTL, "link_loss")
    assert rtl is not None and rtl.text == "failsafe RTL: link_loss" and rtl.severity == M.MAV_SEVERITY_CRITICAL
    assert said.update(FailsafeAction.RTL, "link_loss") is None  # once per action (health says it at 10 Hz)
    assert said.update(FailsafeAction.LAND, "battery_critical").text.startswith("failsafe LAND")
    cleared = said.update(FailsafeAction.WARN, "")
    assert cleared is not None and cleared.text == "failsafe cleared"
    assert said.update(FailsafeAction.NONE, "") is None


def test_get_home_position_requests_the_home_position_message():
    """Issue 14.15: MAV_CMD_GET_HOME_POSITION (410, MAVProxy) was UNSUPPORTED."""
    msg = M.MAVLink_command_long_message(1, 1, M.MAV_CMD_GET_HOME_POSITION, 0, 0, 0, 0, 0, 0, 0, 0)
    action = translate(msg, Context(None, 5.0))
    assert action.kind == Kind.REQUEST and action.fields == {"msg_id": M.MAVLINK_MSG_ID_HOME_POSITION}
