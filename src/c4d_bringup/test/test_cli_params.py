"""`c4d param list | set | reset` on a temporary XDG_DATA_HOME: what `set` stores is what `list` shows
and what a core started for that vehicle restores (the same VehicleStore); bad input is one line
`c4d: error: ...` and exit 2; `reset` removes the stored changes."""

from __future__ import annotations

import os
import subprocess
import sys

import yaml


def c4d(tmp_path, *args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "XDG_DATA_HOME": str(tmp_path)}
    return subprocess.run([sys.executable, "-m", "c4d_bringup.cli", "param", *args], capture_output=True, text=True,
                          env=env, check=False, timeout=60)


def test_set_list_reset_and_refusals(tmp_path):
    store = tmp_path / "c4d" / "vehicles" / "sitl" / "core.yaml"
    listed = c4d(tmp_path, "list")  # the bundled sitl.yaml names the vehicle 'sitl'
    assert listed.returncode == 0, listed.stderr
    assert "(no stored changes)" in listed.stdout and "gains.rate.roll.p" in listed.stdout
    done = c4d(tmp_path, "set", "gains.rate.roll.p", "30")
    assert done.returncode == 0, done.stderr
    assert yaml.safe_load(store.read_text()) == {"gains.rate.roll.p": 30.0}
    row = next(line for line in c4d(tmp_path, "list").stdout.splitlines() if " gains.rate.roll.p " in line)
    assert row.startswith("*") and " 30 " in row
    for args, error in ((("set", "gains.rate.roll.p", "300"), "gains.rate.roll.p: 300 is outside [0, 200] 1/s"),
                        (("set", "limits.min_thrust_ratio", "0.96"), "must be below limits.max_thrust_ratio"),
                        (("set", "gains.rate.roll.p", "nan"), "is not finite"),
                        (("set", "gains.rate.roll.p", "fast"), "is not a number"),
                        (("set", "no.such", "1"), "no.such: no such parameter"),
                        (("set",), "usage: c4d param set NAME VALUE"),
                        (("list", "--vehicle", "../etc"), "vehicle name '../etc'")):
        bad = c4d(tmp_path, *args)
        lines = bad.stderr.strip().splitlines()
        assert bad.returncode == 2 and len(lines) == 1 and lines[0].startswith("c4d: error: ") and error in lines[0], \
            (args, bad.stderr)
    assert yaml.safe_load(store.read_text()) == {"gains.rate.roll.p": 30.0}  # refusals changed nothing
    assert c4d(tmp_path, "reset").returncode == 0 and not store.exists()
    assert "nothing stored" in c4d(tmp_path, "reset").stdout


def test_navigation_and_health_stores(tmp_path):
    """--node navigation / health: the stores the nodes restore from (navigation.yaml, health.yaml), checked
    by the nodes' own tables (the EKF's ranges; the policy's cross rule on the bundled failsafe.yaml)."""
    folder = tmp_path / "c4d" / "vehicles" / "sitl"
    listed = c4d(tmp_path, "list", "--node", "navigation")
    assert listed.returncode == 0 and "ekf.gps_gate" in listed.stdout and "navigation.yaml" in listed.stdout, listed.stderr
    assert c4d(tmp_path, "set", "ekf.gps_gate", "4", "--node", "navigation").returncode == 0
    assert yaml.safe_load((folder / "navigation.yaml").read_text()) == {"ekf.gps_gate": 4.0}
    assert c4d(tmp_path, "set", "battery_low_threshold", "0.35", "--node", "health").returncode == 0
    assert yaml.safe_load((folder / "health.yaml").read_text()) == {"battery_low_threshold": 0.35}
    for args, error in ((("set", "ekf.gps_gate", "0.5", "--node", "navigation"), "ekf.gps_gate: 0.5 is outside [1, 100]"),
                        (("set", "battery_critical_threshold", "0.4", "--node", "health"),
                         "battery_critical_threshold (0.4) must be below battery_low_threshold (0.35)"),
                        (("set", "gains.rate.roll.p", "30", "--node", "health"), "no such parameter"),
                        (("list", "--node", "mission"), "invalid choice")):
        bad = c4d(tmp_path, *args)
        lines = bad.stderr.strip().splitlines()
        assert bad.returncode == 2 and len(lines) == 1 and error in lines[0], (args, bad.stderr)
    assert not (folder / "core.yaml").exists()  # one file per node
    assert c4d(tmp_path, "reset", "--node", "health").returncode == 0 and not (folder / "health.yaml").exists()
    assert (folder / "navigation.yaml").exists()
