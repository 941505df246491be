"""`c4d-sched network` as a real process: round trip through YAML, verification, bad input."""

import json
import subprocess
from pathlib import Path

import pytest
import yaml
from ament_index_python.packages import get_package_prefix

from c4d_sched.cli import main

EXE = Path(get_package_prefix("c4d_sched")) / "lib" / "c4d_sched" / "c4d-sched"
WORKED = Path(__file__).resolve().parents[3] / "examples" / "network_worked_example.yaml"


def run(*args, timeout=120):
    return subprocess.run([str(EXE), "network", *map(str, args)], capture_output=True, text=True, timeout=timeout)


def run_in_process(capsys, *args):
    """cli.main in this process (the same code path as the executable, without a 0.4 s start-up)."""
    code = main(["network", *map(str, args)])
    out, err = capsys.readouterr()
    return code, out, err


def test_round_trip_worked_example(tmp_path):
    out = tmp_path / "with_offsets.yaml"
    r = run(WORKED, "--cycle-load", "section", "--json", "--write", out)
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert [f["offset"] for f in d["flows"]] == [0, 13, 10, 3, 23, 10]
    assert d["gcdsharp"]["sum_delta"] == 9 and d["gcdsharp"]["indicator"] and d["verification"]["ok"]
    assert [f["offset"] for f in yaml.safe_load(out.read_text())["flows"]] == [0, 13, 10, 3, 23, 10]
    r = run(out, "--offsets", "file", "--json")  # the written file is a valid network with its offsets
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["verification"]["ok"]


def test_planted_overlap_exits_1_and_names_the_pair():
    r = run(WORKED, "--offsets", "0,13,10,3,23,1")
    assert r.returncode == 1
    assert "overlap on E1->SW1: S1 at 0 and S6 at 1" in r.stdout


def test_text_report_and_exact_model():
    r = run(WORKED, "--exact")
    assert r.returncode == 0, r.stderr
    assert "verifier (per-port simulation" in r.stdout and "no overlap" in r.stdout
    assert "exact CP-SAT model: feasible" in r.stdout and "(verified: True)" in r.stdout
    assert "Σδ = 9 (90.0 % of Ω)" in r.stdout


def test_orion_like_case(tmp_path):
    r = run("--orion-like", 0, "--json", "--write", tmp_path / "orion.yaml")
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert len(d["flows"]) == 100 and d["verification"]["ok"]
    assert d["gcdsharp"]["sum_delta_over_omega"] < 0.2
    r = run(tmp_path / "orion.yaml", "--offsets", "file")  # the written case reads back
    assert r.returncode == 0 and "no overlap" in r.stdout


GOOD = """time_unit: us
rate: 8000000
end_systems: [E1, E2, E3]
switches: [SW1, SW2, SW3, SW4]
links: [[E1, SW1], [E2, SW2], [E3, SW3], [SW1, SW2], [SW2, SW3], [SW1, SW4], [SW4, SW3]]
flows:
"""


@pytest.mark.parametrize("text, message", [
    (GOOD + "  - {name: a, period: 10, size: 1, path: [E1, SW1, SW7, E2]}\n", "unknown node 'SW7'"),
    (GOOD + "  - {name: a, period: 10, size: 1, path: [E1->SW1, SW1->SW3, SW3->E3]}\n",
     "output port SW1->SW3 has no link SW1-SW3"),
    (GOOD + "  - {name: a, period: 10, size: 1, path: [E1, SW1, SW2, SW3, E3]}\n"
            "  - {name: b, period: 10, size: 1, path: [E1, SW1, SW4, SW3, E3]}\n",
     "paths that fork and merge again are outside GCD#'s model"),
    (GOOD + "  - {name: a, period: -10, size: 1, path: [E1, SW1, SW2, E2]}\n", "period must be a positive integer"),
    (GOOD + "  - {name: a, period: 10, size: 0, path: [E1, SW1, SW2, E2]}\n", "size (bytes) must be a positive"),
    (GOOD.replace("[E3, SW3], ", "") + "  - {name: a, period: 10, size: 1, path: [E3, SW3, SW2, E2]}\n",
     "output port E3->SW3 has no link E3-SW3"),
    (GOOD + "  - {name: a, period: 10, size: 1, path: [E1, SW1, E2\n", "YAML syntax error at line"),
    ("store_and_forward: 1\n" + GOOD + "  - {name: a, period: 10, size: 3, path: [E1, SW1, SW2, E2]}\n",
     "store_and_forward 1 us is below the largest transmission time 3"),
])
def test_bad_networks_exit_2_with_one_line(tmp_path, capsys, text, message):
    f = tmp_path / "bad.yaml"
    f.write_text(text)
    code, out, err = run_in_process(capsys, f)
    assert code == 2 and out == ""
    assert err.startswith("c4d-sched: error: ") and err.count("\n") == 1 and message in err


@pytest.mark.parametrize("args, message", [
    ((), "give a network FILE or --orion-like SEED"),
    ((WORKED, "--orion-like", "1"), "give a network FILE or --orion-like SEED"),
    ((WORKED, "--exact", "--time-limit", "0"), "--time-limit must be > 0"),
    ((WORKED, "--offsets", "1,2"), "--offsets has 2 values for 6 flows"),
    (("/nonexistent.yaml",), "cannot read /nonexistent.yaml"),
])
def test_bad_arguments_exit_2(capsys, args, message):
    code, _, err = run_in_process(capsys, *args)
    assert code == 2 and err.count("\n") == 1 and message in err, err


def test_bad_input_from_the_executable(tmp_path):
    f = tmp_path / "bad.yaml"
    f.write_text(GOOD + "  - {name: a, period: 0, size: 1, path: [E1, SW1, SW2, E2]}\n")
    r = run(f)
    assert r.returncode == 2 and r.stderr == "c4d-sched: error: flow 'a': period must be a positive integer, got 0\n"
