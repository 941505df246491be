"""Offboard streaming for c4d_client: a background thread that publishes the current setpoint on
offboard/trajectory_setpoint at a fixed rate, and the switch into OFFBOARD once the stream is live.

Why a thread: the core enters and stays in OFFBOARD only while the stream is live (>= 2 Hz,
entry after >= 1 s of it) — a script that computes between two `set_*` calls must not starve it.
The script only replaces the setpoint; the thread re-stamps and re-sends it.
"""

from __future__ import annotations

import math
import threading
import time
from typing import Any

from c4d_interfaces.msg import GuidanceSetpoint, VehicleStatus

from .errors import CommandRefused, VehicleTimeout

NAN = math.nan
ENTRY_AFTER_S = 1.1  # [s] of live stream before OFFBOARD is requested (the core needs >= 1 s)


def setpoint(level: int, position: tuple[float, float, float] = (NAN, NAN, NAN),
             velocity: tuple[float, float, float] = (NAN, NAN, NAN),
             acceleration: tuple[float, float, float] = (NAN, NAN, NAN), yaw: float = NAN,
             yaw_rate: float = NAN) -> GuidanceSetpoint:
    """A GuidanceSetpoint in `map` (ENU) with NaN in every field not given (NaN = unset)."""
    sp = GuidanceSetpoint(control_level=level, yaw=float(yaw), yaw_rate=float(yaw_rate), thrust=NAN,
                          max_horizontal_speed=NAN, max_vertical_speed=NAN)
    sp.header.frame_id = "map"
    sp.position.x, sp.position.y, sp.position.z = map(float, position)
    sp.velocity.x, sp.velocity.y, sp.velocity.z = map(float, velocity)
    sp.acceleration.x, sp.acceleration.y, sp.acceleration.z = map(float, acceleration)
    return sp


class OffboardStream:
    """`with vehicle.offboard() as ob:` — streams from the moment it is entered (first setpoint:
    hold where the vehicle is), enters OFFBOARD after ENTRY_AFTER_S, and on exit commands HOLD
    (if the vehicle is still in OFFBOARD) and stops the stream. `set_position` / `set_velocity` /
    `set_setpoint` replace the streamed setpoint (thread-safe). `vehicle` is the c4d_client.Vehicle
    (typed Any: vehicle.py imports this module)."""

    def __init__(self, vehicle: Any, rate_hz: float = 50.0, enter: bool = True, enter_timeout: float = 5.0) -> None:
        if not 2.0 <= rate_hz <= 100.0:
            raise ValueError(f"offboard rate {rate_hz} Hz outside [2, 100] Hz (the core needs >= 2 Hz, the gateway "
                             "passes at most 100 Hz)")
        self.vehicle, self.period, self.enter_offboard, self.enter_timeout = vehicle, 1.0 / rate_hz, enter, enter_timeout
        self.lock = threading.Lock()
        self.current: GuidanceSetpoint | None = None
        self.stop_event = threading.Event()
        self.thread: threading.Thread | None = None
        self.sent = 0

    # ------------------------------------------------------------------ the script's side
    def set_position(self, x: float, y: float, z: float, yaw: float = NAN,
                     velocity: tuple[float, float, float] = (NAN, NAN, NAN),
                     acceleration: tuple[float, float, float] = (NAN, NAN, NAN)) -> None:
        """Fly to / hold (x, y, z) in map ENU [m], optional heading [rad, ENU] and velocity /
        acceleration feed-forward (NaN = none)."""
        self.set_setpoint(setpoint(GuidanceSetpoint.LEVEL_POSITION, (x, y, z), velocity, acceleration, yaw))

    def set_velocity(self, vx: float, vy: float, vz: float, yaw: float = NAN, yaw_rate: float = NAN) -> None:
        """Fly at (vx, vy, vz) [m/s] in map ENU; heading `yaw` [rad] or turn at `yaw_rate` [rad/s]."""
        self.set_setpoint(setpoint(GuidanceSetpoint.LEVEL_VELOCITY, velocity=(vx, vy, vz), yaw=yaw, yaw_rate=yaw_rate))

    def set_setpoint(self, sp: GuidanceSetpoint) -> None:
        """Stream any GuidanceSetpoint (any level; its header is re-stamped at every send)."""
        with self.lock:
            self.current = sp

    # ------------------------------------------------------------------ life cycle
    def start(self) -> OffboardStream:
        x, y, z = self.vehicle.position
        self.set_position(x, y, z)
        self.thread = threading.Thread(target=self._stream, name="c4d_client offboard", daemon=True)
        self.thread.start()
        if self.enter_offboard:
            self._enter()
        return self

    def _enter(self) -> None:
        started = time.monotonic()
        time.sleep(ENTRY_AFTER_S)
        while True:
            try:
                self.vehicle.set_mode(VehicleStatus.MODE_OFFBOARD)
                break
            except CommandRefused as exc:
                if exc.result != 1 or time.monotonic() - started > self.enter_timeout:  # 1 = TEMPORARILY_REJECTED
                    self.stop(hold=False)
                    raise
                time.sleep(0.2)
        if not self.vehicle.wait_for(lambda st: st.flight_mode == VehicleStatus.MODE_OFFBOARD, self.enter_timeout):
            self.stop(hold=False)
            raise VehicleTimeout("offboard", "the status never showed OFFBOARD")

    def stop(self, hold: bool = True) -> None:
        """HOLD (when `hold` and the vehicle is still in OFFBOARD: the core holds in AUTO where the
        vehicle is), then stop streaming."""
        status = self.vehicle.status
        if hold and status is not None and status.flight_mode == VehicleStatus.MODE_OFFBOARD:
            self.vehicle.hold()
        self.stop_event.set()
        if self.thread is not None:
            self.thread.join(timeout=2.0)

    def _stream(self) -> None:
        deadline = time.monotonic()
        while not self.stop_event.is_set():
            with self.lock:
                sp = self.current
            if sp is not None:
                sp.header.stamp = self.vehicle.node.get_clock().now().to_msg()
                self.vehicle.setpoint_pub.publish(sp)
                self.sent += 1
            deadline += self.period
            delay = deadline - time.monotonic()
            if delay <= 0:
                deadline, delay = time.monotonic(), 0.0  # late: no catch-up burst
            self.stop_event.wait(delay)

    def __enter__(self) -> OffboardStream:
        return self.start()

    def __exit__(self, *exc: Any) -> None:
        self.stop(hold=True)
