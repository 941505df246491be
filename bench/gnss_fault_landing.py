#!/usr/bin/env python3
"""How far a vehicle that loses GNSS, or has it spoofed, with no other horizontal source drifts before
it is on the ground — without and with drag fusion, side by side.

Seeded closed loop with the real navigation filter in it (test/support/navigation_loop.py: plant,
c4d_sim sensor models, NavigationFilter, GNC core; health's policy by its timing): take off to 5 m,
hover, then
  spoof   the fixes drift east at 1 m/s → SPOOFED verdict, HOLD 1 s later, LAND 1 s after that
  jam     no fix any more → HOLD 2 s later, LAND 1 s after that
and the flight ends at disarm; and a 30 s hover on GNSS in still air, a steady wind and gusts (what drag
fusion costs while GNSS is good: the estimate's horizontal velocity error against the plant's).
Figures: the true horizontal distance from where the fault started — the farthest (median, max over the
seeds) and at touchdown (median) — and, for spoofing, the time to the
verdict. Drag off = EkfConfig() (inertial dead reckoning: the core flies level once the position is
invalid); drag on = drag_config(quad_x) (the navigation node's default). Deterministic: flight-time
figures, not timings; the platform-stall probe is printed anyway.

`python bench/gnss_fault_landing.py [--seeds 8]`"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "test" / "support"))
from navigation_loop import FaultFlight, fly_gnss_fault, hover_in_wind  # noqa: E402
from stall_probe import StallProbe, worst_line  # noqa: E402

from c4d_sim.world import WindField  # noqa: E402

WINDS = (("still air", WindField()), ("steady 3 m/s east", WindField((3.0, 0.0, 0.0))),
         ("gust 2 m/s, 6 s period", WindField((0.0, 0.0, 0.0), 2.0, 6.0)),
         ("2.8 m/s NE + gust 3 m/s", WindField((2.0, 2.0, 0.0), 3.0, 6.0)))


def summary(flights: list[FaultFlight]) -> str:
    farthest = [f.farthest_m for f in flights]
    touchdown = statistics.median(f.touchdown_m for f in flights)
    return f"{statistics.median(farthest):5.2f} / {max(farthest):5.2f} / {touchdown:5.2f}"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=8, help="flights per fault and configuration")
    args = parser.parse_args()
    if args.seeds < 1:
        parser.error("--seeds must be >= 1")
    probe = StallProbe()
    start = time.monotonic()
    try:
        print(f"{args.seeds} seeded flights each; true horizontal distance from the fault's start [m]: "
              "farthest median / max / touchdown median")
        print(f"{'fault':34} {'drag fusion off':>21}   {'drag fusion on':>21}   worst on/off")
        for label, fault in (("spoofed 1 m/s drift, no alternative", "spoof"), ("GNSS lost in hover", "jam")):
            runs = {drag: [fly_gnss_fault(seed, fault, drag=drag) for seed in range(1, args.seeds + 1)]
                    for drag in (False, True)}
            ratio = max(f.farthest_m for f in runs[True]) / max(f.farthest_m for f in runs[False])
            print(f"{label:34} {summary(runs[False]):>21}   {summary(runs[True]):>21}   {ratio:.2f}x", flush=True)
            if fault == "spoof":
                flagged = {d: statistics.median(f.flagged_s for f in runs[d]) for d in (False, True)}
                print(f"{'  SPOOFED after [s], median':34} {flagged[False]:>21.2f}   {flagged[True]:>21.2f}")
        print(f"\nhover on GNSS, {min(args.seeds, 3)} seeds: velocity error RMS / max [m/s] "
              "(drag samples gated), wind error [m/s]")
        print(f"{'wind':34} {'drag fusion off':>21}   {'drag fusion on':>30}")
        for label, wind in WINDS:
            hovers = {drag: [hover_in_wind(seed, drag, wind) for seed in range(1, min(args.seeds, 3) + 1)]
                      for drag in (False, True)}
            cells = []
            for drag in (False, True):
                h = hovers[drag]
                cell = f"{statistics.mean(x.velocity_rms for x in h):.3f} / {max(x.velocity_max for x in h):.3f}"
                if drag:
                    cell += f" ({sum(x.drag_rejected for x in h)}), {max(x.wind_error for x in h):.2f}"
                cells.append(cell)
            print(f"{label:34} {cells[0]:>21}   {cells[1]:>30}", flush=True)
    finally:
        stalls = probe.stop()
    print(f"\nwall time {time.monotonic() - start:.0f} s; {worst_line(stalls)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
