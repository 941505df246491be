"""Lifecycle states of the flight-critical nodes, from their `transition_event` topics (ROS-free).

What: every managed node publishes `lifecycle_msgs/TransitionEvent` on `/<node>/transition_event`
for each step of a transition (e.g. activate: goal ACTIVATING, then goal ACTIVE). `LifecycleWatch`
keeps each watched node's last goal state (`on_transition(node, goal_state_id)`) and
`not_active(armed)` lists the nodes that announced a state other than ACTIVE and have not come back
to ACTIVE since — the health event `node_inactive`.

Which nodes: the ones health watches for liveness (health_node.WATCHED minus `unwatched_nodes`:
core, navigation, perception, mission, sim) — the flight loop stops without each of them, so no
bundled system mode deactivates them in flight. Nodes a mode deactivates on purpose (payload,
offboard) are not watched at all. `mission` is deactivated on purpose in the `maintenance` phase,
which is a ground phase: nodes in `armed_only` (mission) count only while the vehicle is armed.

The rule, and why: a node never heard from is UNKNOWN, not inactive. `transition_event` is volatile
(no history for late joiners): a node that autostarted before health subscribed announced its
transitions to nobody, and calling it inactive would warn about every healthy graph. Liveness
(node_dead / node_stalled) already covers a node that never shows up. A node heard in a transition
state (ACTIVATING, CONFIGURING, ...) is not ACTIVE yet: reported until its ACTIVE arrives (an
activation takes milliseconds; the policy's delay absorbs it).
"""

from __future__ import annotations

from collections.abc import Iterable

# lifecycle_msgs/msg/State ids (kept here so this module needs no ROS; the test checks them)
UNKNOWN, UNCONFIGURED, INACTIVE, ACTIVE, FINALIZED = 0, 1, 2, 3, 4
STATE_NAMES = {UNKNOWN: "unknown", UNCONFIGURED: "unconfigured", INACTIVE: "inactive", ACTIVE: "active",
               FINALIZED: "finalized", 10: "configuring", 11: "cleaning up", 12: "shutting down", 13: "activating",
               14: "deactivating", 15: "error processing"}
ARMED_ONLY = ("mission",)  # deactivated on purpose in the maintenance phase (on the ground)


def state_name(state: int) -> str:
    return STATE_NAMES.get(state, f"state {state}")


class LifecycleWatch:
    """Last announced lifecycle state per watched node; `not_active` = the node_inactive event."""

    def __init__(self, nodes: Iterable[str], armed_only: Iterable[str] = ARMED_ONLY) -> None:
        self.nodes = tuple(nodes)
        self.armed_only = frozenset(armed_only)
        self.states: dict[str, int] = {}  # node -> last goal state id; absent: never heard (unknown)

    def on_transition(self, node: str, goal_state: int) -> None:
        """A TransitionEvent of `node` (its goal_state.id); other nodes' events are ignored."""
        if node in self.nodes:
            self.states[node] = int(goal_state)

    def state(self, node: str) -> int:
        return self.states.get(node, UNKNOWN)

    def not_active(self, armed: bool) -> tuple[str, ...]:
        """The watched nodes heard in a state other than ACTIVE (sorted), as "name (state)"; the
        `armed_only` ones only while armed."""
        return tuple(f"{node} ({state_name(state)})" for node, state in sorted(self.states.items())
                     if state != ACTIVE and (armed or node not in self.armed_only))
