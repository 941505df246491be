"""Freedom from interference (issue 13): node restarts during a flight, shared memory vs loopback UDP.

For each DDS transport variant, one `c4d fly` of a 10 m square loop; during cruise, `--kills`
SIGKILLs round-robin over `--nodes`, each followed by the supervisor's restart and a settle time.
Printed side by side: the GNC core's worst tick over the kills and the median of the per-kill
worsts (gnc/executor_stats), skipped ticks, the command stream as the vehicle received it
(sim/actuator_link: worst gap, p99.9 gap, gaps > 20 ms), the true altitude band, the platform
stall probe over the same time, and how the flight ended.

  shm  rmw_fastrtps' LOCALHOST transports as they come (shared memory + UDP): C4D_FASTDDS_PROFILE=""
  udp  c4d's profile (src/c4d_ros/config/fastdds_profile.xml): user data over loopback UDP only

`--stacks` also samples the flight-critical processes with py-spy (Python frames, non-blocking) and
prints the longest runs of consecutive samples inside one call: where a stalled tick's time went.

  . ./env.sh && python bench/interference.py [--kills 10] [--variants shm,udp] [--stacks]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "test" / "support"))
from interference import InterferenceFlight

CRITICAL = ("sim", "navigation", "core")


def variant_env(variant: str, domain: int) -> dict[str, str]:
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    env.pop("FASTRTPS_DEFAULT_PROFILES_FILE", None)
    if variant == "shm":
        env["C4D_FASTDDS_PROFILE"] = ""
    else:
        env.pop("C4D_FASTDDS_PROFILE", None)
        from c4d_ros.dds_profile import profile_path
        env["FASTRTPS_DEFAULT_PROFILES_FILE"] = str(profile_path())
    return env


def longest_calls(speedscope: Path, rate_hz: float, top: int = 3) -> list[str]:
    """Longest runs of consecutive main-thread samples in one non-idle innermost call."""
    data = json.loads(speedscope.read_text())
    frames = data["shared"]["frames"]
    runs: list[tuple[int, str]] = []
    for profile in data["profiles"]:
        if "MainThread" not in profile["name"]:
            continue
        current, count = None, 0
        for sample in [*profile["samples"], []]:
            key = " < ".join(frames[i]["name"] for i in reversed(sample[-3:])) if sample else None
            if key == current:
                count += 1
                continue
            if current and count >= 3 and not any(w in current for w in ("sleep", "spin_once", "spin_node")):
                runs.append((count, current))
            current, count = key, 1
    runs.sort(reverse=True)
    return [f"{n / rate_hz * 1e3:5.0f} ms in {k}" for n, k in runs[:top]]


def fly_variant(variant: str, args, domain: int, root: Path) -> dict:
    flight = InterferenceFlight(root / variant, variant_env(variant, domain), cruise_s=args.kills * args.interval + 10)
    spies: dict[str, tuple[subprocess.Popen, Path]] = {}
    try:
        if not flight.wait_cruise():
            return {"result": "no cruise: " + flight.fly_log()[-300:]}
        if args.stacks:
            for name in CRITICAL:
                out = root / f"{variant}-{name}.json"
                spies[name] = (subprocess.Popen(["py-spy", "record", "--nonblocking", "--idle", "-r", "250", "-f", "speedscope",
                                                 "-o", str(out), "--pid", str(flight.pids()[name])],
                                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL), out)
        baseline = flight.close_window(flight.open_window("baseline"), settle_s=4.0)
        nodes = args.nodes.split(",")
        kills = []
        for k in range(args.kills):
            w = flight.open_window(nodes[k % len(nodes)])
            flight.kill_and_wait_restart(w.label)
            kills.append(flight.close_window(w, settle_s=args.interval))
        for proc, _ in spies.values():
            proc.send_signal(2)
        for proc, _ in spies.values():
            proc.wait(30)
        code = flight.finish()
        link = dict(flight.obs.link)
        result = next((line.split(None, 1)[1] for line in flight.fly_log().splitlines() if line.startswith("flight ")), "?")
        return {"baseline": baseline, "kills": kills, "link": link, "fly_exit": code, "result": result,
                "stacks": {n: longest_calls(p, 250.0) for n, (_, p) in spies.items() if p.exists()}}
    finally:
        flight.close()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--kills", type=int, default=10)
    ap.add_argument("--interval", type=float, default=4.0, help="settle time after each restart [s]")
    ap.add_argument("--nodes", default="recorder,bridge,payload,mission,health")
    ap.add_argument("--variants", default="shm,udp")
    ap.add_argument("--stacks", action="store_true")
    ap.add_argument("--domain", type=int, default=88)
    args = ap.parse_args()
    if args.stacks and not shutil.which("py-spy"):
        print("interference: error: --stacks needs py-spy (pip install py-spy)", file=sys.stderr)
        return 2
    root = Path(tempfile.mkdtemp(prefix="c4d-interference-"))
    results = {v: fly_variant(v, args, args.domain + i, root) for i, v in enumerate(args.variants.split(","))}
    print(f"\n{args.kills} kills ({args.nodes}), {args.interval:g} s apart, one flight per variant; runs in {root}")
    rows = [("core worst tick, all kills [ms]", lambda r: max(w.worst_tick_ms for w in r["kills"])),
            ("core worst tick, median of kills [ms]", lambda r: statistics.median(w.worst_tick_ms for w in r["kills"])),
            ("core worst tick, 4 s before kills [ms]", lambda r: r["baseline"].worst_tick_ms),
            ("skipped ticks during kills", lambda r: sum(w.skipped_ticks for w in r["kills"])),
            ("vehicle: worst command gap, whole flight [ms]", lambda r: r["link"].get("max_gap_ms", float("nan"))),
            ("vehicle: p99.9 command gap [ms]", lambda r: r["link"].get("p999_gap_ms", float("nan"))),
            ("vehicle: gaps > 20 ms", lambda r: r["link"].get("gaps_over_20ms", float("nan"))),
            ("true altitude min during kills [m]", lambda r: min(w.min_alt for w in r["kills"])),
            ("true altitude max during kills [m]", lambda r: max(w.max_alt for w in r["kills"])),
            ("platform stall probe, worst [ms]", lambda r: max(w.platform_stall_ms for w in r["kills"]))]
    names = list(results)
    print(f"{'':46s}" + "".join(f"{n:>12s}" for n in names))
    for label, fn in rows:
        cells = []
        for n in names:
            try:
                cells.append(f"{fn(results[n]):12.1f}")
            except (KeyError, ValueError, TypeError):
                cells.append(f"{'-':>12s}")
        print(f"{label:46s}" + "".join(cells))
    for n in names:
        print(f"{n}: flight {results[n].get('result')}")
        for w in results[n].get("kills", []):
            print(f"  kill {w.label:9s} worst tick {w.worst_tick_ms:6.1f} ms  skipped {w.skipped_ticks:4d}  "
                  f"alt {w.min_alt:5.2f}..{w.max_alt:5.2f} m  stall probe {w.platform_stall_ms:5.1f} ms")
        for proc, calls in results[n].get("stacks", {}).items():
            print(f"  {proc}: " + "; ".join(calls))
    return 0


if __name__ == "__main__":
    t0 = time.monotonic()
    code = main()
    print(f"bench time {time.monotonic() - t0:.0f} s")
    sys.exit(code)
