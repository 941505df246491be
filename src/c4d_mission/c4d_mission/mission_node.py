"""`ros2 run c4d_mission mission` — mission management and command executor.

Services: mission/upload (validate item by item, then replace the plan atomically),
mission/download, mission/control (start, pause, resume, clear, set current), vehicle/command
(arm / take-off with pre-arm checks: estimator valid with home set, every sensor healthy,
battery above the reserve, inside the geofence; RTL and go-to (loiter at a global target,
checked against the geofence unless `force`) are flown by the mission node; disarm, land,
hold and set mode are forwarded to the core's gnc/command; hold and an accepted set mode pause
the mission, resumed by mission/control resume). Publishes guidance/setpoint (50 Hz while a mission or RTL
flies), mission/state (on change and at 2 Hz) and mission/plan (latched). Mode changes reach
the core only through its latched gnc/command interface.
Parameters: plan_file (loaded and validated once home is known), min_battery (0.2),
hover_current_a (endurance estimate, 20 A).
"""

from __future__ import annotations

import math
import sys

from c4d_common.geodesy import GeoOrigin
from c4d_common.plan import GLOBAL, Geofence, Item, Plan, PlanError
from c4d_common.plan_files import load_plan
from c4d_common.plan_validation import VehicleLimits, check_goto, leg_inside, validate
from c4d_ros.drain import LatestSampler

from .executor import MissionExecutor, MissionStatus, Vehicle

RESULT_ACCEPTED, RESULT_TEMPORARILY_REJECTED, RESULT_DENIED, RESULT_UNSUPPORTED, RESULT_FAILED = 0, 1, 2, 3, 4
CORE = {"takeoff": 3, "goto": 8, "land": 4, "hold": 6}


def main(argv: list[str] | None = None) -> int:
    from c4d_ros import node_runtime

    rclpy = node_runtime.init(argv)
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
    from rclpy.callback_groups import ReentrantCallbackGroup
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import BatteryState

    from c4d_common import quat
    from c4d_interfaces.msg import GuidanceSetpoint, MissionPlan, MissionState, VehicleState, VehicleStatus
    from c4d_interfaces.srv import DownloadMission, MissionControl, UploadMission, VehicleCommand
    from c4d_ros.plan_msgs import plan_from_msg, plan_to_msg
    from c4d_ros.stamps import s_to_stamp

    node = rclpy.create_node("mission")
    plan_file = node.declare_parameter("plan_file", "").value
    min_battery = float(node.declare_parameter("min_battery", 0.2).value)
    hover_current = float(node.declare_parameter("hover_current_a", 20.0).value)
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    best = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
    executor = MissionExecutor()
    rtl = MissionExecutor()  # RTL and go-to commanded outside a plan
    limits = VehicleLimits()
    world: dict = {"state": None, "status": None, "battery": None, "health": {}, "next_id": 1, "last_state_pub": 0.0,
                   "last_key": None}
    pub_setpoint = node.create_publisher(GuidanceSetpoint, "guidance/setpoint", best)
    pub_state = node.create_publisher(MissionState, "mission/state", latched)
    pub_plan = node.create_publisher(MissionPlan, "mission/plan", latched)
    # its own callback group: the vehicle/command service awaits this client's response, which
    # a mutually exclusive (default) group would never run while the service callback is pending
    core = node.create_client(VehicleCommand, "gnc/command", callback_group=ReentrantCallbackGroup())

    def now() -> float:
        return node.get_clock().now().nanoseconds * 1e-9

    def home() -> GeoOrigin | None:
        s = world["state"]
        if s is None or not s.valid & VehicleState.VALID_ORIGIN:
            return None
        return GeoOrigin(s.origin.latitude, s.origin.longitude, s.origin.altitude)

    def endurance_s() -> float | None:
        b = world["battery"]
        if b is None or not math.isfinite(b.charge) or b.charge <= 0:
            return None
        return b.charge * 0.8 / hover_current * 3600.0  # 20 % reserve

    def accept(plan: Plan) -> tuple[bool, list[str], list[str]]:
        origin = home()
        if origin is None:
            return False, ["plan: no home position yet (estimator not ready)"], []
        result = validate(plan, origin, limits, endurance_s())
        if not result.ok:
            return False, list(result.errors), list(result.warnings)
        if executor.status == MissionStatus.ACTIVE:
            return False, ["plan: a mission is active (pause or land first)"], []
        plan = plan.with_id(world["next_id"])
        world["next_id"] += 1
        executor.load(plan, origin)
        pub_plan.publish(plan_to_msg(plan))
        node.get_logger().info(f"plan {plan.plan_id} '{plan.name}' accepted: {len(plan.items)} items, "
                               f"{result.path_length:.0f} m, ~{result.duration:.0f} s")
        return True, [], list(result.warnings)

    def send_core(command: int, altitude: float = 0.0, mode: int = 0, force: bool = False):
        return core.call_async(VehicleCommand.Request(command=command, altitude=altitude, mode=mode, force=force))

    def on_upload(request, response):
        try:
            plan = plan_from_msg(request.plan)
        except PlanError as exc:
            response.accepted, response.errors = False, [str(exc)]
            return response
        ok, errors, warnings = accept(plan)
        response.accepted, response.errors, response.warnings = ok, errors, warnings
        response.plan_id = executor.plan.plan_id if ok and executor.plan else 0
        if ok and request.start:
            executor.start()
        return response

    def on_download(request, response):
        response.has_plan = executor.plan is not None
        if executor.plan is not None:
            response.plan = plan_to_msg(executor.plan)
        response.state = state_msg()
        return response

    def on_control(request, response):
        a = request.action
        reason = "unknown action"
        if a == MissionControl.Request.ACTION_START:
            reason = executor.start(request.item)
            if not reason:
                rtl.clear()
        elif a == MissionControl.Request.ACTION_PAUSE:
            reason = executor.pause()
            if not reason:
                send_core(VehicleCommand.Request.CMD_HOLD)
        elif a == MissionControl.Request.ACTION_RESUME:
            reason = executor.resume()
            if not reason:
                rtl.clear()  # a go-to interrupted the mission: the plan takes over again
        elif a == MissionControl.Request.ACTION_CLEAR:
            reason = "mission is active (pause it first)" if executor.status == MissionStatus.ACTIVE else ""
            if not reason:
                executor.clear()
        elif a == MissionControl.Request.ACTION_SET_CURRENT:
            if executor.plan is None or not 0 <= request.item < len(executor.plan.items):
                reason = f"item {request.item} does not exist"
            else:
                executor.current, reason = request.item, ""
        response.result = RESULT_ACCEPTED if not reason else (RESULT_UNSUPPORTED if reason == "unknown action" else RESULT_DENIED)
        response.message = reason or "accepted"
        response.state = state_msg()
        return response

    def preflight() -> str:
        s = world["state"]
        needed = VehicleState.VALID_ATTITUDE | VehicleState.VALID_POSITION_XY | VehicleState.VALID_ORIGIN
        if s is None or s.valid & needed != needed:
            return "estimator not ready (attitude, position and home needed)"
        unhealthy = [name for name, level in world["health"].items() if level != DiagnosticStatus.OK]
        if unhealthy:
            return f"sensors not healthy: {', '.join(sorted(unhealthy))}"
        b = world["battery"]
        if b is not None and b.percentage < min_battery:
            return f"battery at {b.percentage:.0%}, below the {min_battery:.0%} reserve"
        plan = executor.plan
        origin = home()
        if plan is not None and plan.geofence.polygon and origin is not None:
            polygon = [origin.to_enu(lat, lon, origin.altitude)[:2] for lat, lon in plan.geofence.polygon]
            here = (s.position.x, s.position.y)
            if not leg_inside(here, here, polygon):
                return "outside the geofence"
        return ""

    async def on_vehicle_command(request, response):
        c = request.command
        if c in (VehicleCommand.Request.CMD_ARM, VehicleCommand.Request.CMD_TAKEOFF) and not request.force:
            reason = preflight()
            if reason:
                response.result, response.message = RESULT_TEMPORARILY_REJECTED, f"pre-arm check failed: {reason}"
                return response
        if c == VehicleCommand.Request.CMD_RETURN_TO_LAUNCH:
            origin, st = home(), world["status"]
            if origin is None or st is None or not st.armed:
                response.result, response.message = RESULT_DENIED, "RTL needs an armed vehicle with a home position"
                return response
            executor.abort()
            rtl.load(Plan((Item("rtl"),), rtl_altitude=executor.plan.rtl_altitude if executor.plan else 0.0), origin)
            rtl.start()
            response.result, response.message = RESULT_ACCEPTED, "returning to launch"
            return response
        if c == VehicleCommand.Request.CMD_GOTO:
            origin, st, s = home(), world["status"], world["state"]
            if origin is None or st is None or not st.armed or st.landed_state != VehicleStatus.LANDED_IN_AIR:
                response.result, response.message = RESULT_DENIED, "go-to needs a flying vehicle (take off first)"
                return response
            t = request.target
            target = Item("loiter", frame=GLOBAL, x=t.latitude, y=t.longitude, z=t.altitude, hold=math.inf,
                          yaw=request.yaw)
            fence = executor.plan.geofence if executor.plan else Geofence()
            errors = check_goto(target, (s.position.x, s.position.y, s.position.z), fence, origin, limits)
            if errors and not (request.force and "finite" not in errors[0] and "out of range" not in errors[0]):
                response.result, response.message = RESULT_DENIED, "; ".join(errors)
                return response
            executor.pause()  # a running mission can be resumed after the go-to
            rtl.load(Plan((target,), rtl_altitude=executor.plan.rtl_altitude if executor.plan else 0.0), origin)
            rtl.start()
            response.result, response.message = RESULT_ACCEPTED, "going to the target" + (
                f" (forced: {'; '.join(errors)})" if errors else "")
            return response
        if c in (VehicleCommand.Request.CMD_LAND, VehicleCommand.Request.CMD_HOLD, VehicleCommand.Request.CMD_DISARM):
            executor.pause() if c == VehicleCommand.Request.CMD_HOLD else executor.abort()
            rtl.clear()
        if not core.service_is_ready():
            response.result, response.message = RESULT_TEMPORARILY_REJECTED, "GNC core not reachable"
            return response
        forwarded = await core.call_async(request)
        response.result, response.message = forwarded.result, forwarded.message
        if c == VehicleCommand.Request.CMD_SET_MODE and forwarded.result == RESULT_ACCEPTED:
            # a mode set by hand (pilot, GCS) takes the vehicle from the plan: the mission pauses (set
            # mission mode again to resume where it stopped) and an RTL or go-to is cancelled
            executor.pause()
            rtl.clear()
        return response

    def on_state(msg) -> None:
        world["state"] = msg
        if plan_file and executor.plan is None and home() is not None and not world.get("file_tried"):
            world["file_tried"] = True
            try:
                ok, errors, _ = accept(load_plan(plan_file))
                if not ok:
                    node.get_logger().error(f"plan_file {plan_file} rejected: {'; '.join(errors)}")
            except PlanError as exc:
                node.get_logger().error(f"plan_file: {exc}")

    def on_health(msg) -> None:
        for status in msg.status:
            world["health"][status.hardware_id] = status.level

    # 500 Hz: sampled at the 50 Hz tick instead of waking the executor for every sample
    state_sampler = LatestSampler(rclpy.create_node("_mission_samples"), VehicleState, "navigation/state", best)
    node.create_subscription(VehicleStatus, "vehicle/status", lambda m: world.__setitem__("status", m), latched)
    node.create_subscription(BatteryState, "sensors/battery", lambda m: world.__setitem__("battery", m), best)
    node.create_subscription(DiagnosticArray, "perception/health", on_health, 10)
    node.create_service(UploadMission, "mission/upload", on_upload)
    node.create_service(DownloadMission, "mission/download", on_download)
    node.create_service(MissionControl, "mission/control", on_control)
    node.create_service(VehicleCommand, "vehicle/command", on_vehicle_command)

    def state_msg() -> MissionState:
        m = MissionState()
        m.header.stamp = s_to_stamp(now())
        m.plan_id = executor.plan.plan_id if executor.plan else 0
        m.state = int(executor.status)
        m.current_item = executor.current
        m.total_items = len(executor.plan.items) if executor.plan else 0
        m.last_reached_item = executor.last_reached
        m.progress = float(executor.progress)
        m.distance_to_item = math.nan
        return m

    def tick() -> None:
        sample = state_sampler.latest()
        if sample is not None and sample is not world["state"]:
            on_state(sample)
        s, st = world["state"], world["status"]
        if s is None or st is None:
            return
        q = (s.orientation.w, s.orientation.x, s.orientation.y, s.orientation.z)
        vehicle = Vehicle((s.position.x, s.position.y, s.position.z), st.armed,
                          st.landed_state in (VehicleStatus.LANDED_IN_AIR, VehicleStatus.LANDED_LANDING),
                          st.nav_state, quat.yaw_of(q))
        t = now()
        for runner in (executor, rtl):
            out = runner.step(t, 0.02, vehicle)
            for name, value in out.requests:
                future = send_core(CORE[name], altitude=value)

                def done(f, runner=runner, name=name) -> None:
                    reply = f.result()
                    if reply is not None and reply.result != RESULT_ACCEPTED:
                        node.get_logger().warning(f"core refused {name}: {reply.message}; retrying")
                        runner.request_rejected(name, reply.message)

                future.add_done_callback(done)
            if out.setpoint is not None:
                position, velocity, yaw = out.setpoint
                sp = GuidanceSetpoint(control_level=GuidanceSetpoint.LEVEL_POSITION, yaw=float(yaw), yaw_rate=math.nan,
                                      thrust=math.nan, max_horizontal_speed=math.nan, max_vertical_speed=math.nan)
                sp.header.stamp, sp.header.frame_id = s_to_stamp(t), "map"
                sp.position.x, sp.position.y, sp.position.z = (float(v) for v in position)
                sp.velocity.x, sp.velocity.y, sp.velocity.z = (float(v) for v in velocity)
                sp.acceleration.x = sp.acceleration.y = sp.acceleration.z = math.nan
                pub_setpoint.publish(sp)
        key = (executor.plan.plan_id if executor.plan else 0, executor.status, executor.current, executor.last_reached)
        if key != world["last_key"] or t - world["last_state_pub"] >= 0.2:  # 5 Hz heartbeat for health
            pub_state.publish(state_msg())
            world["last_key"], world["last_state_pub"] = key, t

    node.create_timer(0.02, tick)
    return node_runtime.spin_node(node, events_executor=False)


if __name__ == "__main__":
    sys.exit(main())
