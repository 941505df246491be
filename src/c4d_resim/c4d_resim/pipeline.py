"""Navigation re-simulated in a second process, its states streamed to the core's (this) process.

Why: navigation never reads the core's outputs (its inputs are the recorded samples and the journal's
vehicle-status edges), so the two re-simulations are a pipeline — navigation ahead, the core behind it
reading the states it has produced. On a machine with two free cores the wall time is the slower of
the two instead of their sum (bench/resim_speed.py prints both ways). The child is forked after the
snapshots were loaded and overridden, runs engine.navigation unchanged and sends (stamp, CDR) in
batches; the bytes are the same either way, only where they are computed differs. The pipe's
buffer bounds memory (the child blocks when the core falls behind).
"""

from __future__ import annotations

import multiprocessing
import os
import time
from collections.abc import Iterator
from typing import Any

from c4d_gnc.navigation_filter import NavigationFilter

from .engine import Counts, navigation
from .flight import Flight

BATCH = 128  # states per message: ~66 kB, a quarter of a second of flight


def usable_cpus() -> int:
    """CPUs this process may run on (its affinity mask where the platform has one); 1 inside a daemonic
    process (a pool worker), which may not start children."""
    if multiprocessing.current_process().daemon:
        return 1
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def _child(conn: Any, flight: Flight, filt: NavigationFilter) -> None:
    counts, batch, sending = Counts(), [], 0.0
    start = time.perf_counter()
    try:
        for item in navigation(flight, filt, counts):
            batch.append(item)
            if len(batch) == BATCH:
                t0 = time.perf_counter()
                conn.send(("states", batch))
                sending += time.perf_counter() - t0
                batch = []
        conn.send(("states", batch))
        conn.send(("end", counts.missing, counts.unsupported, time.perf_counter() - start - sending))
    except Exception as exc:  # handed to the parent, which raises it (JournalError: one line)
        conn.send(("error", exc))
    finally:
        conn.close()


class NavigationProcess:
    """engine.navigation run in a forked child; iterate for its (stamp ns, navigation/state CDR), in order.
    `busy_s`: the child's own compute time (without waiting on the pipe), known once iteration ended."""

    def __init__(self, flight: Flight, filt: NavigationFilter, counts: Counts) -> None:
        ctx = multiprocessing.get_context("fork")
        self._recv, send = ctx.Pipe(duplex=False)
        self._proc = ctx.Process(target=_child, args=(send, flight, filt), name="resim-navigation", daemon=True)
        self._proc.start()
        send.close()
        self.counts = counts
        self.busy_s = 0.0

    def __iter__(self) -> Iterator[tuple[int, bytes]]:
        while True:
            try:
                msg = self._recv.recv()
            except EOFError:
                raise RuntimeError(f"resim's navigation process ended early (exit code {self._proc.exitcode})") from None
            if msg[0] == "states":
                yield from msg[1]
            elif msg[0] == "end":
                for what, n in msg[1].items():
                    self.counts.missing[what] = self.counts.missing.get(what, 0) + n
                for what, n in msg[2].items():
                    self.counts.unsupported[what] = self.counts.unsupported.get(what, 0) + n
                self.busy_s = msg[3]
                return
            else:
                raise msg[1]

    def close(self) -> None:
        """Stop the child if it still runs (the core's side raised) and reap it."""
        if self._proc.is_alive():
            self._proc.terminate()
        self._proc.join()
        self._recv.close()
