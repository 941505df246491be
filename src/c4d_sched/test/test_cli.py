"""The installed `c4d-sched` executable, run as a real process (where `ros2 run` finds it)."""

import json
import subprocess
from pathlib import Path

import pytest
from ament_index_python.packages import get_package_prefix

CONFIG = Path(__file__).resolve().parents[1] / "config"
EXE = Path(get_package_prefix("c4d_sched")) / "lib" / "c4d_sched" / "c4d-sched"


def run(*args, timeout=120):
    return subprocess.run([str(EXE), *map(str, args)], capture_output=True, text=True, timeout=timeout)


def test_assign_worked_example_json():
    r = run("assign", CONFIG / "worked_example.yaml", "--json", "--evaluate")
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert [t["offset"] for t in d["tasks"]] == [4, 3, 0, 8]
    assert d["gcdplus"]["omega"] == 8 and d["gcdplus"]["sum_delta"] == 6 and d["gcdplus"]["certificate"]
    assert d["gcdplus"]["delta_per_section"] == {"2": 4, "3": 2}
    assert d["load"]["max_cycle_load"] == 6 and d["load"]["overloaded_cycles"] == 0
    assert d["evaluation"]["zero_interference"]


def test_assign_text_and_evaluate_zero_offsets():
    r = run("assign", CONFIG / "worked_example.yaml")
    assert r.returncode == 0 and "certificate (Lemma 3.2.2): HOLDS" in r.stdout
    r = run("evaluate", CONFIG / "worked_example.yaml", "--offsets", "0,0,0,0", "--json")
    d = json.loads(r.stdout)
    assert d["load"]["max_cycle_load"] == 9 and [t["max_delay"] for t in d["tasks"]] == [0, 2, 3, 6]


def test_assign_csv_with_baseline(tmp_path):
    f = tmp_path / "set.csv"
    f.write_text("name,period,wcet\na,100,10\nb,200,20\nc,300,5\n")
    r = run("assign", f, "--method", "paparazzi", "--json")
    assert r.returncode == 0, r.stderr
    assert [t["offset"] for t in json.loads(r.stdout)["tasks"]] == [0, 20, 60]


def test_wcet_above_omega_is_reported(tmp_path):
    f = tmp_path / "big.yaml"
    f.write_text("tasks:\n  - {name: a, period: 10, wcet: 4}\n  - {name: b, period: 15, wcet: 12}\n")
    r = run("assign", f)
    assert r.returncode == 0
    assert "no zero-interference guarantee: max C = 12 > Ω = 5" in r.stdout


# 400/300/140/60 Hz in ns: the hyperperiod (~1e27) does not fit in int64 (issue 14 item 5).
HUGE_H = ("unit: ns\ntasks:\n  - {name: imu, period: 2500000, wcet: 100000}\n  - {name: att, period: 3333333, wcet: 200000}\n"
          "  - {name: pos, period: 7142857, wcet: 300000}\n  - {name: tel, period: 16666667, wcet: 400000}\n")


def test_huge_hyperperiod_still_assigns(tmp_path):
    f = tmp_path / "ns.yaml"
    f.write_text(HUGE_H)
    r = run("assign", f, "--json")
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert len({t["offset"] for t in d["tasks"]}) == 4 and "exact evaluation skipped" in d["note"]
    assert "exceed the limit" in d["load"]["skipped"]
    r = run("assign", f)
    assert r.returncode == 0 and "per-cycle load: not computed" in r.stdout, r.stderr


def test_huge_hyperperiod_evaluation_refused_in_one_line(tmp_path):
    f = tmp_path / "ns.yaml"
    f.write_text(HUGE_H)
    for args in (("assign", f, "--evaluate"), ("evaluate", f, "--offsets", "0,0,0,0")):
        r = run(*args)
        assert r.returncode == 2 and r.stderr.startswith("c4d-sched: error: ") and r.stderr.count("\n") == 1, r.stderr
        assert "exceed the limit of 50000000" in r.stderr


BAD = {
    "zero_period.yaml": ("tasks:\n  - {name: a, period: 0, wcet: 1}\n", "period must be a positive integer"),
    "negative.yaml": ("tasks:\n  - {name: a, period: 10, wcet: -1}\n", "wcet must be a positive integer"),
    "float.yaml": ("tasks:\n  - {name: a, period: 10.5, wcet: 1}\n", "period must be a positive integer"),
    "c_gt_t.yaml": ("tasks:\n  - {name: a, period: 10, wcet: 11}\n", "wcet 11 exceeds its period 10"),
    "empty.yaml": ("tasks: []\n", "the task set is empty"),
    "malformed.yaml": ("tasks: [ {name: a, period: 10\n", "malformed YAML"),
    "nolist.yaml": ("hello: 1\n", "needs a 'tasks' list"),
    "dup.yaml": ("tasks:\n  - {name: a, period: 10, wcet: 1}\n  - {name: a, period: 10, wcet: 1}\n", "defined twice"),
    "chain.yaml": ("tasks:\n  - {name: a, period: 10, wcet: 1}\n  - {name: b, period: 20, wcet: 1}\n"
                   "chains:\n  - {tasks: [a, b]}\n", "precedence needs equal periods"),
    "bad.csv": ("name,period,wcet\na,ten,1\n", "must be integers"),
}


@pytest.mark.parametrize("name", sorted(BAD))
def test_bad_input_one_line_exit_2(tmp_path, name):
    content, message = BAD[name]
    f = tmp_path / name
    f.write_text(content)
    r = run("assign", f)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("c4d-sched: error:") and message in lines[0], r.stderr
    assert "Traceback" not in r.stderr and r.stdout == ""


@pytest.mark.parametrize(
    "args,message",
    [
        (["assign", "/nonexistent/set.yaml"], "cannot read"),
        (["assign", "{cfg}", "--method", "magic"], "invalid choice"),
        (["evaluate", "{cfg}", "--offsets", "1,2"], "2 values for 4 tasks"),
        (["evaluate", "{cfg}"], "give --offsets"),
        (["experiment", "--sizes", "x"], "comma-separated integers"),
        ([], "required"),
    ],
)
def test_bad_arguments_one_line_exit_2(args, message):
    args = [a.replace("{cfg}", str(CONFIG / "worked_example.yaml")) for a in args]
    r = run(*args)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], r.stderr


def test_small_experiment_writes_csv_and_png(tmp_path):
    r = run("experiment", "--sizes", "8", "--utilisations", "0.6,0.9", "--sets", "30", "--workers", "1",
            "--out", tmp_path, timeout=300)
    assert r.returncode == 0, r.stderr
    rows = (tmp_path / "schedulability.csv").read_text().splitlines()
    assert rows[0].startswith("n,utilisation,method,sets,schedulable") and len(rows) == 1 + 2 * 6
    assert (tmp_path / "schedulability.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "GCD+/best baseline" in r.stdout
