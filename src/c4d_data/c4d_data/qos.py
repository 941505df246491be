"""QoS profiles as rosbag2 stores them, and the subscription QoS a recorder should request.

Why: `ros2 bag play` re-creates each publisher from the `offered_qos_profiles` of the channel
(metadata version 9: policies as lower-case names, durations as {sec, nsec}, infinite =
{9223372036, 854775807}); a wrong spelling makes playback fall back to defaults or fail. The
request rule is rosbag2's adapt_request_to_offers: reliable only if every publisher is
reliable, transient-local only if every publisher is, so the recorder matches every offer.

Works on anything with rclpy QoSProfile's attribute names (history, depth, reliability,
durability, deadline, lifespan, liveliness, liveliness_lease_duration,
avoid_ros_namespace_conventions); enum members are read by their integer value (rmw's).
"""

from __future__ import annotations

from typing import Any

import yaml

HISTORY = {0: "system_default", 1: "keep_last", 2: "keep_all", 3: "unknown"}
RELIABILITY = {0: "system_default", 1: "reliable", 2: "best_effort", 3: "unknown", 4: "best_available"}
DURABILITY = {0: "system_default", 1: "transient_local", 2: "volatile", 3: "unknown", 4: "best_available"}
LIVELINESS = {0: "system_default", 1: "automatic", 3: "manual_by_topic", 4: "unknown", 5: "best_available"}
RELIABLE, BEST_EFFORT = 1, 2
TRANSIENT_LOCAL, VOLATILE = 1, 2
INFINITE_NS = 9223372036854775807


def _int(value: Any) -> int:
    return int(getattr(value, "value", value))


def _time(duration: Any) -> dict[str, int]:
    ns = int(getattr(duration, "nanoseconds", duration))
    if ns >= INFINITE_NS:
        return {"sec": 9223372036, "nsec": 854775807}
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def profile_dict(qos: Any) -> dict[str, Any]:
    """One offered profile as the rosbag2 v9 YAML mapping (key order as rosbag2 writes it)."""
    return {
        "history": HISTORY.get(_int(qos.history), "unknown"),
        "depth": int(qos.depth),
        "reliability": RELIABILITY.get(_int(qos.reliability), "unknown"),
        "durability": DURABILITY.get(_int(qos.durability), "unknown"),
        "deadline": _time(qos.deadline),
        "lifespan": _time(qos.lifespan),
        "liveliness": LIVELINESS.get(_int(qos.liveliness), "unknown"),
        "liveliness_lease_duration": _time(qos.liveliness_lease_duration),
        "avoid_ros_namespace_conventions": bool(qos.avoid_ros_namespace_conventions),
    }


def profiles_yaml(profiles: list[dict[str, Any]]) -> str:
    """The channel-metadata string `offered_qos_profiles` (a YAML sequence, block style)."""
    if not profiles:
        return ""
    return yaml.safe_dump(profiles, sort_keys=False, default_flow_style=False).rstrip("\n")


def request_for_offers(offers: list[Any]) -> tuple[int, int]:
    """(reliability, durability) integer policies a subscription should request to match all offers."""
    if not offers:
        return BEST_EFFORT, VOLATILE
    reliable = all(_int(q.reliability) == RELIABLE for q in offers)
    latched = all(_int(q.durability) == TRANSIENT_LOCAL for q in offers)
    return (RELIABLE if reliable else BEST_EFFORT), (TRANSIENT_LOCAL if latched else VOLATILE)
