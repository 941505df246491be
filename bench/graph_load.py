#!/usr/bin/env python3
"""The whole SITL graph on a companion-board budget (issue 16): per deployment variant, side by side.

For each variant, one `c4d fly` (the real CLI, as a child process, on a private ROS_DOMAIN_ID) of the
survey in missions/survey.yaml with a hover over its first waypoint inserted after the take-off, so the
flight (arm -> disarm) lasts at least --seconds. The measurement window is that flight. Printed per variant:
  - CPU % of one core per process (utime + stime of every thread from /proc/<pid>/stat, read each
    second; pids from the run's supervisor.json; a composed process is one row naming its nodes) and total;
  - peak RSS (VmRSS) and PSS (smaps_rollup: shared libraries split between the processes) per process, totals;
  - the GNC core from gnc/executor_stats in the flight's MCAP: overruns (total, and those in report
    windows where the platform-stall probe saw no stall), worst tick load (all / without stalls),
    release jitter p50 / p99 (medians of the 1 s windows' values) / worst window's p99 / max;
  - IMU -> actuator latency in ticks (control/actuators: header.stamp - input_stamp) p50 / p99 / max;
  - delivered rate of every fixed-rate topic of the interface manifest vs its nominal rate, counted in the
    flight's MCAP (the flight's own record: no extra subscriber loads the graph; a sample the recorder
    lost counts as undelivered, so read it with the recorder's drops, also printed);
  - the platform-stall probe (test/support/stall_probe.py: SCHED_FIFO 90, 1 ms sleeps) over the same window.

Variants (a variant config is a system YAML, see docs/bringup.md):
  today       src/c4d_bringup/config/sitl.yaml: nine processes, no placement
  board       src/c4d_bringup/config/board.yaml: the board deployment (affinity, nice, composition)
  board@1kHz  board.yaml with the core at a 1 kHz tick (its 500 Hz tasks at 1 kHz) and the sim's IMU at 1 kHz
  board-shared@1kHz  board@1kHz with the niced `ground` group allowed on every CPU, the core's too (below its
              SCHED_FIFO): on 2 CPUs the other CPU alone is too small for sim + sensing + ground at 1 kHz
  <v>+hog     <v> with a competing busy loop pinned to one CPU (--hog-cpu, default the last: the core's)

  . ./env.sh && flock /tmp/c4d_graph.lock python bench/graph_load.py [--variants today,board,board@1kHz] [--hog]
      [--seconds 120] [--repeat N] [--markdown]

--hog adds a +hog run of every listed variant without '@'. About 2.5 min per variant.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "test" / "support"))
sys.path.insert(0, str(Path(__file__).resolve().parent))
import graph_figures as gf  # noqa: E402
from stall_probe import StallProbe  # noqa: E402

CONFIGS = ROOT / "src" / "c4d_bringup" / "config"
SURVEY = ROOT / "missions" / "survey.yaml"
SURVEY_FLIGHT_S = 80.0  # arm -> disarm of the plain survey, measured (c4d fly, this machine)
STALL_MS = 1.0  # a probe second whose worst 1 ms sleep overslept by more than this saw a platform stall
MEMORY_EVERY_S = 5.0


@dataclass
class Variant:
    name: str
    config: Path
    tick_hz: float = 500.0
    imu_hz: float = 500.0
    hog: bool = False
    ground_any_cpu: bool = False  # the niced ground group may also run on the core's CPU (below its SCHED_FIFO)


@dataclass
class Result:
    variant: Variant
    outcome: str = "not run"
    failsafes: str = ""  # c4d fly's summary line
    window: tuple[float, float] = (0.0, 0.0)
    cpu: dict[str, float | None] = field(default_factory=dict)
    memory: dict[str, tuple[int | None, int | None]] = field(default_factory=dict)
    core: gf.CoreFigures | None = None
    windows: list[gf.StatsWindow] = field(default_factory=list)  # the executor's report windows
    latency_ticks: list[float] = field(default_factory=list)
    rates: dict[str, tuple[float, float]] = field(default_factory=dict)  # topic -> (delivered, nominal)
    recorder: dict[str, str] = field(default_factory=dict)
    stall: tuple[float, float, int] = (float("nan"), float("nan"), 0)
    core_placement: str = ""
    run_dir: Path | None = None


def variant(name: str) -> Variant:
    """The Variant of a name (see the module docstring); ValueError names the known ones."""
    base, hog = (name[:-4], True) if name.endswith("+hog") else (name, False)
    known = {"today": Variant("today", CONFIGS / "sitl.yaml"), "board": Variant("board", CONFIGS / "board.yaml"),
             "board@1kHz": Variant("board@1kHz", CONFIGS / "board.yaml", tick_hz=1000.0, imu_hz=1000.0),
             "board-shared@1kHz": Variant("board-shared@1kHz", CONFIGS / "board.yaml", tick_hz=1000.0, imu_hz=1000.0,
                                          ground_any_cpu=True)}
    if base not in known:
        raise ValueError(f"unknown variant '{name}' (known: {', '.join(known)}, each also with +hog)")
    v = known[base]
    v.name, v.hog = name, hog
    if not v.config.exists():
        raise ValueError(f"variant '{name}' needs {v.config.relative_to(ROOT)}, which does not exist")
    return v


def survey_plan(seconds: float) -> dict:
    """missions/survey.yaml with a hover over the first waypoint after the take-off, long enough for an
    arm -> disarm flight of about `seconds`."""
    plan = yaml.safe_load(SURVEY.read_text())
    items = plan["items"]
    first = next(i for i in items if i["type"] == "waypoint")
    hover = {**first, "hold": round(max(0.0, seconds - SURVEY_FLIGHT_S), 1)}
    at = next(k for k, i in enumerate(items) if i["type"] == "takeoff") + 1
    plan["items"] = items[:at] + [hover] + items[at:]
    plan["name"] = f"survey + {hover['hold']:g} s hover"
    return plan


def variant_config(v: Variant, out: Path) -> Path:
    """The system YAML of a variant: the named config, or for a changed tick/IMU rate a copy whose core
    and sim get derived core.yaml / sim.yaml files (written next to it) through their `config` parameter."""
    if v.tick_hz == 500.0 and v.imu_hz == 500.0 and not v.ground_any_cpu:
        return v.config
    core = yaml.safe_load((ROOT / "src" / "c4d_gnc" / "config" / "core.yaml").read_text())
    ex = core["executive"]
    for task in ex["tasks"]:
        if task["rate_hz"] == ex["tick_hz"]:
            task["rate_hz"] = int(v.tick_hz)  # the per-tick chain (state update, rate loop, mixer) follows the tick
    ex["tick_hz"] = int(v.tick_hz)  # the core takes an integer tick rate
    sim = yaml.safe_load((ROOT / "src" / "c4d_sim" / "config" / "sim.yaml").read_text())
    sim["sensors"]["imu_rate_hz"] = int(v.imu_hz)
    system = yaml.safe_load(v.config.read_text())
    if v.ground_any_cpu:
        system["compose"]["ground"]["cpu_affinity"] = ["0..-1"]
    out.mkdir(parents=True, exist_ok=True)
    for node, doc in (("core", core), ("sim", sim)):
        (out / f"{node}.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
        system["nodes"][node].setdefault("parameters", {})["config"] = str(out / f"{node}.yaml")
    path = out / "system.yaml"
    path.write_text(yaml.safe_dump(system, sort_keys=False))
    return path


def start_hog(cpu: int) -> subprocess.Popen:
    """A `stress`-like busy loop at normal priority pinned to `cpu`."""
    return subprocess.Popen([sys.executable, "-c", f"import os\nos.sched_setaffinity(0, {{{cpu}}})\nwhile True: pass"],
                            start_new_session=True)


def placement(pid: int) -> str:
    """Scheduling policy / priority and allowed CPUs of a process, e.g. 'FIFO 60, CPUs 1'."""
    try:
        policy = {os.SCHED_FIFO: "FIFO", os.SCHED_RR: "RR"}.get(os.sched_getscheduler(pid), "OTHER")
        prio = os.sched_getparam(pid).sched_priority
        cpus = ",".join(str(c) for c in sorted(os.sched_getaffinity(pid)))
        return f"{policy} {prio}, CPUs {cpus}" if policy != "OTHER" else f"OTHER, CPUs {cpus}"
    except OSError:
        return "?"


def fly_variant(v: Variant, args, domain: int, root: Path) -> Result:
    """One `c4d fly` of the variant with the probe (and hog) running; figures filled from /proc and the MCAP."""
    result = Result(v)
    vdir = root / v.name.replace("@", "_").replace("+", "_")
    vdir.mkdir(parents=True)  # root/<repeat>/<variant>
    config = variant_config(v, vdir / "config")
    plan = vdir / "plan.yaml"
    plan.write_text(yaml.safe_dump(survey_plan(args.seconds), sort_keys=False))
    run_dir = result.run_dir = vdir / "run"
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    hog = start_hog(args.hog_cpu % os.cpu_count()) if v.hog else None
    probe = StallProbe()
    offset = time.time() - time.monotonic()
    log = open(vdir / "fly.log", "w")
    fly = subprocess.Popen([str(ROOT / "c4d"), "fly", "--mission", str(plan), "--config", str(config),
                            "--run-dir", str(run_dir), "--no-report"],
                           stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, env=env, start_new_session=True)
    series: dict[str, gf.ProcessSeries] = {}
    last_memory = 0.0
    try:
        while fly.poll() is None:
            time.sleep(1.0)
            try:
                state = json.loads((run_dir / "supervisor.json").read_text())
            except (OSError, ValueError):
                continue
            now = time.time()
            memory = now - last_memory >= MEMORY_EVERY_S
            last_memory = now if memory else last_memory
            for pid, label in gf.processes(state).items():  # a composed process: its members joined with '+'
                figures = gf.read_proc(pid, memory)
                if figures is not None:
                    series.setdefault(label, gf.ProcessSeries(label)).samples.append((now, pid, figures))
                if label == "core" and memory:
                    result.core_placement = placement(pid)  # the latest: the core sets its own policy once running
    finally:
        if fly.poll() is None:
            os.killpg(fly.pid, signal.SIGINT)  # c4d fly stops its graph
            try:
                fly.wait(60)
            except subprocess.TimeoutExpired:
                os.killpg(fly.pid, signal.SIGKILL)
                fly.wait()
        stalls = [(t + offset, ms) for t, ms in probe.stop()]
        if hog is not None:
            hog.kill()
            hog.wait()
        log.close()
    text = (vdir / "fly.log").read_text(errors="replace")
    summary = {k: v for k, _, v in (line.partition(" ") for line in text.splitlines()) if k in ("flight", "failsafes")}
    result.outcome = summary.get("flight", f"c4d fly exit {fly.returncode}").strip()
    result.failsafes = summary.get("failsafes", "?").strip()
    bags = sorted((run_dir / "flights").glob("*.mcap"))
    if not bags:
        result.outcome += " (no MCAP)"
        return result
    read_flight(bags[-1], result)
    start, end = result.window
    for label, s in series.items():
        result.cpu[label] = s.cpu_percent(start, end)
        result.memory[label] = s.memory_kb(start, end)
    result.stall = gf.stall_summary(stalls, start, end, STALL_MS)
    result.core = gf.core_figures(result.windows, stalls, STALL_MS) if result.windows else None
    return result


def read_flight(bag: Path, result: Result) -> None:
    """Window, executor windows, latency, topic rates and recorder status from the flight's MCAP."""
    from c4d_data.bag_reader import Decoders, iter_messages, open_bag
    from c4d_ros.manifest import MANIFEST

    contents = open_bag(bag)
    start, end = contents.start_ns * 1e-9, contents.end_ns * 1e-9
    result.window = (start, end)
    decoders = Decoders()
    times: dict[str, list[float]] = {}
    windows: list[gf.StatsWindow] = []
    latency: list[float] = []
    stamp = lambda t: t.sec + t.nanosec * 1e-9  # noqa: E731
    tick_s = 1.0 / result.variant.tick_hz
    for topic, message in iter_messages(contents):
        name = topic.name.lstrip("/")
        times.setdefault(name, []).append(message.log_time * 1e-9)
        if name == "control/actuators":
            m = decoders.decode(topic, message.data)
            if m.armed:  # disarmed, the core holds its last input (stale stamps before take-off and after landing)
                latency.append((stamp(m.header.stamp) - stamp(m.input_stamp)) / tick_s)
        elif name == "gnc/executor_stats":
            m = decoders.decode(topic, message.data)
            windows.append(gf.StatsWindow(stamp(m.header.stamp), m.ticks / m.tick_rate_hz if m.tick_rate_hz else 1.0,
                                       int(m.ticks), int(m.overruns), m.load_max_percent,
                                       getattr(m, "release_jitter_p50_us", float("nan")), m.release_jitter_p99_us,
                                       m.release_jitter_max_us, m.tick_rate_hz))
        elif name == "recorder/status":
            m = decoders.decode(topic, message.data)
            result.recorder = {kv.key: kv.value for kv in m.values}
    result.latency_ticks = latency
    result.windows = windows
    nominal = gf.nominal_rates({t.name: t.rate for t in MANIFEST.topics}, result.variant.imu_hz, result.variant.tick_hz)
    delivered = gf.delivered_rates({n: times.get(n, []) for n in nominal}, start, end)
    result.rates = {n: (delivered[n], nominal[n]) for n in nominal if n in times}


def table_rows(groups: list[list[Result]]) -> list:
    """Rows of the side-by-side table (label, one cell per variant); a variant flown several times
    (--repeat) shows the median of its numeric figures."""
    def each(fn):
        out = []
        for runs in groups:
            values = []
            for r in runs:
                try:
                    values.append(fn(r))
                except (KeyError, TypeError, ValueError, AttributeError, ZeroDivisionError, StopIteration):
                    pass
            numbers = [v for v in values if isinstance(v, int | float) and v == v]
            if numbers:
                out.append(statistics.median(numbers) if len(numbers) > 1 else numbers[0])
            else:
                out.append(" / ".join(dict.fromkeys(str(v) for v in values if isinstance(v, str))) or None)
        return out

    def total(values):
        present = [v for v in values if v is not None]
        if not present:
            raise ValueError("no figures")
        return sum(present)

    results = [r for runs in groups for r in runs]
    labels = list(dict.fromkeys(label for r in results for label in r.cpu))
    rows: list = [("flight (measurement window) [s]", each(lambda r: r.window[1] - r.window[0] or None)),
                  "CPU [% of one core] (utime+stime, all threads)"]
    rows += [(f"  {label}", each(lambda r, k=label: r.cpu.get(k))) for label in labels]
    rows.append(("  total", each(lambda r: total(r.cpu.values()))))
    rows.append("RSS / PSS [MB], peak in the window")
    for label in labels:
        rows.append((f"  {label} RSS", each(lambda r, k=label: r.memory[k][0] / 1024)))
    rows.append(("  total RSS", each(lambda r: total(m[0] for m in r.memory.values()) / 1024)))
    for label in labels:
        rows.append((f"  {label} PSS", each(lambda r, k=label: r.memory[k][1] / 1024)))
    rows.append(("  total PSS", each(lambda r: total(m[1] for m in r.memory.values()) / 1024)))
    rows += ["GNC core (gnc/executor_stats)",
             ("  placement", each(lambda r: r.core_placement or "-")),
             ("  tick rate [Hz]", each(lambda r: r.variant.tick_hz)),
             ("  ticks", each(lambda r: r.core.ticks)),
             ("  overruns", each(lambda r: r.core.overruns)),
             ("  overruns [% of ticks]", each(lambda r: 100.0 * r.core.overruns / r.core.ticks), 3),
             ("  overruns not in a stall window [% of ticks]",
              each(lambda r: 100.0 * r.core.overruns_unexplained / r.core.ticks), 3),
             (f"  overruns not in a stall window (>{STALL_MS:g} ms)", each(lambda r: r.core.overruns_unexplained)),
             ("  report windows with a platform stall", each(lambda r: f"{r.core.stalled_windows}/{r.core.windows}")),
             ("  worst tick load [%]", each(lambda r: r.core.worst_load_percent)),
             ("  worst tick load, no-stall windows [%]", each(lambda r: r.core.worst_load_unstalled_percent)),
             ("  release jitter p50 [us]", each(lambda r: r.core.jitter_p50_us)),
             ("  release jitter p99 [us]", each(lambda r: r.core.jitter_p99_us)),
             ("  release jitter p99, worst window [us]", each(lambda r: r.core.jitter_p99_worst_us)),
             ("  release jitter max [us]", each(lambda r: r.core.jitter_max_us)),
             "IMU -> actuator latency [ticks] (control/actuators stamp - input_stamp)"]
    for q in (50, 99, 100):
        rows.append((f"  {'max' if q == 100 else f'p{q}'}", each(lambda r, q=q: gf.percentiles(r.latency_ticks, [q])[0])))
    rows.append("delivered rate [% of nominal] (flight MCAP)")
    topics = list(dict.fromkeys(t for r in results for t in r.rates))
    for t in topics:
        nominals = "/".join(f"{hz:g}" for hz in dict.fromkeys(r.rates[t][1] for r in results if t in r.rates))
        rows.append((f"  {t} ({nominals} Hz)", each(lambda r, t=t: 100.0 * r.rates[t][0] / r.rates[t][1])))
    rows += ["recorder (last recorder/status in the MCAP)",
             ("  written", each(lambda r: int(r.recorder["written"]))),
             ("  dropped", each(lambda r: int(r.recorder["dropped"]))),
             "platform-stall probe (SCHED_FIFO 90, 1 ms sleeps), worst oversleep per second",
             ("  median [ms]", each(lambda r: r.stall[0])),
             ("  worst [ms]", each(lambda r: r.stall[1])),
             (f"  seconds with a stall > {STALL_MS:g} ms", each(lambda r: r.stall[2]))]
    return rows


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--variants", default="today,board,board@1kHz", help="comma-separated (see the module docstring)")
    ap.add_argument("--seconds", type=float, default=120.0, help="minimum flight (measurement window) per variant [s]")
    ap.add_argument("--hog", action="store_true", help="also run every variant without '@' with a busy loop (+hog)")
    ap.add_argument("--hog-cpu", type=int, default=-1, help="CPU the busy loop is pinned to (-1: the last)")
    ap.add_argument("--domain", type=int, default=210, help="ROS_DOMAIN_ID of the first variant (+1 per variant)")
    ap.add_argument("--repeat", type=int, default=1, help="flights per variant (the table shows medians)")
    ap.add_argument("--markdown", action="store_true", help="print the table as markdown too")
    args = ap.parse_args()
    names = [n for n in args.variants.split(",") if n]
    if args.hog:
        names += [f"{n}+hog" for n in names if "@" not in n and not n.endswith("+hog")]
    try:
        variants = [variant(n) for n in names]
    except ValueError as exc:
        print(f"graph_load: error: {exc}", file=sys.stderr)
        return 2
    if args.repeat < 1:
        print("graph_load: error: --repeat must be at least 1", file=sys.stderr)
        return 2
    if args.seconds < 30:
        print("graph_load: error: --seconds must be at least 30", file=sys.stderr)
        return 2
    root = Path(tempfile.mkdtemp(prefix="c4d-graph-load-"))
    groups: list[list[Result]] = [[] for _ in variants]
    for n in range(args.repeat):  # interleaved: a slow phase of the machine hits every variant alike
        for k, v in enumerate(variants):
            print(f"graph_load: {v.name}: flight {n + 1}/{args.repeat} ({v.config.relative_to(ROOT)})", flush=True)
            groups[k].append(fly_variant(v, args, args.domain + k, root / f"{n + 1}"))
            print(f"graph_load: {v.name}: {groups[k][-1].outcome}", flush=True)
    cols = [v.name for v in variants]
    rows = table_rows(groups)
    print(f"\nc4d whole graph, survey + hover, {args.repeat} flight(s) per variant"
          f"{' (medians)' if args.repeat > 1 else ''}, {os.cpu_count()} CPUs ({platform_line()}); runs in {root}")
    print(gf.side_by_side(cols, rows))
    for v, runs in zip(variants, groups, strict=True):
        for r in runs:
            print(f"{v.name}: flight {r.outcome}; failsafes {r.failsafes}")
    if args.markdown:
        print("\n" + gf.markdown_table(cols, rows))
    return 0


def platform_line() -> str:
    try:
        model = next(line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                     if line.startswith("model name"))
    except (OSError, StopIteration):
        model = "?"
    return f"{model}, Linux {os.uname().release}, Python {sys.version.split()[0]}"


if __name__ == "__main__":
    t0 = time.monotonic()
    code = main()
    print(f"bench time {time.monotonic() - t0:.0f} s")
    sys.exit(code)
