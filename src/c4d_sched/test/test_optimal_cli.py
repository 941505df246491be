"""`c4d-sched optimal | schedule | gap-study` as a real process: results, and bad input in one line with exit 2."""

import json
import subprocess
from pathlib import Path

import pytest
from ament_index_python.packages import get_package_prefix

CONFIG = Path(__file__).resolve().parents[1] / "config"
EXE = Path(get_package_prefix("c4d_sched")) / "lib" / "c4d_sched" / "c4d-sched"

EXECUTIVE = """executive:
  tick_hz: 1000
  phase_method: optimal
  tasks:
    - {name: f1, group: control, divider: 3, budget_us: 300}
    - {name: f2, group: control, divider: 5, budget_us: 300}
    - {name: slow, group: telemetry, divider: 15, budget_us: 300}
  precedence:
"""


def run(*args):
    return subprocess.run([str(EXE), *map(str, args)], capture_output=True, text=True, timeout=120)


def test_optimal_executive_and_fifo_json():
    r = run("optimal", CONFIG / "worked_example.yaml", "--json")
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert d["status"] == "optimal" and d["worst_tick_load"] == d["bound"] == 6 <= d["gcdplus_worst_tick_load"]
    r = run("optimal", CONFIG / "worked_example.yaml", "--model", "fifo", "--json")
    d = json.loads(r.stdout)
    assert d["zero_interference"] is True and d["max_overlap"] == 0


def test_schedule_with_the_d33_edge(tmp_path):
    f = tmp_path / "exec.yaml"
    f.write_text(EXECUTIVE + "    - {producer: f1, consumer: f2, w_p: 3, w_c: 5, m0: 2}\n")
    r = run("schedule", f, "--json")
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert d["method"] == "optimal" and d["optimality"] == "optimal" and d["lower_bound_us"] == d["max_tick_load_us"]
    phase = {t["name"]: t["phase"] for t in d["tasks"]}
    # M0 = 2: F2 jobs wait for F1 jobs (1, 3, 5): φ1 ≤ φ2, φ1 + 6 ≤ φ2 + 5, φ1 + 12 ≤ φ2 + 10  ⇔  φ2 − φ1 ≥ 2
    assert phase["f2"] - phase["f1"] >= 2


BAD = [
    ("    - {producer: f1, consumer: f2, w_p: 3, w_c: 4}\n", "tokens never balance"),
    ("    - {producer: f1, consumer: f2}\n    - {producer: f2, consumer: f1}\n", "infeasible precedence cycle"),
    ("    - {producer: f1, consumer: ghost}\n", "unknown task 'ghost'"),
]


@pytest.mark.parametrize(("edges", "message"), BAD)
def test_bad_schedule_input_one_line_exit_2(tmp_path, edges, message):
    f = tmp_path / "exec.yaml"
    f.write_text(EXECUTIVE + edges)
    r = run("schedule", f)
    assert r.returncode == 2 and r.stderr.startswith("c4d-sched: error: ") and r.stderr.count("\n") == 1, r.stderr
    assert message in r.stderr


@pytest.mark.parametrize("args", [("optimal", "WE", "--time-limit", "0"), ("optimal", "WE", "--time-limit", "-3"),
                                  ("schedule", "WE", "--time-limit", "0"), ("gap-study", "--time-limit", "0")])
def test_time_limit_not_positive_one_line_exit_2(args):
    r = run(*(CONFIG / "worked_example.yaml" if a == "WE" else a for a in args))
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "time limit must be a positive number" in r.stderr, r.stderr
