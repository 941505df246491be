#!/usr/bin/env python3
"""GNSS integrity monitor: false alarms per flight-hour and detection times, open loop.

Seeded survey flights (test/support/gnss_flights.py: lawnmower legs at 3-5 m/s, U-turns, a climb)
through the simulator's sensor models (c4d_sim.sensors, 500 Hz IMU, 10 Hz GNSS with σ_h 0.3 m)
into the real NavigationEkf and c4d_gnc.gnss_integrity with its default thresholds:
  nominal    N flights without a fault: SPOOFED / JAMMED episodes per flight-hour, the largest score
  faults     M flights per fault, injected FAULT_T s into the flight (in the survey): time from the
             fault to SPOOFED (spoofing) or JAMMED/SPOOFED (jamming), median and max, and the missed
             ones (nothing within the rest of the flight), side by side without / with an external
             position source (the external cross-check; the source is given to the monitor only)
Prints the platform-stall probe's worst oversleep (a stall there is the machine's; the figures here
are flight-time figures, not timings).

Run under the graph lock: `flock /tmp/c4d_graph.lock python bench/gnss_integrity.py [--flights 20 --fault-flights 5]`.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "test" / "support"))
from gnss_flights import Fault, fly  # noqa: E402
from stall_probe import StallProbe  # noqa: E402

from c4d_gnc.gnss_integrity import IntegrityConfig  # noqa: E402

FAULT_T = 40.0  # [s] into the flight: in the survey (legs start at 12 s)
FAULTS = [("drift 0.2 m/s", "drift", 0.2), ("drift 0.5 m/s", "drift", 0.5), ("drift 1 m/s", "drift", 1.0),
          ("drift 2 m/s", "drift", 2.0), ("jump 2 m", "jump", 2.0), ("jump 5 m", "jump", 5.0),
          ("jump 20 m", "jump", 20.0), ("meaconing 0.5 s", "delay", 0.5), ("meaconing 2 s", "delay", 2.0),
          ("jamming dropout 50 %", "dropout", 0.5), ("jamming dropout 90 %", "dropout", 0.9),
          ("jamming sigma x5", "sigma", 5.0)]


def summary(times: list[float]) -> str:
    found = [t for t in times if math.isfinite(t)]
    missed = len(times) - len(found)
    if not found:
        return f"{'missed':>8} {'':>7} {missed:>2}/{len(times)}"
    return f"{statistics.median(found):8.2f} {max(found):7.2f} {missed:>2}/{len(times)}"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--flights", type=int, default=20, help="nominal flights")
    parser.add_argument("--seconds", type=float, default=120.0, help="[s] each nominal flight")
    parser.add_argument("--fault-flights", type=int, default=5, help="flights per fault and source setting")
    parser.add_argument("--fault-seconds", type=float, default=70.0, help="[s] each fault flight")
    args = parser.parse_args()
    if min(args.flights, args.fault_flights) < 1 or args.seconds < 30 or args.fault_seconds < FAULT_T + 10:
        parser.error(f"need >= 1 flight, --seconds >= 30 and --fault-seconds >= {FAULT_T + 10:g}")
    config = IntegrityConfig()
    probe = StallProbe()
    start = time.monotonic()
    try:
        alarms, scores = 0, []
        for seed in range(args.flights):
            result = fly(seed, args.seconds, config=config)
            alarms += result.false_alarms()
            scores.append(max((v.score for _, v in result.verdicts if v.state.name != "UNKNOWN"), default=0.0))
        hours = args.flights * args.seconds / 3600.0
        print(f"nominal: {args.flights} flights x {args.seconds:g} s ({hours:.2f} flight-hours, 3-5 m/s survey)")
        print(f"  false alarms (SPOOFED/JAMMED episodes): {alarms}  = {alarms / hours:.2f} per flight-hour")
        print(f"  largest score per flight (alarm at 1): median {statistics.median(scores):.2f}, max {max(scores):.2f}")
        print(f"\nfaults at t = {FAULT_T:g} s, {args.fault_flights} flights each; detection [s]: median, max, missed")
        print(f"{'fault':24} {'no external source':>22}   {'external source':>22}")
        for label, kind, value in FAULTS:
            row = []
            for external in (False, True):
                times = []
                for k in range(args.fault_flights):
                    seed = 1000 + k
                    fault = Fault(FAULT_T, kind, value, direction=0.7 * seed)
                    times.append(fly(seed, args.fault_seconds, fault=fault, external=external, config=config).detection_s())
                row.append(summary(times))
            print(f"{label:24} {row[0]:>22}   {row[1]:>22}", flush=True)
    finally:
        stalls = probe.stop()
    worst = max((s for _, s in stalls), default=0.0)
    print(f"\nwall time {time.monotonic() - start:.0f} s; platform-stall probe: worst oversleep {worst:.2f} ms "
          f"over {len(stalls)} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
