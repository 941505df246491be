"""The named QoS profiles of c4d (docs/ARCHITECTURE.md § QoS profiles is generated from here).

Every publisher and subscription of the graph uses one of these, chosen per topic by the
interface manifest (`c4d_ros.manifest`), so that producers and consumers always match:
a best-effort publisher never meets a reliable subscription, a latched topic is latched on
both sides.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy


@dataclass(frozen=True)
class ProfileSpec:
    """What a profile promises, in the words of the docs table."""

    reliable: bool
    transient_local: bool
    depth: int
    use: str

    def profile(self) -> QoSProfile:
        return QoSProfile(
            history=HistoryPolicy.KEEP_LAST, depth=self.depth,
            reliability=ReliabilityPolicy.RELIABLE if self.reliable else ReliabilityPolicy.BEST_EFFORT,
            durability=DurabilityPolicy.TRANSIENT_LOCAL if self.transient_local else DurabilityPolicy.VOLATILE)


class Profile(Enum):
    """c4d's QoS presets (like rclpy.qos.qos_profile_sensor_data, with c4d's depths)."""

    SENSOR = ProfileSpec(False, False, 5, "raw and conditioned sensor streams: newest data wins, a lost sample is not resent")
    IMU = ProfileSpec(False, False, 50, "IMU streams: as sensor, deep enough for the sim's catch-up burst after a stall "
                                        "(navigation integrates every sample)")
    STATE = ProfileSpec(False, False, 1, "vehicle state, setpoints, actuator commands: only the newest sample matters")
    COMMAND = ProfileSpec(True, False, 50, "events that must all arrive (captures)")
    LATCHED = ProfileSpec(True, True, 1, "status, schedule table, mission plan/state: late joiners get the last one")
    STATS = ProfileSpec(True, False, 10, "diagnostics, executor and link statistics")

    @property
    def qos(self) -> QoSProfile:
        return self.value.profile()


SENSOR = Profile.SENSOR.qos
IMU = Profile.IMU.qos
STATE = Profile.STATE.qos
COMMAND = Profile.COMMAND.qos
LATCHED = Profile.LATCHED.qos
STATS = Profile.STATS.qos


def newest_only(profile: QoSProfile) -> QoSProfile:
    """`profile` for a reader that uses only the newest sample (depth 1): same reliability and
    durability, so it matches the writer, but after a stall it does not wade through a burst it
    would throw away (the core's gyro: one take per tick instead of up to 50)."""
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=profile.reliability,
                      durability=profile.durability)
