#!/usr/bin/env python3
"""The navigation filter's cost per sample before (7509a19: EKF + NavigationFilter without history,
sources or integrity) and after issue 19, in-process, the real classes, interleaved rounds.

  imu       NavigationFilter.imu: prediction (+ after: the state-history push and the 5 Hz tick)
  gnss      one fix (before: against the current state moved by v·age; after: the state at its
            sample time, the integrity monitor's check_fix, the journal)
  external  one accepted external pose, 30 ms old, fused at its sample time (after only)
  flood     one external sample dropped by the rate limit (what each extra sample of a 1 kHz flood costs)
  replay    what a rewind/replay of 30 ms at 500 Hz would cost instead (15 predictions, measured)
  drag      one drag-fusion update (10 Hz in flight; part of every 50th imu sample)
The "after" filters are the navigation node's default: drag fusion on with quad_x's coefficients (17 states).
Prints medians and p99 in µs, the after/before ratio, the CPU share at the sample rate, and the
platform-stall probe's worst oversleep (a stall there is the machine's, not c4d's).

Run under the graph lock: `flock /tmp/c4d_graph.lock python bench/navigation_cost.py [--samples 20000]`.
"""

from __future__ import annotations

import argparse
import importlib
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "test" / "support"))
from stall_probe import StallProbe, worst_line  # noqa: E402

from c4d_common.airframe import default_airframe_path, load_airframe  # noqa: E402
from c4d_common.geodesy import GeoOrigin  # noqa: E402
from c4d_gnc.ekf import NavigationEkf, drag_config  # noqa: E402
from c4d_gnc.external_pose import ExternalSample  # noqa: E402
from c4d_gnc.navigation_filter import NavigationConfig, NavigationFilter  # noqa: E402
from c4d_gnc.source_selection import EXTERNAL, GNSS, NONE  # noqa: E402

BEFORE = "7509a19"
HOME = GeoOrigin(43.5629, 1.4815, 146.0)
G, STILL, FIELD, DT = (0.0, 0.0, 9.80665), (0.0, 0.0, 0.0), (0.0, 2.2e-5, -4.2e-5), 0.002


def before_modules(tmp: Path):
    """The 7509a19 ekf.py and navigation_filter.py as package `nav_before`."""
    package = tmp / "nav_before"
    package.mkdir()
    (package / "__init__.py").write_text("")
    for name in ("ekf", "navigation_filter"):
        source = subprocess.run(["git", "-C", str(ROOT), "show", f"{BEFORE}:src/c4d_gnc/c4d_gnc/{name}.py"],
                                capture_output=True, text=True, check=True).stdout
        (package / f"{name}.py").write_text(source)
    sys.path.insert(0, str(tmp))
    return importlib.import_module("nav_before.ekf"), importlib.import_module("nav_before.navigation_filter")


class Rig:
    """A filter standing still, fed on its own clock; `t` advances with each IMU sample."""

    def __init__(self, flt) -> None:
        self.f, self.t, self.k = flt, 0.0, 0
        flt.on_ground = True  # disarmed: zero-velocity updates converge the gyro bias, then home is set
        while self.t < 3.0 or (flt.ekf.origin is None and self.t < 15.0):
            self.imu()
            if self.k % 50 == 0:
                self.gnss()
        flt.on_ground = False  # then armed: the figures are the flying path's

    def imu(self) -> None:
        self.k += 1
        self.t = self.k * DT
        if self.k % 10 == 0:
            self.f.magnetometer(FIELD)
        self.f.imu(self.t, STILL, G)

    def gnss(self) -> None:
        lat, lon, alt = HOME.to_geodetic(0.0, 0.0, 0.0)
        self.f.gnss(lat, lon, alt, 0.09, 0.36, self.t - 0.1)


def external(t: float) -> ExternalSample:
    return ExternalSample(t=t, position=np.zeros(3), quaternion=(1.0, 0.0, 0.0, 0.0), covariance=np.zeros((6, 6)),
                          frame_id="odom")


def timed(call) -> float:
    t0 = time.perf_counter_ns()
    call()
    return (time.perf_counter_ns() - t0) / 1e3


def measure(rigs: dict[str, Rig], samples: int, rounds: int = 20) -> dict[str, list[float]]:
    out: dict[str, list[float]] = {k: [] for k in ("imu before", "imu after", "gnss before", "gnss after", "external",
                                                   "flood", "replay", "drag")}
    per_round = max(1, samples // rounds)
    old, new, ext = rigs["before"], rigs["after"], rigs["external"]
    for _ in range(rounds):
        for rig, key in ((old, "imu before"), (new, "imu after")):
            for _ in range(per_round):
                out[key].append(timed(rig.imu))
        for rig, key in ((old, "gnss before"), (new, "gnss after")):
            for _ in range(per_round // 50):  # 10 Hz fixes
                for _ in range(50):
                    rig.imu()
                out[key].append(timed(rig.gnss))
        for _ in range(per_round // 5):  # 100 Hz external, 30 ms old; 3 flood samples each 1 ms later
            for _ in range(5):
                ext.imu()
            t = ext.t - 0.03
            out["external"].append(timed(lambda t=t: ext.f.external(external(t))))
            for j in (1, 2, 3):
                out["flood"].append(timed(lambda t=t, j=j: ext.f.validator.rate_limited(t + 0.001 * j)))
        ekf = ext.f.ekf
        for _ in range(max(1, per_round // 50)):
            out["drag"].append(timed(lambda ekf=new.f.ekf: ekf.update_drag(G)))
            out["replay"].append(timed(lambda ekf=ekf: [ekf.predict(STILL, G, DT) for _ in range(15)]))
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=20000, help="IMU samples per configuration")
    args = parser.parse_args(argv)
    if args.samples < 1000:
        parser.error("--samples must be >= 1000")
    with tempfile.TemporaryDirectory() as tmp:
        old_ekf, old_filter = before_modules(Path(tmp))
        probe = StallProbe()
        try:
            node_default = drag_config(load_airframe(default_airframe_path("quad_x")))
            rigs = {"before": Rig(old_filter.NavigationFilter(old_ekf.NavigationEkf())),
                    "after": Rig(NavigationFilter(NavigationEkf(node_default), NavigationConfig(
                        horizontal_primary=GNSS, horizontal_secondary=NONE))),
                    "external": Rig(NavigationFilter(NavigationEkf(node_default), NavigationConfig(
                        horizontal_primary=EXTERNAL, horizontal_secondary=NONE, external_alignment="configured",
                        origin=(HOME.latitude, HOME.longitude, HOME.altitude))))}
            measure(rigs, 2000, rounds=2)  # warm-up
            samples = measure(rigs, args.samples)
        finally:
            stalls = probe.stop()
    med = {k: statistics.median(v) for k, v in samples.items()}
    rates = {"imu": 500.0, "gnss": 10.0, "external": 100.0, "flood": 750.0, "replay": 100.0, "drag": 10.0}
    print(f"navigation filter cost per sample ({args.samples} IMU samples per configuration, 20 interleaved rounds)")
    print(f"{'what':<13} {'n':>6} {'median µs':>10} {'p99 µs':>9} {'after/before':>13} {'CPU at rate':>16}")
    for key, values in samples.items():
        values.sort()
        kind = key.split()[0]
        ratio = f"{med[key] / med[kind + ' before']:.2f}x" if key.endswith("after") else ""
        cpu = f"{med[key] * rates[kind] / 1e4:.2f}% @{rates[kind]:g} Hz"
        print(f"{key:<13} {len(values):>6} {med[key]:>10.1f} {values[int(0.99 * (len(values) - 1))]:>9.1f} "
              f"{ratio:>13} {cpu:>16}")
    print(worst_line(stalls))
    return 0


if __name__ == "__main__":
    sys.exit(main())
