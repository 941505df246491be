"""When the core publishes vehicle/status, without ROS.

The status goes out on every change of (armed, mode, navigation state, landed state, setpoint
source) and at
least every `period_s` — that periodic message is also the heartbeat the health monitor
watches. The cadence also remembers when the vehicle was armed (the status carries it).
"""

from __future__ import annotations

from .gnc import Outputs

STATUS_PERIOD_S = 0.2  # 5 Hz: also the heartbeat health watches


class StatusCadence:
    def __init__(self, period_s: float = STATUS_PERIOD_S) -> None:
        self.period_s = period_s
        self.arm_time_ns = 0  # clock time of the last arming
        self._armed = False
        self._key: tuple[object, ...] | None = None
        self._sent = 0.0

    def due(self, out: Outputs, now: float) -> bool:
        """Note `out` at clock time `now` [s]; True when a status message is due now."""
        if out.armed and not self._armed:
            self.arm_time_ns = int(now * 1e9)
        self._armed = out.armed
        key = (out.armed, out.mode, out.nav, out.landed, out.source)
        if key != self._key or now - self._sent >= self.period_s:
            self._key, self._sent = key, now
            return True
        return False
