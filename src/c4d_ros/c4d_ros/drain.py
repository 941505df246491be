"""Non-blocking drain of rclpy subscriptions and services for a cyclic executive's input phase.

Why: an executor's spin_once(timeout_sec=0) builds a wait set every call — ~90–170 µs even
when nothing is ready (measured, rclpy 7.1) — which would eat most of a 2 ms tick. The
Drainer instead takes whatever is already queued on each subscription and service, with the
same rclpy take calls the executors use internally (~1 µs when empty), runs the callback, and
returns. Nothing ever waits. Call `drain()` once per tick.
"""

from __future__ import annotations

from collections.abc import Callable


class Drainer:
    def __init__(self, node) -> None:
        self.node = node
        self.subscriptions: list[tuple[object, Callable]] = []
        self.services: list[tuple[object, Callable]] = []

    def subscription(self, msg_type, topic: str, callback: Callable, qos, raw: bool = False) -> None:
        """Drain `topic` into `callback`; raw=True hands over the serialized bytes (c4d_ros.cdr reads the
        few fields a hot path needs in ~1 µs, rclpy's message conversion costs ~40 µs for an Imu)."""
        sub = self.node.create_subscription(msg_type, topic, callback, qos, raw=raw)
        self.subscriptions.append((sub, callback))

    def service(self, srv_type, name: str, handler: Callable) -> None:
        srv = self.node.create_service(srv_type, name, handler)
        self.services.append((srv, handler))

    def adopt_node_services(self) -> None:
        """Serve the node's own services (rclpy's parameter services: get/set/list/describe)
        from drain() too. Why: then no executor needs to spin this node at all — an executor
        would also wake for every sample of the drained subscriptions (an EventsExecutor even
        queues one event per sample, faster than a few spin_once calls can consume them)."""
        known = {id(srv) for srv, _ in self.services}
        for srv in self.node.services:
            if id(srv) not in known:
                self.services.append((srv, srv.callback))

    def drain(self, limit: int = 64) -> int:
        """Run the callbacks of everything queued (at most `limit` per entity); return how many."""
        handled = 0
        for sub, callback in self.subscriptions:
            for _ in range(limit):
                with sub.handle:
                    taken = sub.handle.take_message(sub.msg_type, sub.raw)
                if taken is None:
                    break
                callback(taken[0])
                handled += 1
        for srv, handler in self.services:
            for _ in range(limit):
                with srv.handle:
                    taken = srv.handle.service_take_request(srv.srv_type.Request)
                if taken is None or taken[0] is None:
                    break
                request, header = taken
                srv.send_response(handler(request, srv.srv_type.Response()), header)
                handled += 1
        return handled


class LatestSampler:
    """The newest sample of a high-rate topic, for a node that only needs it at a low rate.

    Why: an rclpy executor wakes up and runs Python for every sample it is subscribed to — a
    500 Hz VehicleState costs a fifth of a core per subscribing node on these machines. The
    subscription here lives on a hidden side node that no executor spins, with keep-last-1 QoS,
    so DDS just overwrites the newest sample and `latest()` takes it (~µs) when the owner's
    timer asks.
    """

    def __init__(self, side_node, msg_type, topic: str, qos) -> None:
        self._sub = side_node.create_subscription(msg_type, topic, lambda msg: None, qos)
        self._latest = None

    def latest(self):
        """The newest sample received so far (None before the first); never blocks."""
        sub = self._sub
        while True:
            with sub.handle:
                taken = sub.handle.take_message(sub.msg_type, sub.raw)
            if taken is None:
                return self._latest
            self._latest = taken[0]
