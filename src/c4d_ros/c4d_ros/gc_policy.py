"""Garbage-collector discipline for the event-driven 500 Hz processes (perception, navigation).

Why: CPython's automatic full (generation 2) collection walks every tracked object of the process;
in a navigation process that is ~40 000 objects of rclpy, numpy and message types and a pause of
~11 ms (measured) — five 500 Hz samples — at an unpredictable moment in a message callback. The
core's and the sim's executives already freeze the start-up heap and collect only in their slack
(c4d_sched.executive, manage_gc). `LoopGc` does the same for a process spun by an rclpy executor:
the first tick (after start-up, from a timer) collects once and freezes what exists (the frozen
objects are never walked again), automatic collection is switched off, and each later tick collects
the young generations when enough allocations piled up, plus a full collection of the (small,
unfrozen) rest every `full_period_s` so no cyclic garbage is kept for ever.
"""

from __future__ import annotations

import gc
import time
from collections.abc import Callable


class LoopGc:
    """See the module docstring; `tick()` from a low-rate timer, `release()` at shutdown."""

    def __init__(self, young_threshold: int = 2000, full_period_s: float = 10.0,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.young_threshold, self.full_period_s, self.clock = young_threshold, full_period_s, clock
        self.started = False
        self.next_full = 0.0
        self.collections = [0, 0, 0]  # per generation, since start

    def tick(self) -> int | None:
        """Collect if due; return the generation collected (None: nothing to do)."""
        now = self.clock()
        if not self.started:
            gc.collect()
            gc.freeze()
            gc.disable()
            self.started, self.next_full = True, now + self.full_period_s
            return self._count(2)
        if now >= self.next_full:
            self.next_full = now + self.full_period_s
            gc.collect(2)
            return self._count(2)
        young, middle, _ = gc.get_count()
        if young > self.young_threshold:
            generation = 0 if middle < 10 else 1
            gc.collect(generation)
            return self._count(generation)
        return None

    def _count(self, generation: int) -> int:
        self.collections[generation] += 1
        return generation

    def release(self) -> None:
        """Automatic collection back on, the start-up heap unfrozen (after the loop ended)."""
        if self.started:
            gc.enable()
            gc.unfreeze()
            self.started = False


PROCESS = LoopGc()  # one per process: composed nodes share it (ticking it from several timers is harmless)
TICK_PERIOD_S = 0.1


def install(node, period_s: float = TICK_PERIOD_S) -> None:
    """Drive the process's LoopGc from a timer of `node` (the first tick runs once spinning started)."""
    node.create_timer(period_s, PROCESS.tick)
