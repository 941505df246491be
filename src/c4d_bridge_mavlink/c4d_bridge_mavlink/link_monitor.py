"""GCS link-loss detection for the health monitor.

What: the ground link is *up* while a HEARTBEAT from a ground station (type MAV_TYPE_GCS) has been
accepted — i.e. passed CRC and, when enabled, signature checks in the transport — within
`timeout_s`, on any endpoint. `status(now)` reports up/down, the age of the last GCS heartbeat,
which GCS systems were heard on which endpoints, and counts up→down transitions (losses).
Why heartbeats only: every GCS sends one at 1 Hz whatever else it does, and other traffic may be
forwarded from elsewhere; unsigned or corrupted frames never count (the router drops them
first). Pure logic on a caller-supplied clock, so it is tested without waiting.
"""

from __future__ import annotations

from dataclasses import dataclass

from .signing import mavlink
from .transport import Received

DEFAULT_TIMEOUT_S = 5.0  # five missed 1 Hz heartbeats (ArduPilot's FS_GCS_TIMEOUT default)


@dataclass(frozen=True)
class LinkHealth:
    up: bool
    since_heartbeat_s: float | None  # None: no GCS heartbeat ever
    losses: int
    gcs: tuple[tuple[int, str, float], ...]  # (sysid, endpoint, age s) of every GCS heard, by sysid


class LinkMonitor:
    """Tracks GCS heartbeats; a link is lost after `timeout_s` without one."""

    def __init__(self, timeout_s: float = DEFAULT_TIMEOUT_S) -> None:
        if not timeout_s > 0:
            raise ValueError(f"link-loss timeout must be > 0 s, got {timeout_s!r}")
        self.timeout_s = timeout_s
        self._last: dict[int, tuple[str, float]] = {}  # GCS sysid -> (endpoint, time)
        self._was_up = False
        self.losses = 0

    def observe(self, received: Received, now: float) -> None:
        msg = received.message
        if msg.get_msgId() == mavlink.MAVLINK_MSG_ID_HEARTBEAT and msg.type == mavlink.MAV_TYPE_GCS:
            self._last[msg.get_srcSystem()] = (received.endpoint, now)

    def status(self, now: float) -> LinkHealth:
        latest = max((t for _, t in self._last.values()), default=None)
        age = None if latest is None else max(0.0, now - latest)
        up = age is not None and age <= self.timeout_s
        if self._was_up and not up:
            self.losses += 1
        self._was_up = up
        gcs = tuple((sysid, endpoint, max(0.0, now - t)) for sysid, (endpoint, t) in sorted(self._last.items()))
        return LinkHealth(up, age, self.losses, gcs)
