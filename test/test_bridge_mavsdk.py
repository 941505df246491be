"""Issue 7 acceptance: stock MAVSDK-Python (the PyPI `mavsdk` 4.x native binding, no pymavlink on
the GCS side) against the whole SITL graph through the c4d MAVLink bridge: it connects, sees
health (global position, home) and a position, sets the take-off altitude (a parameter), arms,
takes off, uploads a 4-waypoint mission, starts and flies it to the end, returns to launch, and
the vehicle lands and disarms within 2 m of home; the flight modes MAVSDK decodes say RETURN_TO_LAUNCH
during the return, LAND for its landing, HOLD once landed.

The bridge sends to MAVSDK's UDP port (`udpout`), MAVSDK listens (`udpin://`), as with PX4 SITL.
Every wait is bounded; a failure names the step and carries the MAVSDK log and the bridge log.
MAVSDK (a C++ library with its own threads) runs in a child process of the test's process group —
this file run as a script — so whatever it does (a crash in its teardown included) cannot take
the test process and its graph teardown with it, and no MAVSDK thread outlives the test."""

from __future__ import annotations

import argparse
import asyncio
import collections
import json
import math
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import mavsdk  # the PyPI package (requirements.txt), 4.x: the native binding, no mavsdk_server
import pytest

TAKEOFF_ALT = 5.0
WAYPOINTS = [(6.0, 0.0), (6.0, 6.0), (0.0, 6.0), (0.0, 2.0)]  # east, north [m] from home, at TAKEOFF_ALT


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def enu_from(home, lat: float, lon: float) -> tuple[float, float]:
    """East, north [m] of (lat, lon) from home (local tangent plane; ample for tens of metres)."""
    r = 6_378_137.0
    north = math.radians(lat - home.latitude_deg) * r
    east = math.radians(lon - home.longitude_deg) * r * math.cos(math.radians(home.latitude_deg))
    return east, north


def geodetic_from(home, east: float, north: float) -> tuple[float, float]:
    r = 6_378_137.0
    lat = home.latitude_deg + math.degrees(north / r)
    lon = home.longitude_deg + math.degrees(east / (r * math.cos(math.radians(home.latitude_deg))))
    return lat, lon


@pytest.fixture(scope="module")
def graph(module_processes, tmp_path_factory):
    from c4d_testing import installed_executable

    port = free_udp_port()
    params_file = tmp_path_factory.mktemp("bridge") / "params.yaml"
    nodes = [("c4d_sim", "sim", []), ("c4d_gnc", "perception", []), ("c4d_gnc", "navigation", []),
             ("c4d_gnc", "core", ["--ros-args", "-p", "rt_priority:=50"]), ("c4d_mission", "mission", []),
             ("c4d_health", "health", ["--ros-args", "-p", "link_topic:=bridge/gcs_heartbeat"]),
             ("c4d_bridge_mavlink", "bridge", ["--ros-args", "-p", f"endpoints:=['udpout:127.0.0.1:{port}']",
                                               "-p", f"param_file:={params_file}"])]
    procs = {name: module_processes.spawn(name, [installed_executable(pkg, name), *args]) for pkg, name, args in nodes}
    yield port, procs, module_processes


class Session:
    """Bounded waits on MAVSDK; a failure names the step and carries the MAVSDK, bridge and mission logs."""

    def __init__(self, logs: Path) -> None:
        self.logs = logs
        self.log: collections.deque[str] = collections.deque(maxlen=60)
        self.t0 = time.monotonic()
        self.durations: list[tuple[str, float]] = []
        self.closing = False

    def on_log(self, level, message, file, line) -> bool:
        self.log.append(f"[{level.name}] {message}")
        if self.closing:
            print(f"MAVSDK closing: [{level.name}] {message}", file=sys.stderr, flush=True)
        return True  # keep MAVSDK quiet; shown on failure

    def context(self) -> str:
        tail = lambda name, n: (self.logs / f"{name}.log").read_text(errors="replace")[-n:]  # noqa: E731
        return ("\n--- MAVSDK log (tail) ---\n" + "\n".join(self.log) + "\n--- bridge log (tail) ---\n"
                + tail("bridge", 3000) + "\n--- mission log (tail) ---\n" + tail("mission", 1500))

    def fail(self, what: str) -> None:
        print(f"FAILED: {what}{self.context()}", flush=True)  # now: MAVSDK's teardown comes next
        pytest.fail(what)

    async def step(self, name: str, awaitable, timeout: float):
        start = time.monotonic()
        try:
            result = await asyncio.wait_for(awaitable, timeout)
        except TimeoutError:
            self.fail(f"{name}: no result within {timeout:.0f} s")
        except mavsdk.MavsdkError as exc:  # ActionError, MissionError, TelemetryError, ...
            await asyncio.sleep(1.0)  # the reason follows the ack as a STATUSTEXT
            self.fail(f"{name}: MAVSDK error {exc!r}")
        self.durations.append((name, time.monotonic() - start))
        return result

    async def until(self, stream, predicate):
        """The first value of an async stream for which predicate holds (the stream is closed)."""
        try:
            async for value in stream:
                if predicate(value):
                    return value
        finally:
            await stream.aclose()


async def fly(port: int, s: Session, result: Path) -> dict:
    from mavsdk.asyncio import Configuration, Mavsdk
    from mavsdk.asyncio.plugins.action import ActionAsync
    from mavsdk.asyncio.plugins.mission import MissionAsync, MissionItem, MissionPlan
    from mavsdk.asyncio.plugins.telemetry import LandedState, TelemetryAsync

    out: dict = {}
    config = Configuration.create_with_component_type(mavsdk.ComponentType.GROUND_STATION)
    async with Mavsdk(config) as drone:
        await drone.add_any_connection(f"udpin://127.0.0.1:{port}")
        system = await s.step("discover the autopilot", drone.first_autopilot(timeout_s=30.0), 35.0)
        assert system is not None, f"no autopilot heartbeat within 30 s{s.context()}"
        out["autopilot"] = (await system.autopilot_type()).name
        out["version"] = await drone.version()
        telemetry, action, mission = TelemetryAsync(system), ActionAsync(system), MissionAsync(system)
        modes: list[str] = []  # every flight mode MAVSDK reports, changes only

        async def watch_modes(source: TelemetryAsync) -> None:
            async for mode in source.subscribe_flight_mode():
                if not modes or modes[-1] != mode.name:
                    modes.append(mode.name)

        watcher = asyncio.ensure_future(watch_modes(telemetry))

        await s.step("health: global + home position OK", s.until(
            telemetry.subscribe_health(), lambda h: h.is_global_position_ok and h.is_home_position_ok), 60.0)
        position = await s.step("a position", s.until(telemetry.subscribe_position(),
                                                        lambda p: math.isfinite(p.latitude_deg)), 10.0)
        home = await s.step("home", s.until(telemetry.subscribe_home(), lambda h: math.isfinite(h.latitude_deg)), 10.0)
        east, north = enu_from(home, position.latitude_deg, position.longitude_deg)
        assert math.hypot(east, north) < 1.0 and abs(position.relative_altitude_m) < 0.5, (position, home)

        await s.step("set take-off altitude", action.set_takeoff_altitude(TAKEOFF_ALT), 15.0)
        assert await s.step("get take-off altitude", action.get_takeoff_altitude(), 15.0) == pytest.approx(TAKEOFF_ALT)

        # a c4d plan starts with its take-off (MAVSDK: vehicle_action TAKEOFF → MAV_CMD_NAV_TAKEOFF); flown
        # in the air it is passed at once. A speed (→ DO_CHANGE_SPEED) rides on the first waypoint.
        items = [MissionItem(home.latitude_deg, home.longitude_deg, TAKEOFF_ALT, is_fly_through=True,
                             vehicle_action=MissionItem.VehicleAction.TAKEOFF)]
        items += [MissionItem(*geodetic_from(home, e, n), TAKEOFF_ALT, 3.0 if k == 0 else None, True, acceptance_radius_m=1.0)
                  for k, (e, n) in enumerate(WAYPOINTS)]
        plan = MissionPlan(items)
        await s.step("upload the mission", mission.upload_mission(plan), 20.0)

        await s.step("arm", action.arm(), 15.0)
        await s.step("armed", s.until(telemetry.subscribe_armed(), bool), 5.0)
        await s.step("take off", action.takeoff(), 10.0)
        await s.step(f"climb to {TAKEOFF_ALT} m", s.until(
            telemetry.subscribe_position(), lambda p: abs(p.relative_altitude_m - TAKEOFF_ALT) < 0.5), 30.0)
        await s.step("in air", s.until(telemetry.subscribe_landed_state(), lambda st: st == LandedState.IN_AIR), 5.0)

        await s.step("start the mission", mission.start_mission(), 10.0)
        seen: list[tuple[int, int]] = []

        def record(p) -> bool:
            if not seen or seen[-1] != (p.current, p.total):
                seen.append((p.current, p.total))
            return p.total == len(items) and p.current == p.total

        await s.step("fly the mission to the end", s.until(mission.subscribe_mission_progress(), record), 60.0)
        out["progress"] = seen
        out["finished"] = await s.step("mission finished", mission.is_mission_finished(), 5.0)
        position = await s.step("position at the end", telemetry.position(), 5.0)
        out["end_of_mission"] = enu_from(home, position.latitude_deg, position.longitude_deg)

        rtl_from = max(0, len(modes) - 1)  # the mode when the RTL is commanded, and every one after
        await s.step("return to launch", action.return_to_launch(), 10.0)
        await s.step("land and disarm", s.until(telemetry.subscribe_armed(), lambda armed: not armed), 60.0)
        await asyncio.sleep(1.5)  # the mode after landing (HEARTBEAT, 1 Hz)
        out["rtl_modes"] = modes[rtl_from:]
        out["modes"] = list(modes)
        watcher.cancel()
        out["landed_state"] = (await s.step("on the ground", s.until(  # EXTENDED_SYS_STATE is a 1 Hz stream
            telemetry.subscribe_landed_state(), lambda st: st == LandedState.ON_GROUND), 5.0)).name
        position = await s.step("final position", telemetry.position(), 5.0)
        out["final"] = enu_from(home, position.latitude_deg, position.longitude_deg)
        out["final_alt"] = position.relative_altitude_m
        out["final_down"] = (await s.step("final local position", telemetry.position_velocity_ned(), 5.0)).position.down_m
        out["durations"] = s.durations
        out["total"] = time.monotonic() - s.t0
        result.write_text(json.dumps(out))  # before the teardown: see test_mavsdk_session
        s.closing = True
        del telemetry, action, mission, system
    return out


def main() -> int:
    """The GCS side, in its own process: fly, write the results as JSON (exit 0), or fail (exit 1)."""
    args = argparse.ArgumentParser()
    args.add_argument("--port", type=int, required=True)
    args.add_argument("--logs", type=Path, required=True)  # the graph's log directory
    args.add_argument("--out", type=Path, required=True)
    a = args.parse_args()
    s = Session(a.logs)
    mavsdk.log_subscribe(s.on_log)
    try:
        asyncio.run(asyncio.wait_for(fly(a.port, s, a.out), 150.0))
    except TimeoutError:
        print(f"the MAVSDK session took more than 150 s{s.context()}")
        return 1
    except pytest.fail.Exception:
        return 1
    finally:
        mavsdk.log_unsubscribe()
    print("MAVSDK closed", flush=True)
    return 0


def test_mavsdk_session(graph, tmp_path):
    port, procs, group = graph
    result = tmp_path / "result.json"
    gcs = group.spawn("mavsdk", [sys.executable, "-X", "faulthandler", __file__, "--port", str(port),
                                 "--logs", str(group.log_dir), "--out", str(result)])
    try:
        code = gcs.wait(timeout=170.0)
    except subprocess.TimeoutExpired:
        gcs.kill()
        gcs.wait()
        code = None
    dead = {name: p.returncode for name, p in procs.items() if p.poll() is not None}
    log = group.log_of(gcs)
    # The results are written before MAVSDK is destroyed. libcmavsdk 4.1.0 intermittently aborts
    # (SIGABRT, ~2 runs in 15 here) inside mavsdk_destroy, after a complete session (cf. the upstream
    # destructor fix for language bindings, mavlink/MAVSDK#2776): that is reported, not failed; any
    # other exit is a failure.
    teardown_crash = code in (-signal.SIGABRT, -signal.SIGSEGV) and result.exists() and "MAVSDK closed" not in log
    assert (code == 0 or teardown_crash) and not dead, f"MAVSDK session: exit {code}; nodes died: {dead}\n{log[-8000:]}"
    out = json.loads(result.read_text())
    assert out["autopilot"] == "PX4"
    assert out["progress"][-1] == [len(WAYPOINTS) + 1] * 2 and out["finished"], out["progress"]
    assert math.dist(out["end_of_mission"], WAYPOINTS[-1]) < 1.5, out["end_of_mission"]
    assert out["landed_state"] == "ON_GROUND"
    # issue 14.11: the return is reported as RETURN_TO_LAUNCH (was HOLD: MISSION → HOLD → LAND), its
    # landing as LAND, and the landed vehicle in a mode MAVSDK names (HOLD = AUTO.LOITER; was READY)
    rtl = out["rtl_modes"]
    assert "RETURN_TO_LAUNCH" in rtl and "LAND" in rtl, out["modes"]
    returning = rtl[rtl.index("RETURN_TO_LAUNCH"):rtl.index("LAND")]
    assert set(returning) == {"RETURN_TO_LAUNCH"} and rtl[-1] == "HOLD", out["modes"]
    east, north = out["final"]
    assert math.hypot(east, north, out["final_alt"]) < 2.0, (east, north, out["final_alt"])  # estimated height
    # GLOBAL_POSITION_INT and LOCAL_POSITION_NED tell the same height
    assert out["final_alt"] == pytest.approx(-out["final_down"], abs=0.2), (out["final_alt"], out["final_down"])
    print(f"\nMAVSDK {out['version']}")
    print("\n".join(f"{name}: {dt:.1f} s" for name, dt in out["durations"]))
    print(f"flight modes {out['modes']}")
    print(f"mission progress {out['progress']}; final {east:+.2f} E {north:+.2f} N {out['final_alt']:+.2f} U m "
          f"from home (estimated); whole MAVSDK session {out['total']:.1f} s")
    if teardown_crash:
        print(f"WARNING: MAVSDK crashed in its teardown (exit {code}) after the session\n{log[-2000:]}")


if __name__ == "__main__":
    sys.exit(main())
