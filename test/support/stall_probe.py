"""The platform-stall probe: what the machine itself (VM, host) imposes on any code, measured alongside a run.

A separate process at SCHED_FIFO 90 (above every c4d node's priority, so the graph's own load cannot
delay it) sleeps 1 ms at a time and prints, once per second, `<time.monotonic()> <worst oversleep in ms>`.
An oversleep of several ms there is a stall of the platform, not of c4d. Shared by
test/support/interference.py (test_interference, bench/interference.py) and bench/graph_load.py.
"""

from __future__ import annotations

import signal
import subprocess
import sys

PROBE_CODE = """
import os, sys, time
try:  # above every node's priority: the probe sees what the platform (VM, host) imposes, not the graph's load
    os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(90))
except OSError:
    pass
window_end, worst = time.monotonic() + 1.0, 0.0
while True:
    t = time.monotonic(); time.sleep(0.001); gap = time.monotonic() - t - 0.001
    worst = max(worst, gap)
    if time.monotonic() >= window_end:
        print(f"{time.monotonic():.3f} {worst * 1e3:.2f}", flush=True); window_end += 1.0; worst = 0.0
"""


class StallProbe:
    """A separate process that sleeps 1 ms at a time and reports its worst oversleep per second."""

    def __init__(self) -> None:
        self.proc = subprocess.Popen([sys.executable, "-c", PROBE_CODE], stdout=subprocess.PIPE, text=True)

    def stop(self) -> list[tuple[float, float]]:
        self.proc.send_signal(signal.SIGKILL)
        out, _ = self.proc.communicate(timeout=10)
        return [(float(a), float(b)) for a, b in (line.split() for line in out.splitlines() if line.strip())]


def worst_line(stalls: list[tuple[float, float]]) -> str:
    """The line benchmarks print beside their figures: the probe's worst oversleep over the run."""
    worst = max((s for _, s in stalls), default=0.0)
    return f"platform-stall probe: worst oversleep {worst:.2f} ms over {len(stalls)} s"
