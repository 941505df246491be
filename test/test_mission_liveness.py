"""The mission node stays alive for health while a forwarded command waits for the core (issue 14.2).

Its vehicle/command service forwards HOLD / LAND / DISARM / SET_MODE to the core's gnc/command and
awaits the answer. That service shared the default callback group with the 50 Hz guidance tick, and
rclpy keeps a group busy while a coroutine callback awaits: the tick — guidance and the
mission/state heartbeat health judges liveness by — stopped for as long as the core took, for
ever when its answer was lost. Here the real mission process meets a core that never answers (and
no vehicle inputs at all: the heartbeat must not depend on them either)."""

from __future__ import annotations

import functools
import threading
import time

from c4d_testing import installed_executable, spin_for


def test_mission_state_keeps_coming_while_a_forwarded_command_waits_for_the_core(processes, ros_node):
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.task import Future

    from c4d_interfaces.msg import MissionState
    from c4d_interfaces.srv import VehicleCommand
    from c4d_ros import manifest

    node, executor = ros_node
    never: list[Future] = []

    async def silent_core(request, response):  # receives, never answers
        future = Future()
        never.append(future)
        await future
        return response

    # the silent core on a node and executor of its own: its pending coroutine would starve the test's spin
    core = rclpy.create_node("core", context=node.context)
    core.create_service(VehicleCommand, manifest.CORE_COMMAND.name, silent_core)
    core_executor = SingleThreadedExecutor(context=node.context)
    core_executor.add_node(core)
    threading.Thread(target=core_executor.spin, daemon=True).start()
    heard: list[float] = []
    node.create_subscription(MissionState, manifest.MISSION_STATE.name, lambda m: heard.append(time.monotonic()),
                             manifest.MISSION_STATE.qos)
    command = node.create_client(VehicleCommand, manifest.VEHICLE_COMMAND.name)
    mission = processes.spawn("mission", [installed_executable("c4d_mission", "mission")])
    spin = functools.partial(spin_for, executor, watch=(processes, {"mission": mission}))
    assert spin(30, lambda: len(heard) >= 3), "no mission/state heartbeat without vehicle inputs"
    assert spin(10, command.service_is_ready)
    reply = command.call_async(VehicleCommand.Request(command=VehicleCommand.Request.CMD_HOLD))
    assert spin(10, lambda: bool(never)), "the HOLD was not forwarded to the core"
    asked = time.monotonic()
    spin(3.0)
    after = [t for t in heard if t > asked]
    assert not reply.done()  # still waiting for the core
    gaps = [b - a for a, b in zip([asked, *after], after, strict=False)] or [3.0]
    try:
        assert len(after) >= 10 and max(gaps) < 0.6, f"{len(after)} heartbeats in 3 s while waiting, gaps {gaps}"
    finally:
        core_executor.shutdown()
        core.destroy_node()
